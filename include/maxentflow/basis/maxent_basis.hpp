// maxentflow: local maximum-entropy basis functions (paper Eqs. 2-5; Arroyo &
// Ortiz 2006), values and exact gradients, at single points or whole point sets.
#pragma once

#include <maxentflow/basis/basis_table.hpp>
#include <maxentflow/basis/detail/convex_hull.hpp>
#include <maxentflow/basis/detail/dual_solver.hpp>
#include <maxentflow/basis/detail/support_grid.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/mesh/nodal_spacing.hpp>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace maxentflow {

/// The local max-ent basis p_a(x) of a node cloud in Dim = 1, 2 or 3 dimensions.
///
/// Each node carries beta_a = gamma_a / h_a^2 (Eq. 2): gamma_a the dimensionless
/// locality (1.6 in the paper; >= 4 approaches the Delaunay affine basis) and h_a
/// the nodal spacing. Only nodes with |x - x_a| <= h_a sqrt(-ln(tol0)/gamma_a),
/// i.e. whose prior weight exp(-beta_a |x - x_a|^2) is at least tol0, take part.
/// At each point the dual variable lambda minimizes ln Z (Eq. 4) by Newton's
/// method; p_a follows from Eq. (5). On a facet of the nodes' convex hull the
/// dual has no minimizer (lambda runs off to infinity); there the basis is the
/// lower-dimensional max-ent of the nodes on that facet (weak Kronecker-delta
/// property), computed directly.
///
/// Accuracy of first-order consistency |sum_a p_a x_a - x| (beyond round-off):
/// at most 1e-8 h inside the hull (h: the nearest node's spacing; the dual's
/// acceptance), at most 3e-6 h_max on or within 1e-6 h of a hull facet (h_max:
/// the support's largest spacing), where the basis is the facet's at x's
/// projection, with the facet's nodes taken within 2e-6 h of its line. The
/// same holds on a facet of the support's own hull where the dual has no
/// minimizer (a side straight over the support, concave at large).
template <int Dim>
class MaxEntBasis {
 public:
  static_assert(Dim >= 1 && Dim <= 3, "maxentflow: MaxEntBasis dimension must be 1, 2 or 3");
  static constexpr int dim = Dim;
  using Point = Eigen::Matrix<double, Dim, 1>;
  using Points = Eigen::Matrix<double, Dim, Eigen::Dynamic>;
  using Tensor = Eigen::Matrix<double, Dim, Dim>;

  struct params {
    double gamma = 1.6;            ///< locality when one gamma serves all nodes
    double tol0 = 1e-6;            ///< support cut-off on the prior weight
    double newton_tol = 1e-13;     ///< converged when |r| <= newton_tol * h (r: reproduction error)
    int max_iterations = 100;      ///< Newton iterations before the solve is declared failed
    double hull_tol = 1e-10;       ///< a point within hull_tol * h of a hull facet lies on it
    bool warm_start = true;        ///< start each point's Newton at its predecessor's lambda
    int block = 64;                ///< warm-start chains restart every `block` points (so
                                   ///< results do not depend on the thread count)
    double gradient_offset = 1e-7; ///< gradients on a hull facet are taken this far (times h)
                                   ///< inside, where they exist; error O(offset)
  };

  /// Per-node gamma and h.
  MaxEntBasis(Points nodes, Eigen::VectorXd h, Eigen::VectorXd gamma, params prm = {})
      : prm_(prm), nodes_(std::move(nodes)), h_(std::move(h)), gamma_(std::move(gamma)) {
    check_nodes();
    require(h_.size() == nodes_.cols() && gamma_.size() == nodes_.cols(),
            detail::cat("h and gamma need one value per node (", nodes_.cols(), " nodes, ",
                        h_.size(), " h, ", gamma_.size(), " gamma)"),
            where());
    for (Eigen::Index a = 0; a < h_.size(); ++a) {
      MAXENTFLOW_REQUIRE(std::isfinite(h_(a)) && h_(a) > 0,
              detail::cat("nodal spacing h must be positive, got h = ", h_(a)), where_node(a));
      MAXENTFLOW_REQUIRE(std::isfinite(gamma_(a)) && gamma_(a) > 0,
              detail::cat("gamma must be positive, got gamma = ", gamma_(a)), where_node(a));
    }
    beta_ = gamma_.array() / h_.array().square();  // Eq. (2): beta_a = gamma_a / h_a^2
    setup();
  }

  /// One gamma (params::gamma) for all nodes, per-node h.
  MaxEntBasis(Points nodes, Eigen::VectorXd h, params prm = {})
      : MaxEntBasis(std::move(nodes), std::move(h), Eigen::VectorXd(), prm, 0) {}

  /// One gamma (params::gamma) for all nodes; h_a is the mean distance to the
  /// node's natural (Delaunay) neighbours, as in the paper.
  explicit MaxEntBasis(const Points& nodes, params prm = {})
      : MaxEntBasis(nodes, delaunay_spacing<Dim>(nodes), prm) {}

  /// beta given directly; beta_a = 0 (a uniform prior, the global max-ent of
  /// Sukumar 2004) is allowed and gives a global support. h only scales tolerances.
  static MaxEntBasis from_beta(Points nodes, Eigen::VectorXd beta, Eigen::VectorXd h, params prm = {}) {
    return MaxEntBasis(std::move(nodes), std::move(beta), std::move(h), prm, 'b');
  }

  const Points& nodes() const { return nodes_; }
  const Eigen::VectorXd& h() const { return h_; }
  const Eigen::VectorXd& gamma() const { return gamma_; }
  const Eigen::VectorXd& beta() const { return beta_; }
  /// Support radius of each node (+inf for beta = 0).
  const Eigen::VectorXd& support_radius() const { return radius_; }
  const params& parameters() const { return prm_; }
  Eigen::Index size() const { return nodes_.cols(); }

  /// The basis at one point: nodes (ascending), values, gradients.
  struct PointValues {
    std::vector<int> node;
    std::vector<double> p;
    std::vector<double> grad;  // Dim per entry
    int iterations = 0;
    bool on_hull = false;
    Point lambda = Point::Zero();
    Eigen::Map<const Eigen::Matrix<double, Dim, Eigen::Dynamic>> gradients() const {
      return {grad.data(), Dim, static_cast<Eigen::Index>(node.size())};
    }
  };

  PointValues evaluate(const Point& x, bool gradients = true) const {
    Workspace ws;
    return to_values(evaluate_point(x, ws, nullptr, gradients, -1), ws, gradients);
  }

  /// The basis at x with a support set chosen by the caller (ascending node
  /// indices): for finite-difference checks across the support boundary and for
  /// users who manage their own neighbour lists. Interior points only.
  PointValues evaluate_on(const Point& x, const std::vector<int>& support, bool gradients = true) const {
    Workspace ws;
    const int m = static_cast<int>(support.size());
    ws.dual.reserve(m);
    double h_ref = std::numeric_limits<double>::infinity(), d_near = h_ref;
    for (int j = 0; j < m; ++j) {
      const int a = support[static_cast<std::size_t>(j)];
      MAXENTFLOW_REQUIRE(a >= 0 && a < size(), detail::cat("support node ", a, " out of range"), where());
      load(ws, j, x, nodes_.col(a), beta_(a), h_(a), h_ref, d_near);
    }
    ws.support = support;
    return to_values(solve_interior(x, ws, m, h_ref, nullptr, gradients, -1), ws, gradients);
  }

  /// The basis at every column of x (e.g. all Gauss points).
  BasisTable<Dim> evaluate(const Points& x, bool gradients = true) const {
    BasisTable<Dim> t;
    evaluate(x, t, gradients);
    return t;
  }

  /// Same, into a table whose storage is reused (no page faults when a stepper
  /// evaluates every step). Parallel over blocks of points; the result is
  /// identical for any thread count (warm starts restart at block boundaries).
  void evaluate(const Points& x, BasisTable<Dim>& t, bool gradients = true) const {
    const int n = static_cast<int>(x.cols());
    const int block = std::max(1, prm_.block);
    const int nblocks = (n + block - 1) / block;
    // Pass 1: support sizes, so every point writes straight into its place.
    t.offset.resize(static_cast<std::size_t>(n) + 1);
    t.offset[0] = 0;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; ++i) t.offset[static_cast<std::size_t>(i) + 1] = support_size(x.col(i));
    for (int i = 0; i < n; ++i) t.offset[static_cast<std::size_t>(i) + 1] += t.offset[static_cast<std::size_t>(i)];
    const auto total = static_cast<std::size_t>(t.offset[static_cast<std::size_t>(n)]);
    t.node.resize(total);
    t.p.resize(total);
    t.grad.resize(gradients ? total * Dim : 0);
    t.iterations.resize(static_cast<std::size_t>(n));
    t.on_hull.resize(static_cast<std::size_t>(n));
    // Pass 2: the dual solves.
    std::vector<std::exception_ptr> errors(static_cast<std::size_t>(nblocks));
#pragma omp parallel
    {
      Workspace ws;
#pragma omp for schedule(dynamic, 8)
      for (int b = 0; b < nblocks; ++b) {
        try {
          const int first = b * block, last = std::min(n, first + block);
          Point lambda = Point::Zero(), previous = Point::Zero();
          Tensor dlambda = Tensor::Zero();
          bool have = false;
          for (int i = first; i < last; ++i) {
            const Point xi = x.col(i);
            // Warm start from a close predecessor, moved along d lambda / dx.
            Point guess;
            const bool warm = prm_.warm_start && have && (xi - previous).norm() <= ws.last_h_ref;
            if (warm) guess = lambda + dlambda * (xi - previous);
            ws.shift_guess = warm ? ws.last_shift : std::numeric_limits<double>::quiet_NaN();
            const Info info = evaluate_point(xi, ws, warm ? &guess : nullptr, gradients, i);
            const auto s = static_cast<std::size_t>(t.offset[static_cast<std::size_t>(i)]);
            if (t.offset[static_cast<std::size_t>(i) + 1] - t.offset[static_cast<std::size_t>(i)] != info.m)
              throw Error("support size changed between passes", where_point(xi, i));
            std::copy_n(ws.support.data(), info.m, t.node.data() + s);
            std::copy_n(ws.dual.p.data(), info.m, t.p.data() + s);
            if (gradients) std::copy_n(ws.grad.data(), info.m * Dim, t.grad.data() + s * Dim);
            t.iterations[static_cast<std::size_t>(i)] = info.iterations;
            t.on_hull[static_cast<std::size_t>(i)] = info.on_hull ? 1 : 0;
            have = !info.on_hull;
            lambda = info.lambda;
            dlambda = gradients ? info.dlambda : Tensor::Zero();
            previous = xi;
          }
        } catch (...) {
          errors[static_cast<std::size_t>(b)] = std::current_exception();
        }
      }
    }
    for (auto& e : errors)  // the first failing block in point order, whatever the threads did
      if (e) std::rethrow_exception(e);
  }

 private:
  struct Workspace {
    detail::DualWorkspace<Dim> dual;
    std::vector<int> support;
    std::vector<double> grad;  // Dim per support node
    double last_h_ref = 0;
    // The dual's exponent shift: the last interior solve's, and the first
    // guess of the next (a warm-started neighbour's saves the pass for max f).
    double last_shift = std::numeric_limits<double>::quiet_NaN();
    double shift_guess = std::numeric_limits<double>::quiet_NaN();
  };
  struct Info {
    int m = 0;  // support size; results in the workspace
    int iterations = 0;
    bool on_hull = false;
    Point lambda = Point::Zero();
    Tensor dlambda = Tensor::Zero();  // d lambda* / dx (with gradients)
  };

  MaxEntBasis(Points nodes, Eigen::VectorXd a, Eigen::VectorXd b, params prm, char kind)
      : prm_(prm), nodes_(std::move(nodes)) {
    check_nodes();
    if (kind == 'b') {  // from_beta(nodes, beta = a, h = b)
      beta_ = std::move(a);
      h_ = std::move(b);
      require(beta_.size() == nodes_.cols() && h_.size() == nodes_.cols(),
              "beta and h need one value per node", where());
      for (Eigen::Index i = 0; i < beta_.size(); ++i) {
        MAXENTFLOW_REQUIRE(std::isfinite(beta_(i)) && beta_(i) >= 0,
                detail::cat("beta must be non-negative, got ", beta_(i)), where_node(i));
        MAXENTFLOW_REQUIRE(std::isfinite(h_(i)) && h_(i) > 0,
                detail::cat("nodal spacing h must be positive, got h = ", h_(i)), where_node(i));
      }
      gamma_ = beta_.array() * h_.array().square();
    } else {  // (nodes, h = a), one gamma
      h_ = std::move(a);
      require(std::isfinite(prm_.gamma) && prm_.gamma > 0,
              detail::cat("gamma must be positive, got gamma = ", prm_.gamma), where());
      require(h_.size() == nodes_.cols(),
              detail::cat("h needs one value per node (", nodes_.cols(), " nodes, ", h_.size(), " h)"),
              where());
      for (Eigen::Index i = 0; i < h_.size(); ++i)
        MAXENTFLOW_REQUIRE(std::isfinite(h_(i)) && h_(i) > 0,
                detail::cat("nodal spacing h must be positive, got h = ", h_(i)), where_node(i));
      gamma_ = Eigen::VectorXd::Constant(nodes_.cols(), prm_.gamma);
      beta_ = gamma_.array() / h_.array().square();  // Eq. (2)
    }
    setup();
  }

  std::string where() const { return detail::cat("MaxEntBasis<", Dim, ">"); }
  std::string where_node(Eigen::Index a) const {
    return detail::cat("MaxEntBasis<", Dim, ">, node ", a, " at (", nodes_.col(a).transpose(), ")");
  }
  std::string where_point(const Point& x, int id) const {
    return detail::cat("MaxEntBasis<", Dim, ">::evaluate, ", id >= 0 ? "point " : "point",
                       id >= 0 ? std::to_string(id) : std::string(), " at (", x.transpose(), ")");
  }

  void check_nodes() const {
    const Eigen::Index N = nodes_.cols();
    for (Eigen::Index a = 0; a < N; ++a)
      MAXENTFLOW_REQUIRE(nodes_.col(a).allFinite(), "node coordinate is NaN or infinite", where_node(a));
    require(N >= Dim + 1, detail::cat("need at least ", Dim + 1, " nodes, got ", N), where());
    // The cloud must span R^Dim (else no point has a max-ent basis).
    const Point mean = nodes_.rowwise().mean();
    const Points c = nodes_.colwise() - mean;
    const Tensor cov = c * c.transpose() / static_cast<double>(N);
    Eigen::SelfAdjointEigenSolver<Tensor> eig(cov, Eigen::EigenvaluesOnly);
    require(eig.eigenvalues().minCoeff() > 1e-20 * eig.eigenvalues().maxCoeff(),
            detail::cat("nodes do not span ", Dim, "-D space (all collinear/coplanar)"), where());
  }

  void setup() {
    const Eigen::Index N = nodes_.cols();
    require(prm_.tol0 > 0 && prm_.tol0 < 1,
            detail::cat("tol0 must lie in (0, 1), got ", prm_.tol0), where());
    require(prm_.newton_tol > 0 && prm_.max_iterations > 0, "Newton tolerance and iterations must be positive", where());
    radius_.resize(N);
    const double log_tol0 = -std::log(prm_.tol0);
    for (Eigen::Index a = 0; a < N; ++a)  // exp(-beta r^2) >= tol0
      radius_(a) = beta_(a) > 0 ? std::sqrt(log_tol0 / beta_(a)) : std::numeric_limits<double>::infinity();
    scale_ = nodes_.cwiseAbs().maxCoeff();
    h_min_ = h_.minCoeff();
    pad_ = prm_.hull_tol * h_.maxCoeff() + 16 * std::numeric_limits<double>::epsilon() * scale_;
    hull_ = detail::hull_halfspaces(Points(nodes_), on_hull_tol(h_min_));
    grid_.build(nodes_, radius_, beta_, h_, hull_, hull_pad());
    // Coincident nodes: any two closer than 1e-10 of their spacing.
    for (Eigen::Index a = 0; a < N; ++a) {
      const Point xa = nodes_.col(a);
      const auto cand = grid_.candidates(grid_.cell_of(xa));
      for (int i = 0; i < cand.size && cand.node[i] < a; ++i) {  // candidates ascend
        const double tol = 1e-10 * std::min(h_(a), h_(cand.node[i]));
        if ((nodes_.col(cand.node[i]) - xa).squaredNorm() <= tol * tol)
          throw Error(detail::cat("coincident nodes ", cand.node[i], " and ", a), where_node(a));
      }
    }
  }

  double hull_pad() const { return pad_; }
  double on_hull_tol(double h_ref) const {
    return prm_.hull_tol * h_ref + 16 * std::numeric_limits<double>::epsilon() * scale_;
  }

  PointValues to_values(const Info& info, const Workspace& ws, bool gradients) const {
    PointValues out;
    out.node.assign(ws.support.begin(), ws.support.begin() + info.m);
    out.p.assign(ws.dual.p.data(), ws.dual.p.data() + info.m);
    if (gradients) out.grad.assign(ws.grad.begin(), ws.grad.begin() + info.m * Dim);
    out.iterations = info.iterations;
    out.on_hull = info.on_hull;
    out.lambda = info.lambda;
    return out;
  }

  // Loads a node as the j-th support entry: dx = x - x_a, beta, the prior exponent.
  template <class XA>
  static void load(Workspace& ws, int j, const Point& x, const XA& xa, double beta, double h,
                   double& h_ref, double& d_near) {
    double d2 = 0;
    for (int k = 0; k < Dim; ++k) {
      const double d = x(k) - xa[k];
      ws.dual.dx[k](j) = d;
      d2 += d * d;
    }
    ws.dual.beta(j) = beta;
    ws.dual.q(j) = -beta * d2;
    if (d2 < d_near) {  // the nearest node's spacing scales the tolerances
      d_near = d2;
      h_ref = h;
    }
  }

  int support_size(const Point& x) const {
    if (!x.allFinite()) return 0;
    const auto c = grid_.candidates(grid_.cell_of(x));
    int m = 0;
#pragma omp simd reduction(+ : m)
    for (int i = 0; i < c.size; ++i) {
      double d2 = 0;
      for (int k = 0; k < Dim; ++k) d2 += (x(k) - c.x[k][i]) * (x(k) - c.x[k][i]);
      m += d2 <= c.r2[i] ? 1 : 0;
    }
    return m;
  }

  // Support of x: candidates of its cell within their radius (ascending). First
  // the indices of the candidates inside, with no branch (about a third are, in
  // a pattern the branch predictor misses), then their data.
  int gather(const Point& x, int cell, Workspace& ws) const {
    const auto c = grid_.candidates(cell);
    ws.dual.reserve(c.size);
    ws.support.resize(static_cast<std::size_t>(c.size));
    int* node = ws.support.data();  // candidate positions first, node indices after
    int m = 0;
    for (int i = 0; i < c.size; ++i) {
      double d2 = 0;
      for (int k = 0; k < Dim; ++k) d2 += (x(k) - c.x[k][i]) * (x(k) - c.x[k][i]);
      node[m] = i;
      m += d2 <= c.r2[i] ? 1 : 0;
    }
    // Then their data; the nearest node (its spacing scales the tolerances)
    // is found without a branch per entry.
    double d_near = std::numeric_limits<double>::infinity();
    int j_near = -1;
    for (int j = 0; j < m; ++j) {
      const int i = node[j];
      double d2 = 0;
      for (int k = 0; k < Dim; ++k) {
        const double d = x(k) - c.x[k][i];
        ws.dual.dx[k](j) = d;
        d2 += d * d;
      }
      const int a = c.node[i];
      const double beta = c.node_beta[a];
      ws.dual.beta(j) = beta;
      ws.dual.q(j) = -beta * d2;  // the prior's exponent
      node[j] = a;
      const bool nearer = d2 < d_near;
      d_near = nearer ? d2 : d_near;
      j_near = nearer ? j : j_near;
    }
    ws.support.resize(static_cast<std::size_t>(m));
    ws.last_h_ref = j_near >= 0 ? c.node_h[node[j_near]] : h_min_;
    return m;
  }

  Info evaluate_point(const Point& x, Workspace& ws, const Point* lambda0, bool gradients, int id) const {
    if (!x.allFinite()) throw Error("evaluation point is NaN or infinite", where_point(x, id));
    if (!grid_.in_box(x, hull_pad()))
      throw Error("point lies outside the convex hull of the nodes", where_point(x, id));
    const int cell = grid_.cell_of(x);
    if (grid_.status(cell) == detail::SupportGrid<Dim>::Cell::exterior)
      throw Error("point lies outside the convex hull of the nodes", where_point(x, id));
    const int m = gather(x, cell, ws);
    const double h_ref = ws.last_h_ref;
    if (m < Dim + 1)
      throw Error(detail::cat("only ", m, " node(s) in the support, need at least ", Dim + 1,
                              " affinely spanning (lower gamma or tol0, or fill the gap)"),
                  where_point(x, id));
    // Points on hull facets: the lower-dimensional max-ent (weak Kronecker-delta).
    if (grid_.status(cell) == detail::SupportGrid<Dim>::Cell::boundary) {
      const double tol = on_hull_tol(h_ref);
      Point inward = Point::Zero();
      int on = -1;
      bool on_within = false;  // x lies within the chosen facet's extent
      for (int f : grid_.facets(cell)) {
        const auto& F = hull_[static_cast<std::size_t>(f)];
        const double s = F.n.dot(x) - F.c;
        if (s > tol)
          throw Error(detail::cat("point lies outside the convex hull of the nodes (by ", s, ")"),
                      where_point(x, id));
        if (std::abs(s) <= tol) {
          // Next to a nearly straight hull vertex, x is within tol of both
          // facets' lines: restrict to the facet that x lies on, not to the
          // neighbour whose line merely passes within tol.
          const bool within = ((x - F.lo).array() >= -tol).all() && ((F.hi - x).array() >= -tol).all();
          if (on < 0 || (within && !on_within)) {
            on = f;
            on_within = within;
          }
          inward -= F.n;
        }
      }
      if (on >= 0)
        return solve_on_hull(x, ws, m, h_ref, hull_[static_cast<std::size_t>(on)], inward, gradients, id);
      // Just inside a facet (beyond tol, within near_hull) the dual is too stiff
      // for Newton: there the basis is, to that distance, the facet's own.
      const double near_hull = 1e-6 * h_ref;
      int nearest = -1;
      double s_near = -near_hull;
      for (int f : grid_.facets(cell)) {
        const auto& F = hull_[static_cast<std::size_t>(f)];
        const double s = F.n.dot(x) - F.c;
        const bool within = ((x - F.lo).array() >= -near_hull).all() && ((F.hi - x).array() >= -near_hull).all();
        if (within && s >= s_near) {
          nearest = f;
          s_near = s;
        }
      }
      if (nearest >= 0) {
        try {
          return solve_interior(x, ws, m, h_ref, lambda0, gradients, id);
        } catch (const Error&) {
          const auto& F = hull_[static_cast<std::size_t>(nearest)];
          gather(x, cell, ws);
          try {
            return solve_on_hull(x, ws, m, h_ref, F, -F.n, gradients, id, -s_near);
          } catch (const Error&) {
            return on_support_hull(x, cell, ws, m, h_ref, gradients, id);
          }
        }
      }
    }
    try {
      return solve_interior(x, ws, m, h_ref, lambda0, gradients, id);
    } catch (const Error&) {
      return on_support_hull(x, cell, ws, m, h_ref, gradients, id);
    }
  }

  // Called while an Error from the dual is being handled: x on (or within
  // 1e-6 h of) the hull of its support but not of the cloud, e.g. on a side
  // that is straight over the support and concave at large (a workpiece side
  // dented by 1e-5 h over its length as a cutting tool approaches). The
  // basis there is that facet's, as on the cloud's hull. Where it is not, or
  // the facet's basis fails too, the dual's Error goes on.
  Info on_support_hull(const Point& x, int cell, Workspace& ws, int m, double h_ref, bool gradients,
                       int id) const {
    const std::exception_ptr dual_error = std::current_exception();
    gather(x, cell, ws);
    const std::optional<detail::HalfSpace<Dim>> F = support_facet(x, ws, m, h_ref);
    if (!F) std::rethrow_exception(dual_error);
    try {
      return solve_on_hull(x, ws, m, h_ref, *F, -F->n, gradients, id, std::max(0.0, F->c - F->n.dot(x)));
    } catch (const Error&) {
      std::rethrow_exception(dual_error);
    }
  }

  // The facet of the support's convex hull that x lies on or within 1e-6
  // h_ref of (x within the facet's extent), if any.
  std::optional<detail::HalfSpace<Dim>> support_facet(const Point& x, const Workspace& ws, int m,
                                                      double h_ref) const {
    Points xa(Dim, m);
    for (int j = 0; j < m; ++j) xa.col(j) = nodes_.col(ws.support[static_cast<std::size_t>(j)]);
    const double near = 1e-6 * h_ref, tol = on_hull_tol(h_ref);
    std::optional<detail::HalfSpace<Dim>> best;
    double s_best = -near;
    for (const auto& F : detail::hull_halfspaces(xa, tol)) {
      const double s = F.n.dot(x) - F.c;
      const bool within = ((x - F.lo).array() >= -near).all() && ((F.hi - x).array() >= -near).all();
      if (within && s >= s_best && s <= tol) {
        best = F;
        s_best = s;
      }
    }
    return best;
  }

  Info solve_interior(const Point& x, Workspace& ws, int m, double h_ref, const Point* lambda0,
                      bool gradients, int id) const {
    const Point start = lambda0 ? *lambda0 : Point::Zero();
    auto res = detail::solve_dual<Dim>(ws.dual, m, start, prm_.newton_tol * h_ref, prm_.max_iterations,
                                       lambda0 ? ws.shift_guess : std::numeric_limits<double>::quiet_NaN());
    // Safeguard: a warm start predicted across a kink of lambda(x) (e.g. from a
    // hull point) can start Newton where it cannot descend; restart cold.
    if (res.status != detail::DualStatus::converged && lambda0)
      res = detail::solve_dual<Dim>(ws.dual, m, Point::Zero(), prm_.newton_tol * h_ref, prm_.max_iterations);
    // Very close to a hull corner the dual is so stiff that Newton stalls a few
    // digits short of newton_tol; a reproduction error below 1e-8 h is accepted.
    const bool attainable = res.status != detail::DualStatus::not_finite &&
                            res.residual() <= 1e-8 * h_ref;
    if (res.status != detail::DualStatus::converged && !attainable) {
      const char* why = res.status == detail::DualStatus::max_iterations       ? "no convergence"
                        : res.status == detail::DualStatus::line_search_failed ? "line search failed"
                                                                               : "non-finite values";
      throw Error(detail::cat("max-ent dual solve failed (", why, ") after ", res.iterations,
                              " Newton iterations, |r| = ", res.residual(), " (tolerance ",
                              prm_.newton_tol * h_ref, "), ", m,
                              " support nodes; the point may lie outside the hull of its neighbours"),
                  where_point(x, id));
    }
    ws.last_shift = res.shift;
    Info info;
    info.m = m;
    info.iterations = res.iterations;
    info.lambda = res.lambda;
    if (gradients) {
      info.dlambda = gradients_into(ws, m, res.r, res.J);
      // Found by libFuzzer: at a point on a node whose neighbours' weights
      // underflow (a large gamma), J is singular in floating point.
      const bool finite = info.dlambda.allFinite() &&
                          std::all_of(ws.grad.begin(), ws.grad.begin() + m * Dim,
                                      [](double g) { return std::isfinite(g); });
      if (!finite)
        throw Error(detail::cat("max-ent gradients are not finite: the dual's covariance J is singular (",
                                m, " support nodes, det J = ", res.J.determinant(),
                                "); a smaller gamma or a point off the node"),
                    where_point(x, id));
    }
    return info;
  }

  // grad p_a = p_a [ r_b - 2 beta_a dx_a + (J_b - I) J^-1 dx_a ], with
  // r_b = 2 sum beta_b p_b dx_b, J_b = 2 sum beta_b p_b dx_b (x) dx_b, J = sum p_b dx_b (x) dx_b
  // (differentiating Eq. 5 with lambda*(x) from r(x, lambda*) = 0; the beta terms
  // are those of node-dependent beta). dx_a is taken about its mean r (zero at the
  // exact lambda*): then sum_a grad p_a = 0 holds to round-off even where J is
  // nearly singular (next to the hull), instead of to |J^-1 r|.
  // Returns d lambda* / dx = J^-1 (J_b - I), which warm-starts the next point.
  Tensor gradients_into(Workspace& ws, int m, const Point& r, const Tensor& J) const {
    const double* p = ws.dual.p.data();
    const double* beta = ws.dual.beta.data();
    const double* x0 = ws.dual.dx[0].data();
    const double* x1 = ws.dual.dx[Dim > 1 ? 1 : 0].data();
    const double* x2 = ws.dual.dx[Dim > 2 ? 2 : 0].data();
    // rb and Jb in one vectorized pass.
    double r0 = 0, r1 = 0, r2 = 0, J00 = 0, J01 = 0, J02 = 0, J11 = 0, J12 = 0, J22 = 0;
#pragma omp simd reduction(+ : r0, r1, r2, J00, J01, J02, J11, J12, J22)
    for (int j = 0; j < m; ++j) {
      const double bp = 2.0 * beta[j] * p[j], a = bp * x0[j];
      r0 += a;
      J00 += a * x0[j];
      if constexpr (Dim > 1) {
        const double b = bp * x1[j];
        r1 += b;
        J01 += a * x1[j];
        J11 += b * x1[j];
        if constexpr (Dim > 2) {
          const double c = bp * x2[j];
          r2 += c;
          J02 += a * x2[j];
          J12 += b * x2[j];
          J22 += c * x2[j];
        }
      }
    }
    const double rb_all[3] = {r0, r1, r2};
    const double Jb_all[3][3] = {{J00, J01, J02}, {J01, J11, J12}, {J02, J12, J22}};
    Point rb;
    Tensor Jb;
    for (int k = 0; k < Dim; ++k) {
      rb(k) = rb_all[k];
      for (int l = 0; l < Dim; ++l) Jb(k, l) = Jb_all[k][l];
    }
    const Tensor M = (Jb - Tensor::Identity()) * J.inverse();
    // grad_k p_j = p_j (rb_k - 2 beta_j dx_kj + sum_l M_kl (dx_lj - r_l)), as
    // p_j ((rb - M r)_k + sum_l (M_kl - 2 beta_j delta_kl) dx_lj).
    const Point c = rb - M * r;
    ws.grad.resize(static_cast<std::size_t>(m) * Dim);
    double* g = ws.grad.data();
    double Mm[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}, cm[3] = {0, 0, 0};  // padded to 3-D
    for (int k = 0; k < Dim; ++k) {
      cm[k] = c(k);
      for (int l = 0; l < Dim; ++l) Mm[k][l] = M(k, l);
    }
    const double M00 = Mm[0][0], M01 = Mm[0][1], M02 = Mm[0][2], M10 = Mm[1][0], M11 = Mm[1][1],
                 M12 = Mm[1][2], M20 = Mm[2][0], M21 = Mm[2][1], M22 = Mm[2][2];
    const double c0 = cm[0], c1 = cm[1], c2 = cm[2];
#pragma omp simd
    for (int j = 0; j < m; ++j) {
      const double tb = 2.0 * beta[j], pj = p[j];
      if constexpr (Dim == 1) {
        g[j] = pj * (c0 + (M00 - tb) * x0[j]);
      } else if constexpr (Dim == 2) {
        g[2 * j] = pj * (c0 + (M00 - tb) * x0[j] + M01 * x1[j]);
        g[2 * j + 1] = pj * (c1 + M10 * x0[j] + (M11 - tb) * x1[j]);
      } else {
        g[3 * j] = pj * (c0 + (M00 - tb) * x0[j] + M01 * x1[j] + M02 * x2[j]);
        g[3 * j + 1] = pj * (c1 + M10 * x0[j] + (M11 - tb) * x1[j] + M12 * x2[j]);
        g[3 * j + 2] = pj * (c2 + M20 * x0[j] + M21 * x1[j] + (M22 - tb) * x2[j]);
      }
    }
    return M.transpose();
  }

  Info solve_on_hull(const Point& x, Workspace& ws, int m, double h_ref,
                     const detail::HalfSpace<Dim>& facet, const Point& inward, bool gradients,
                     int id, double depth = 0.0) const {
    Points xa(Dim, m);
    for (int j = 0; j < m; ++j) xa.col(j) = nodes_.col(ws.support[static_cast<std::size_t>(j)]);
    const Eigen::ArrayXd beta = ws.dual.beta.head(m);
    Eigen::ArrayXd p = Eigen::ArrayXd::Zero(m);
    Info info;
    info.m = m;
    info.on_hull = true;
    // Nodes count as on the facet within the point's tolerance; where the cloud's
    // side is straight only to a few 1e-10 h (round-off of updated-Lagrangian
    // steps), the nodes next to x can sit just beyond it, so the facet's nodes
    // no longer bracket x: widen the node tolerance by decades, up to 1e-6 h.
    const double tol_max = std::max(1e-6 * h_ref, 2.0 * depth);
    for (double tol = std::max(on_hull_tol(h_ref), 2.0 * depth);; tol *= 10.0) {
      try {
        p.setZero();
        info.iterations = restrict_to_facet<Dim>(x, xa, beta, facet.n, facet.c, tol, p, id, x);
        break;
      } catch (const Error&) {
        if (tol * 10.0 > tol_max) throw;
      }
    }
    if (gradients) {
      // Gradients do not exist on the facet from outside; take the one-sided limit
      // just inside, with the same support.
      // At a sharp hull vertex (a spike of the free surface) the dual just
      // inside is too stiff to solve; step further in, up to 1e-3 h (the
      // gradient of a function that is a Kronecker delta there is a limit
      // of little accuracy anyway).
      for (double offset = prm_.gradient_offset;; offset *= 100.0) {
        const Point xin = x + offset * h_ref * inward;
        double hr = 0, dn = std::numeric_limits<double>::infinity();
        for (int j = 0; j < m; ++j) {
          const int a = ws.support[static_cast<std::size_t>(j)];
          load(ws, j, xin, nodes_.col(a), beta_(a), h_(a), hr, dn);
        }
        try {
          const Info in = solve_interior(xin, ws, m, h_ref, nullptr, true, id);
          info.iterations += in.iterations;
          break;
        } catch (const Error&) {
          if (offset * 100.0 > 1e-3) throw;
        }
      }
    }
    ws.dual.p.head(m) = p;
    return info;
  }

  // Max-ent restricted to the facet {n . y = c} of a D-dimensional problem: the
  // nodes on it, in D-1 coordinates of the facet. Returns Newton iterations.
  template <int D>
  int restrict_to_facet(const Eigen::Matrix<double, D, 1>& y,
                        const Eigen::Matrix<double, D, Eigen::Dynamic>& ya, const Eigen::ArrayXd& beta,
                        const Eigen::Matrix<double, D, 1>& n, double c, double tol,
                        Eigen::ArrayXd& p, int id, const Point& x) const {
    std::vector<int> on;
    for (Eigen::Index j = 0; j < ya.cols(); ++j)
      if (std::abs(n.dot(ya.col(j)) - c) <= tol) on.push_back(static_cast<int>(j));
    if constexpr (D == 1) {
      if (on.size() != 1)
        throw Error(detail::cat(on.empty() ? "no node" : "coincident nodes",
                                " at the end of the hull"), where_point(x, id));
      p(on[0]) = 1.0;  // Kronecker-delta at a hull vertex
      return 0;
    } else {
      if (on.empty()) throw Error("no support node on the hull facet", where_point(x, id));
      const Eigen::Matrix<double, D - 1, D> T = detail::tangent_frame<D>(n);
      const Eigen::Matrix<double, D - 1, 1> z = T * y;
      Eigen::Matrix<double, D - 1, Eigen::Dynamic> za(D - 1, static_cast<Eigen::Index>(on.size()));
      Eigen::ArrayXd b(static_cast<Eigen::Index>(on.size()));
      for (std::size_t k = 0; k < on.size(); ++k) {
        za.col(static_cast<Eigen::Index>(k)) = T * ya.col(on[k]);
        b(static_cast<Eigen::Index>(k)) = beta(on[k]);
      }
      Eigen::ArrayXd q = Eigen::ArrayXd::Zero(static_cast<Eigen::Index>(on.size()));
      const int it = solve_restricted<D - 1>(z, za, b, tol, q, id, x);
      for (std::size_t k = 0; k < on.size(); ++k) p(on[k]) = q(static_cast<Eigen::Index>(k));
      return it;
    }
  }

  // D-dimensional max-ent of a small node set (a hull facet's), with its own hull
  // check: a point on an edge of the facet recurses once more.
  template <int D>
  int solve_restricted(const Eigen::Matrix<double, D, 1>& z,
                       const Eigen::Matrix<double, D, Eigen::Dynamic>& za, const Eigen::ArrayXd& beta,
                       double tol, Eigen::ArrayXd& p, int id, const Point& x) const {
    const Eigen::Index m = za.cols();
    if (m < D + 1) {
      if constexpr (D == 1) {
        return restrict_to_facet<1>(z, za, beta, Eigen::Matrix<double, 1, 1>::Ones(), z(0), tol, p, id, x);
      } else {
        throw Error("too few support nodes on the hull facet", where_point(x, id));
      }
    }
    for (const auto& F : detail::hull_halfspaces(Eigen::Matrix<double, D, Eigen::Dynamic>(za), tol)) {
      const double s = F.n.dot(z) - F.c;
      if (s > tol) throw Error("point lies outside the convex hull of the nodes", where_point(x, id));
      if (std::abs(s) <= tol) return restrict_to_facet<D>(z, za, beta, F.n, F.c, tol, p, id, x);
    }
    detail::DualWorkspace<D> ws;
    ws.reserve(m);
    for (Eigen::Index j = 0; j < m; ++j) {
      const Eigen::Matrix<double, D, 1> d = z - za.col(j);
      for (int k = 0; k < D; ++k) ws.dx[k](j) = d(k);
      ws.beta(j) = beta(j);
      ws.q(j) = -beta(j) * d.squaredNorm();
    }
    const double h_scale = (za.rowwise().maxCoeff() - za.rowwise().minCoeff()).maxCoeff() /
                           std::max<double>(1.0, static_cast<double>(m - 1));
    const auto res = detail::solve_dual<D>(ws, m, Eigen::Matrix<double, D, 1>::Zero(),
                                           prm_.newton_tol * h_scale, prm_.max_iterations);
    if (res.status != detail::DualStatus::converged)
      throw Error(detail::cat("max-ent dual solve on a hull facet failed after ", res.iterations,
                              " iterations, |r| = ", res.residual()),
                  where_point(x, id));
    p = ws.p.head(m);
    return res.iterations;
  }

  params prm_;
  Points nodes_;
  Eigen::VectorXd h_, gamma_, beta_, radius_;
  double scale_ = 1, h_min_ = 1, pad_ = 0;
  std::vector<detail::HalfSpace<Dim>> hull_;
  detail::SupportGrid<Dim> grid_;
};

}  // namespace maxentflow

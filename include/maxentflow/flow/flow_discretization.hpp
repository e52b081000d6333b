// maxentflow: the max-ent basis at the quadrature points of an integration mesh,
// laid out per triangle for assembly, with the consistent-integration correction.
#pragma once

#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/core/parallel.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>

namespace maxentflow {

/// Plane strain or axisymmetric (x = (r, z), the axis at r = 0).
enum class Geometry { plane_strain, axisymmetric };

struct FlowDiscretizationParams {
  int triangle_points = 3;             ///< Gauss points per triangle (1, 3, 6, 7, 12)
  int segment_points = 3;              ///< Gauss-Legendre points per edge (1..8)
  bool consistent_integration = true;  ///< false: the paper's plain Gauss quadrature
};

/// Per triangle T of the integration mesh: the nodes U_T whose basis functions
/// are nonzero somewhere on T (its Gauss points or its edges' Gauss points),
/// and at each Gauss point of T the values p_a and gradients of all a in U_T.
///
/// Consistent integration (spec V1; Ortiz-Bernardin, Puso & Sukumar 2015):
/// max-ent functions are not polynomials, so Gauss quadrature breaks the
/// discrete divergence theorem sum_q w_q grad p_a(x_q) = int_dT p_a n, and
/// with it the patch test. Each gradient in T gets the constant
///   c_a = ( int_dT p_a n ds - sum_q w_q grad p_a(x_q) ) / |T|
/// (edge integral by Gauss-Legendre). Linear fields keep their exact gradients
/// and interior edges cancel, so the identity holds on the whole domain.
/// Axisymmetric: the r-weighted identities int_T (r dp/dr + p) = int_dT p n_r r
/// and int_T r dp/dz = int_dT p n_z r, with |T| replaced by int_T r.
class FlowDiscretization {
 public:
  using Mesh = IntegrationMesh<2>;
  using Basis = MaxEntBasis<2>;

  using params = FlowDiscretizationParams;

  FlowDiscretization() = default;
  FlowDiscretization(const Mesh& mesh, const Basis& basis, Geometry g, const params& prm = {}) {
    build(mesh, basis, g, prm);
  }

  void build(const Mesh& mesh, const Basis& basis, Geometry g, const params& prm = {});

  /// The linear-triangle (P1) companion of a max-ent discretization `maxent`
  /// on the same mesh: U_T = the three vertices, barycentric values and
  /// constant gradients at the same Gauss points, the same weights and rho.
  /// Assembled with the same material and tau it is spectrally close to the
  /// max-ent system (max-ent tends to P1 as gamma grows) but has ~7 neighbours
  /// per node instead of ~90, so its LU is cheap: the Krylov preconditioner.
  void build_linear(const Mesh& mesh, const FlowDiscretization& maxent);

  Geometry geometry() const { return geometry_; }
  bool axisymmetric() const { return geometry_ == Geometry::axisymmetric; }
  const params& parameters() const { return prm_; }
  int number_of_nodes() const { return n_nodes_; }

  // --- cells ---
  int cells() const { return static_cast<int>(node_offset_.size()) - 1; }
  int points_per_cell() const { return nq_; }
  /// U_T, ascending.
  std::span<const int> nodes(int t) const {
    return {node_.data() + node_offset_[t], static_cast<std::size_t>(node_offset_[t + 1] - node_offset_[t])};
  }
  int count(int t) const { return node_offset_[t + 1] - node_offset_[t]; }
  /// Gauss point q of triangle t has global index t * points_per_cell() + q.
  const Eigen::Matrix2Xd& points() const { return x_; }
  /// Weight: area (plane strain) or area * 2 pi r (axisymmetric).
  double weight(int g) const { return w_[g]; }
  /// rho of Eq. (14): the mean h_a over the support of the point.
  double rho(int g) const { return rho_[g]; }
  /// p_a at point q of triangle t, in the order of nodes(t).
  const double* values(int t, int q) const { return p_.data() + value_offset_[t] + q * count(t); }
  /// Gradients (x, y interleaved per node), corrected if consistent_integration.
  const double* gradients(int t, int q) const {
    return dp_.data() + 2 * (value_offset_[t] + q * count(t));
  }
  double mean_nodes_per_cell() const {
    return cells() ? static_cast<double>(node_.size()) / cells() : 0.0;
  }

  // --- thread ownership (parallel assembly) ---
  /// Node a's place in a spatial order of the nodes (recursive coordinate
  /// bisection). A thread that owns a range of ranks owns a compact region,
  /// so few cells touch the nodes of two threads (such a cell is integrated
  /// by both): on E2 after 100 steps of rezoning, whose new nodes take the
  /// last indices, ranges of node indices left 32 % of the cells to both of
  /// two threads.
  int rank(int a) const { return rank_[static_cast<std::size_t>(a)]; }
  /// The smallest and largest rank in U_T.
  int min_rank(int t) const { return cell_rank_[2 * static_cast<std::size_t>(t)]; }
  int max_rank(int t) const { return cell_rank_[2 * static_cast<std::size_t>(t) + 1]; }

  // --- edges (for boundary conditions and tractions) ---
  int points_per_edge() const { return ne_; }
  /// Gauss points of mesh edge e are e * points_per_edge() + k, from edge.a to edge.b.
  const Eigen::Matrix2Xd& edge_points() const { return edge_x_; }
  /// Plain length weights (no 2 pi r).
  const Eigen::VectorXd& edge_weights() const { return edge_w_; }
  /// Parameter s in [0, 1] of edge point k along its edge (from edge.a).
  double edge_parameter(int k) const { return segment_rule(prm_.segment_points).t[k]; }
  /// The basis at the Gauss points of the boundary edges (point k of mesh
  /// edge e is e * points_per_edge() + k). Interior edges' points have no
  /// entries once built: their basis served the gradient correction only
  /// (kept, it was 7 % of the memory of bench_flow's 64k-node solve).
  const BasisTable<2>& edge_basis() const { return edge_basis_; }

  /// max over nodes of |sum_q w_q grad p_a - int_dOmega p_a n| relative to the
  /// largest |int_dOmega p_a n|: the discrete divergence-theorem defect
  /// (round-off with the correction); the r-weighted identities if axisymmetric.
  double divergence_defect(const Mesh& mesh) const;

 private:
  // The build's phases (Eq. 19's cell sets, the basis at the Gauss points, and
  // the consistent-integration correction of the gradients).
  std::vector<std::vector<int>> cell_unions(const Mesh& mesh, const BasisTable<2>& cell_basis) const;
  double fill_cell(int t, const std::vector<int>& u, const BasisTable<2>& cell_basis, const Eigen::VectorXd& wq_of,
                   const Eigen::VectorXd& h);
  void correct_gradients(int t, const std::vector<int>& u, const Mesh& mesh, const Eigen::VectorXd& wq_of,
                         double measure, std::vector<double>& boundary_integral);
  void keep_boundary_edge_basis(const Mesh& mesh);
  void rank_nodes(const Mesh::Points& x);
  void rank_cells();

  params prm_;
  Geometry geometry_ = Geometry::plane_strain;
  int n_nodes_ = 0, nq_ = 0, ne_ = 0;
  std::vector<int> node_offset_{0}, node_, value_offset_{0};
  std::vector<int> rank_, cell_rank_;
  std::vector<double> p_, dp_, w_, rho_;
  Eigen::Matrix2Xd x_, edge_x_;
  Eigen::VectorXd edge_w_;
  BasisTable<2> edge_basis_;
};

inline void FlowDiscretization::build(const Mesh& mesh, const Basis& basis, Geometry g,
                                      const params& prm) {
  const char* where = "FlowDiscretization::build";
  require(!mesh.empty(), "the integration mesh is empty", where);
  require(basis.size() == mesh.number_of_nodes(),
          detail::cat("basis has ", basis.size(), " nodes, mesh ", mesh.number_of_nodes()), where);
  prm_ = prm;
  geometry_ = g;
  n_nodes_ = static_cast<int>(mesh.number_of_nodes());
  const TriangleRule& trule = triangle_rule(prm.triangle_points);
  const SegmentRule& srule = segment_rule(prm.segment_points);
  nq_ = static_cast<int>(trule.weight.size());
  ne_ = static_cast<int>(srule.weight.size());

  // 1. Gauss points of the cells and edges, and the basis there.
  const auto cq = mesh.cell_quadrature(trule, false);
  const auto eq = mesh.edge_quadrature(srule, false);
  x_ = cq.x;
  edge_x_ = eq.x;
  edge_w_ = eq.w;
  if (axisymmetric())
    for (Eigen::Index k = 0; k < x_.cols(); ++k)
      MAXENTFLOW_REQUIRE(x_(0, k) > 0,
                         detail::cat("axisymmetric Gauss point at r = ", x_(0, k),
                                     " <= 0: the material crosses the axis"),
                         detail::cat(where, ", triangle ", cq.cell[static_cast<std::size_t>(k)]));
  const BasisTable<2> cell_basis = basis.evaluate(x_, true);
  basis.evaluate(edge_x_, edge_basis_, false);

  // 2. U_T of every cell, and storage for its values and gradients.
  const int nt = static_cast<int>(mesh.number_of_triangles());
  const std::vector<std::vector<int>> unions = cell_unions(mesh, cell_basis);
  node_offset_.assign(static_cast<std::size_t>(nt) + 1, 0);
  value_offset_.assign(static_cast<std::size_t>(nt) + 1, 0);
  for (int t = 0; t < nt; ++t) {
    const int n = static_cast<int>(unions[static_cast<std::size_t>(t)].size());
    node_offset_[t + 1] = node_offset_[t] + n;
    value_offset_[t + 1] = value_offset_[t] + n * nq_;
  }
  node_.resize(static_cast<std::size_t>(node_offset_.back()));
  p_.assign(static_cast<std::size_t>(value_offset_.back()), 0.0);
  dp_.assign(2 * static_cast<std::size_t>(value_offset_.back()), 0.0);
  w_.resize(static_cast<std::size_t>(nt * nq_));
  rho_.resize(static_cast<std::size_t>(nt * nq_));

  // 3. Values, gradients, rho, weights; then the gradient correction.
#pragma omp parallel
  {
    std::vector<double> boundary_integral;  // int_dT p_a n (r), 2 per node of U_T
#pragma omp for schedule(dynamic, 256)
    for (int t = 0; t < nt; ++t) {
      const auto& u = unions[static_cast<std::size_t>(t)];
      std::copy(u.begin(), u.end(), node_.begin() + node_offset_[t]);
      const double measure = fill_cell(t, u, cell_basis, cq.w, basis.h());
      if (prm_.consistent_integration) correct_gradients(t, u, mesh, cq.w, measure, boundary_integral);
    }
  }
  keep_boundary_edge_basis(mesh);
  rank_nodes(mesh.nodes());
  rank_cells();
}

inline void FlowDiscretization::rank_nodes(const Mesh::Points& x) {
  std::vector<int> order(static_cast<std::size_t>(n_nodes_));
  for (int a = 0; a < n_nodes_; ++a) order[static_cast<std::size_t>(a)] = a;
  // Halve each range at the median along its bounding box's longer side.
  struct Range {
    std::size_t lo, hi;
  };
  std::vector<Range> todo{{0, order.size()}};
  while (!todo.empty()) {
    const Range r = todo.back();
    todo.pop_back();
    if (r.hi - r.lo < 2) continue;
    Eigen::Vector2d lo = x.col(order[r.lo]), hi = lo;
    for (std::size_t i = r.lo; i < r.hi; ++i) {
      lo = lo.cwiseMin(x.col(order[i]));
      hi = hi.cwiseMax(x.col(order[i]));
    }
    const int axis = hi.x() - lo.x() >= hi.y() - lo.y() ? 0 : 1;
    const std::size_t mid = r.lo + (r.hi - r.lo) / 2;
    const auto base = order.begin();
    std::nth_element(base + static_cast<std::ptrdiff_t>(r.lo), base + static_cast<std::ptrdiff_t>(mid),
                     base + static_cast<std::ptrdiff_t>(r.hi),
                     [&](int a, int b) { return x(axis, a) < x(axis, b) || (x(axis, a) == x(axis, b) && a < b); });
    todo.push_back({r.lo, mid});
    todo.push_back({mid, r.hi});
  }
  rank_.resize(order.size());
  for (std::size_t i = 0; i < order.size(); ++i) rank_[static_cast<std::size_t>(order[i])] = static_cast<int>(i);
}

inline void FlowDiscretization::rank_cells() {
  cell_rank_.resize(2 * static_cast<std::size_t>(cells()));
  for (int t = 0; t < cells(); ++t) {
    int lo = n_nodes_, hi = -1;
    for (const int a : nodes(t)) {
      lo = std::min(lo, rank(a));
      hi = std::max(hi, rank(a));
    }
    cell_rank_[2 * static_cast<std::size_t>(t)] = lo;
    cell_rank_[2 * static_cast<std::size_t>(t) + 1] = hi;
  }
}

inline void FlowDiscretization::keep_boundary_edge_basis(const Mesh& mesh) {
  std::vector<char> boundary(mesh.edges().size(), 0);
  for (const auto& seg : mesh.boundary_segments()) boundary[static_cast<std::size_t>(seg.edge)] = 1;
  const BasisTable<2>& all = edge_basis_;
  BasisTable<2> kept;
  const int np = all.size();
  kept.offset.resize(static_cast<std::size_t>(np) + 1);
  kept.offset[0] = 0;
  for (int i = 0; i < np; ++i)
    kept.offset[static_cast<std::size_t>(i) + 1] =
        kept.offset[static_cast<std::size_t>(i)] + (boundary[static_cast<std::size_t>(i / ne_)] ? all.count(i) : 0);
  kept.node.resize(static_cast<std::size_t>(kept.offset.back()));
  kept.p.resize(kept.node.size());
  for (int i = 0; i < np; ++i) {
    if (!boundary[static_cast<std::size_t>(i / ne_)]) continue;
    std::copy_n(all.node.data() + all.offset[static_cast<std::size_t>(i)], all.count(i),
                kept.node.data() + kept.offset[static_cast<std::size_t>(i)]);
    std::copy_n(all.p.data() + all.offset[static_cast<std::size_t>(i)], all.count(i),
                kept.p.data() + kept.offset[static_cast<std::size_t>(i)]);
  }
  kept.iterations = all.iterations;
  kept.on_hull = all.on_hull;
  edge_basis_ = std::move(kept);
}

inline std::vector<std::vector<int>> FlowDiscretization::cell_unions(const Mesh& mesh,
                                                                     const BasisTable<2>& cell_basis) const {
  const int nt = static_cast<int>(mesh.number_of_triangles());
  std::vector<std::vector<int>> unions(static_cast<std::size_t>(nt));
#pragma omp parallel
  {
    // Each point's support is already sorted; a mark per node (the last
    // triangle that took it) keeps the union free of duplicates before the sort.
    std::vector<int> mark(static_cast<std::size_t>(n_nodes_), -1);
#pragma omp for schedule(dynamic, 256)
    for (int t = 0; t < nt; ++t) {
      std::vector<int>& u = unions[static_cast<std::size_t>(t)];
      auto take = [&](std::span<const int> s) {
        for (int a : s)
          if (mark[static_cast<std::size_t>(a)] != t) {
            mark[static_cast<std::size_t>(a)] = t;
            u.push_back(a);
          }
      };
      for (int q = 0; q < nq_; ++q) take(cell_basis.nodes(t * nq_ + q));
      for (int i = 0; i < 3; ++i) {
        const int e = mesh.triangle_edge(t, i);
        for (int k = 0; k < ne_; ++k) take(edge_basis_.nodes(e * ne_ + k));
      }
      std::sort(u.begin(), u.end());
    }
  }
  return unions;
}

inline double FlowDiscretization::fill_cell(int t, const std::vector<int>& u, const BasisTable<2>& cell_basis,
                                            const Eigen::VectorXd& wq_of, const Eigen::VectorXd& h) {
  constexpr double two_pi = 6.283185307179586476925;
  const bool axi = axisymmetric();
  const int n = static_cast<int>(u.size());
  double* p = p_.data() + value_offset_[t];
  double* dp = dp_.data() + 2 * value_offset_[t];
  double measure = 0.0;  // |T| or int_T r
  for (int q = 0; q < nq_; ++q) {
    const int gq = t * nq_ + q;
    const auto s = cell_basis.nodes(gq);
    const auto v = cell_basis.values(gq);
    const auto grad = cell_basis.gradients(gq);
    double hsum = 0.0;
    for (std::size_t j = 0; j < s.size(); ++j) {
      const int i = static_cast<int>(std::lower_bound(u.begin(), u.end(), s[j]) - u.begin());
      p[q * n + i] = v[j];
      dp[2 * (q * n + i)] = grad(0, static_cast<Eigen::Index>(j));
      dp[2 * (q * n + i) + 1] = grad(1, static_cast<Eigen::Index>(j));
      hsum += h(s[j]);
    }
    rho_[static_cast<std::size_t>(gq)] = hsum / static_cast<double>(s.size());
    const double r = x_(0, gq);
    const double wq = wq_of(gq);
    measure += axi ? wq * r : wq;
    w_[static_cast<std::size_t>(gq)] = axi ? wq * two_pi * r : wq;
  }
  return measure;
}

inline void FlowDiscretization::correct_gradients(int t, const std::vector<int>& u, const Mesh& mesh,
                                                  const Eigen::VectorXd& wq_of, double measure,
                                                  std::vector<double>& boundary_integral) {
  const bool axi = axisymmetric();
  const int n = static_cast<int>(u.size());
  double* p = p_.data() + value_offset_[t];
  double* dp = dp_.data() + 2 * value_offset_[t];
  const auto& X = mesh.nodes();
  boundary_integral.assign(2 * static_cast<std::size_t>(n), 0.0);
  const auto& tri = mesh.triangles()[static_cast<std::size_t>(t)];
  for (int i = 0; i < 3; ++i) {
    const int e = mesh.triangle_edge(t, i);
    const auto& edge = mesh.edges()[static_cast<std::size_t>(e)];
    // Outward normal of T on this edge: away from the opposite vertex.
    const Eigen::Vector2d d = X.col(edge.b) - X.col(edge.a);
    Eigen::Vector2d nrm(d.y(), -d.x());
    nrm.normalize();
    if (nrm.dot(X.col(tri[static_cast<std::size_t>(i)]) - X.col(edge.a)) > 0) nrm = -nrm;
    for (int k = 0; k < ne_; ++k) {
      const int ge = e * ne_ + k;
      const double wk = edge_w_(ge) * (axi ? edge_x_(0, ge) : 1.0);
      const auto s = edge_basis_.nodes(ge);
      const auto v = edge_basis_.values(ge);
      for (std::size_t j = 0; j < s.size(); ++j) {
        const auto a = static_cast<std::size_t>(std::lower_bound(u.begin(), u.end(), s[j]) - u.begin());
        boundary_integral[2 * a] += wk * v[j] * nrm.x();
        boundary_integral[2 * a + 1] += wk * v[j] * nrm.y();
      }
    }
  }
  // dp += (int_dT p n - int_T grad p) / |T|, the same for every point of T.
  for (int i = 0; i < n; ++i) {
    double cx = boundary_integral[2 * static_cast<std::size_t>(i)];
    double cy = boundary_integral[2 * static_cast<std::size_t>(i) + 1];
    for (int q = 0; q < nq_; ++q) {
      const double wq = wq_of(t * nq_ + q);
      const double r = axi ? x_(0, t * nq_ + q) : 1.0;
      cx -= wq * (r * dp[2 * (q * n + i)] + (axi ? p[q * n + i] : 0.0));
      cy -= wq * r * dp[2 * (q * n + i) + 1];
    }
    cx /= measure;
    cy /= measure;
    for (int q = 0; q < nq_; ++q) {
      dp[2 * (q * n + i)] += cx;
      dp[2 * (q * n + i) + 1] += cy;
    }
  }
}

inline void FlowDiscretization::build_linear(const Mesh& mesh, const FlowDiscretization& maxent) {
  const char* where = "FlowDiscretization::build_linear";
  require(maxent.number_of_nodes() == static_cast<int>(mesh.number_of_nodes()) &&
              maxent.cells() == static_cast<int>(mesh.number_of_triangles()),
          "the max-ent discretization is not on this mesh", where);
  prm_ = maxent.prm_;
  prm_.consistent_integration = false;  // P1 gradients are exact
  geometry_ = maxent.geometry_;
  n_nodes_ = maxent.n_nodes_;
  nq_ = maxent.nq_;
  ne_ = 0;
  x_ = maxent.x_;
  w_ = maxent.w_;
  rho_ = maxent.rho_;
  edge_x_.resize(2, 0);
  edge_w_.resize(0);
  edge_basis_ = {};
  const int nt = maxent.cells();
  node_offset_.resize(static_cast<std::size_t>(nt) + 1);
  value_offset_.resize(static_cast<std::size_t>(nt) + 1);
  node_.resize(3 * static_cast<std::size_t>(nt));
  p_.resize(3 * static_cast<std::size_t>(nt * nq_));
  dp_.resize(2 * p_.size());
  const auto& X = mesh.nodes();
  for (int t = 0; t < nt; ++t) {
    node_offset_[t] = 3 * t;
    value_offset_[t] = 3 * t * nq_;
    auto v = mesh.triangles()[static_cast<std::size_t>(t)];
    std::sort(v.begin(), v.end());
    const Eigen::Vector2d a = X.col(v[0]), b = X.col(v[1]), c = X.col(v[2]);
    const double det = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    MAXENTFLOW_REQUIRE(det != 0.0, "degenerate triangle", detail::cat(where, ", triangle ", t));
    // grad of the barycentric coordinates L_1, L_2; L_0 = 1 - L_1 - L_2
    const Eigen::Vector2d g1 = Eigen::Vector2d((c - a).y(), -(c - a).x()) / det;
    const Eigen::Vector2d g2 = Eigen::Vector2d(-(b - a).y(), (b - a).x()) / det;
    const Eigen::Vector2d g0 = -g1 - g2;
    for (int i = 0; i < 3; ++i) node_[3 * static_cast<std::size_t>(t) + i] = v[static_cast<std::size_t>(i)];
    for (int q = 0; q < nq_; ++q) {
      const Eigen::Vector2d d = x_.col(t * nq_ + q) - a;
      const double l1 = g1.dot(d), l2 = g2.dot(d);
      double* p = p_.data() + value_offset_[t] + 3 * q;
      double* dp = dp_.data() + 2 * (value_offset_[t] + 3 * q);
      p[0] = 1.0 - l1 - l2;
      p[1] = l1;
      p[2] = l2;
      const Eigen::Vector2d* g[3] = {&g0, &g1, &g2};
      for (int i = 0; i < 3; ++i) {
        dp[2 * i] = g[i]->x();
        dp[2 * i + 1] = g[i]->y();
      }
    }
  }
  node_offset_[nt] = 3 * nt;
  value_offset_[nt] = 3 * nt * nq_;
  rank_ = maxent.rank_;
  rank_cells();
}

inline double FlowDiscretization::divergence_defect(const Mesh& mesh) const {
  // Plane identity sum_q w grad p_a = int_dOmega p_a n over the whole mesh.
  std::vector<double> lhs(2 * static_cast<std::size_t>(n_nodes_), 0.0), rhs(lhs.size(), 0.0);
  constexpr double two_pi = 6.283185307179586476925;
  for (int t = 0; t < cells(); ++t) {
    const auto u = nodes(t);
    const int n = count(t);
    for (int q = 0; q < nq_; ++q) {
      const int g = t * nq_ + q;
      const bool axi = axisymmetric();
      const double r = axi ? x_(0, g) : 1.0;
      const double wq = axi ? w_[g] / (two_pi * r) : w_[g];
      const double* p = values(t, q);
      const double* dp = gradients(t, q);
      for (int i = 0; i < n; ++i) {
        lhs[2 * static_cast<std::size_t>(u[i])] += wq * (r * dp[2 * i] + (axi ? p[i] : 0.0));
        lhs[2 * static_cast<std::size_t>(u[i]) + 1] += wq * r * dp[2 * i + 1];
      }
    }
  }
  for (const auto& seg : mesh.boundary_segments()) {
    for (int k = 0; k < ne_; ++k) {
      const int ge = seg.edge * ne_ + k;
      const double wk = edge_w_(ge) * (axisymmetric() ? edge_x_(0, ge) : 1.0);
      const auto s = edge_basis_.nodes(ge);
      const auto v = edge_basis_.values(ge);
      for (std::size_t j = 0; j < s.size(); ++j) {
        rhs[2 * static_cast<std::size_t>(s[j])] += wk * v[j] * seg.normal.x();
        rhs[2 * static_cast<std::size_t>(s[j]) + 1] += wk * v[j] * seg.normal.y();
      }
    }
  }
  double defect = 0.0, scale = 0.0;
  for (std::size_t i = 0; i < lhs.size(); ++i) {
    defect = std::max(defect, std::abs(lhs[i] - rhs[i]));
    scale = std::max(scale, std::abs(rhs[i]));
  }
  return scale > 0 ? defect / scale : defect;
}

}  // namespace maxentflow

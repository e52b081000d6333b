// maxentflow: the stabilized velocity-pressure flow formulation, Eqs. (6)-(14),
// (19)-(22): cell integrals of the saddle system (21) and their Newton tangent.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <maxentflow/core/dof_layout.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/core/linearization.hpp>
#include <maxentflow/core/parallel.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/material/norton_hoff.hpp>

namespace maxentflow {

/// Unknowns: node a has v_x = X[3a], v_y = X[3a+1] (v_r, v_z axisymmetric) and
/// the pressure coefficient P_a = X[3a+2] (the same max-ent basis, Eq. 19);
/// Lagrange multipliers follow from 3N on.
inline int velocity_dof(int a, int c) { return DofLayout::velocity(a, c); }
inline int pressure_dof(int a) { return DofLayout::pressure(a); }

/// The sparse structure of the saddle system: every pair of nodes that share a
/// triangle's U_T gives a dense 3x3 block (v_x, v_y, p); multiplier columns and
/// rows follow. Built once per configuration, reused by every iteration.
class SystemPattern {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  /// node adjacency from the triangles' node sets; constraint rows as (dof lists).
  template <class Rows>
  void build(const FlowDiscretization& disc, const Rows& rows) {
    build_adjacency(disc);
    set_constraints(rows);
  }

  void build_adjacency(const FlowDiscretization& disc) {
    const int n = disc.number_of_nodes();
    n_nodes_ = n;
    // triangles touching each node (node -> cells CSR)
    std::vector<int> cnt(static_cast<std::size_t>(n) + 1, 0);
    for (int t = 0; t < disc.cells(); ++t)
      for (int a : disc.nodes(t)) ++cnt[static_cast<std::size_t>(a) + 1];
    for (int a = 0; a < n; ++a) cnt[a + 1] += cnt[a];
    std::vector<int> cells(static_cast<std::size_t>(cnt.back()));
    {
      std::vector<int> pos(cnt.begin(), cnt.end() - 1);
      for (int t = 0; t < disc.cells(); ++t)
        for (int a : disc.nodes(t)) cells[static_cast<std::size_t>(pos[a]++)] = t;
    }
    std::vector<std::vector<int>> adj(static_cast<std::size_t>(n));
#pragma omp parallel
    {
      std::vector<int> mark(static_cast<std::size_t>(n), -1);  // last node that took it
#pragma omp for schedule(dynamic, 64)
      for (int a = 0; a < n; ++a) {
        auto& l = adj[static_cast<std::size_t>(a)];
        auto take = [&](int b) {
          if (mark[static_cast<std::size_t>(b)] == a) return;
          mark[static_cast<std::size_t>(b)] = a;
          l.push_back(b);
        };
        for (int k = cnt[a]; k < cnt[a + 1]; ++k)
          for (int b : disc.nodes(cells[static_cast<std::size_t>(k)])) take(b);
        take(a);  // keep the diagonal block even for an orphan node
        std::sort(l.begin(), l.end());
      }
    }
    adj_offset_.assign(static_cast<std::size_t>(n) + 1, 0);
    for (int a = 0; a < n; ++a)
      adj_offset_[a + 1] = adj_offset_[a] + static_cast<int>(adj[static_cast<std::size_t>(a)].size());
    adj_.resize(static_cast<std::size_t>(adj_offset_.back()));
    for (int a = 0; a < n; ++a)
      std::copy(adj[static_cast<std::size_t>(a)].begin(), adj[static_cast<std::size_t>(a)].end(),
                adj_.begin() + adj_offset_[a]);
  }

  /// (Re)builds the matrix structure with these constraint rows (each with a
  /// `dof` list, ascending); cheap, so contact can change its active set.
  template <class Rows>
  void set_constraints(const Rows& rows) {
    const int nf = DofLayout::per_node, nv = DofLayout::fields_of(n_nodes_);
    const int m = static_cast<int>(rows.size());
    n_ = nv + m;
    // multiplier rows per velocity/pressure column
    extra_.assign(static_cast<std::size_t>(nv) + 1, 0);
    for (const auto& r : rows)
      for (int d : r.dof) ++extra_[static_cast<std::size_t>(d) + 1];
    for (int j = 0; j < nv; ++j) extra_[j + 1] += extra_[j];
    extra_row_.resize(static_cast<std::size_t>(extra_.back()));
    {
      std::vector<int> pos(extra_.begin(), extra_.end() - 1);
      for (int i = 0; i < m; ++i)
        for (int d : rows[static_cast<std::size_t>(i)].dof)
          extra_row_[static_cast<std::size_t>(pos[d]++)] = nv + i;
    }
    std::vector<int>& outer = outer_;
    outer.assign(static_cast<std::size_t>(n_) + 1, 0);
    for (int b = 0; b < n_nodes_; ++b)
      for (int c = 0; c < nf; ++c) {
        const int j = nf * b + c;
        outer[j + 1] = outer[j] + nf * (adj_offset_[b + 1] - adj_offset_[b]) + (extra_[j + 1] - extra_[j]);
      }
    multiplier_inner_.clear();
    for (int i = 0; i < m; ++i) {
      const auto& dof = rows[static_cast<std::size_t>(i)].dof;
      outer[nv + i + 1] = outer[nv + i] + static_cast<int>(dof.size());
      multiplier_inner_.insert(multiplier_inner_.end(), dof.begin(), dof.end());
    }
    generation_ = next_generation();
  }

  int size() const { return n_; }
  int number_of_nodes() const { return n_nodes_; }
  /// Nodes coupled to node b (ascending).
  const int* adjacency_begin(int b) const { return adj_.data() + adj_offset_[b]; }
  const int* adjacency_end(int b) const { return adj_.data() + adj_offset_[b + 1]; }
  /// A zeroed matrix with this structure. The pattern keeps node adjacency,
  /// not the matrix's row indices (a third of a matrix's memory: 250 MB at
  /// bench_flow's 64k nodes); they are written here.
  Matrix matrix() const {
    Matrix M;
    zero_matrix(M);
    return M;
  }
  /// M gets this structure with zero values.
  void zero_matrix(Matrix& M) const {
    const int nf = DofLayout::per_node, nv = DofLayout::fields_of(n_nodes_);
    M.resize(n_, n_);
    M.resizeNonZeros(nonzeros());
    std::copy(outer_.begin(), outer_.end(), M.outerIndexPtr());
    int* inner = M.innerIndexPtr();
#pragma omp parallel for schedule(static)
    for (int b = 0; b < n_nodes_; ++b)
      for (int c = 0; c < nf; ++c) {
        const int j = nf * b + c;
        int k = outer_[j];
        for (int q = adj_offset_[b]; q < adj_offset_[b + 1]; ++q)
          for (int cc = 0; cc < nf; ++cc) inner[k++] = nf * adj_[static_cast<std::size_t>(q)] + cc;
        for (int q = extra_[j]; q < extra_[j + 1]; ++q) inner[k++] = extra_row_[static_cast<std::size_t>(q)];
      }
    std::copy(multiplier_inner_.begin(), multiplier_inner_.end(), inner + outer_[nv]);
    std::fill_n(M.valuePtr(), M.nonZeros(), 0.0);
  }
  Eigen::Index nonzeros() const { return outer_.back(); }
  /// Compressed-column starts: column j's entries are [outer_index()[j], outer_index()[j + 1]).
  const int* outer_index() const { return outer_.data(); }
  /// The value index of entry (row, col) in a matrix with this structure
  /// (rows ascend in each column); -1 if the structure has no such entry.
  int position(int row, int col) const {
    const int nf = DofLayout::per_node, nv = DofLayout::fields_of(n_nodes_);
    if (row < 0 || col < 0 || row >= n_ || col >= n_) return -1;
    if (col >= nv) {  // a multiplier column: its row's dofs
      const auto b = multiplier_inner_.begin() + (outer_[col] - outer_[nv]);
      const auto e = multiplier_inner_.begin() + (outer_[col + 1] - outer_[nv]);
      const auto it = std::lower_bound(b, e, row);
      return it != e && *it == row ? outer_[col] + static_cast<int>(it - b) : -1;
    }
    const int node = col / nf;
    if (row < nv) {  // a field row: the node's block in the column's adjacency
      const int* b = adjacency_begin(node);
      const int* e = adjacency_end(node);
      const int* it = std::lower_bound(b, e, row / nf);
      return it != e && *it == row / nf ? outer_[col] + nf * static_cast<int>(it - b) + row % nf : -1;
    }
    const auto b = extra_row_.begin() + extra_[col];
    const auto e = extra_row_.begin() + extra_[col + 1];
    const auto it = std::lower_bound(b, e, row);
    return it != e && *it == row
               ? outer_[col] + nf * (adj_offset_[node + 1] - adj_offset_[node]) + static_cast<int>(it - b)
               : -1;
  }
  /// Unique to this structure, across all patterns (a new symbolic factorization is due).
  long generation() const { return generation_; }
  double mean_adjacency() const {
    return n_nodes_ ? static_cast<double>(adj_.size()) / n_nodes_ : 0.0;
  }

 private:
  static long next_generation() {
    static std::atomic<long> counter{0};
    return ++counter;
  }
  int n_nodes_ = 0, n_ = 0;
  long generation_ = 0;
  std::vector<int> adj_offset_{0}, adj_;
  std::vector<int> outer_{0};
  std::vector<int> extra_{0}, extra_row_;  // multiplier rows of each field column (CSR)
  std::vector<int> multiplier_inner_;      // the multiplier columns' rows, in column order
};

/// Gauss-point state after an assembly (for post-processing and the tests).
struct FlowPointState {
  Eigen::VectorXd d;    ///< equivalent strain rate sqrt(2/3 D:D)
  Eigen::VectorXd mu;   ///< viscosity
  Eigen::VectorXd tau;  ///< stabilization parameter, Eq. (14)
  Eigen::VectorXd p;    ///< pressure
  Eigen::VectorXd div;  ///< div v
};

struct StabilizationParams {
  double Cs = 0.5;  ///< Eq. (14)
  /// Keep f in the stabilizing residual of Eq. (13), as the paper writes it.
  /// With div(2 mu D) neglected, grad p - f is not small wherever the viscous
  /// term is not (measured on V4, h = 1/16: pressure L2 error 0.62 with f,
  /// 0.15 without), so the default drops f; forming problems have no body force.
  bool stabilize_body_force = false;
};

/// Cell integrals of Eq. (21)-(22) for a viscosity law: K (with the tangent
/// 2 mu Q + (4/3) mu'/d (Q eps)(Q eps)^T for Newton), G, the stabilization
/// M_S = -int tau grad(phi)^T grad(phi) with tau = Cs rho^2 / mu (Eq. 14), the
/// body force F and F_S. Stress sigma = 2 mu D - p I (pressure positive in
/// compression). Residual form: R = A(X) X - F, so that a Picard step and a
/// Newton step are both X += solve(A, -R).
///
/// tau depends on mu(d(v)); the Newton tangent differentiates it too (a
/// non-symmetric pressure-velocity block), so Newton is quadratic for n != 1.
template <ViscosityLaw Material>
class StabilizedFlowAssembler {
 public:
  using Matrix = SystemPattern::Matrix;
  using BodyForce = std::function<Eigen::Vector2d(const Eigen::Vector2d&)>;

  using params = StabilizationParams;

  StabilizedFlowAssembler(const FlowDiscretization& disc, Material material, params prm = {})
      : disc_(&disc), material_(std::move(material)), prm_(prm) {
    require(std::isfinite(prm_.Cs) && prm_.Cs >= 0,
            detail::cat("Cs must be >= 0, got ", prm_.Cs), "StabilizedFlowAssembler");
  }

  const Material& material() const { return material_; }
  const params& parameters() const { return prm_; }
  const FlowDiscretization& discretization() const { return *disc_; }
  void set_body_force(BodyForce f) { body_ = std::move(f); }
  void set_body_force(const Eigen::Vector2d& f) {
    body_ = [f](const Eigen::Vector2d&) { return f; };
  }

  /// Adds the cell integrals at X to A's values (A has pat's structure) and to
  /// R (momentum and continuity rows, size >= 3N); fint (if given, size 3N)
  /// receives the momentum rows without the body force, the force scale.
  /// Parallel over nodes (each thread owns a node range: its rows and
  /// columns); every entry sums its cells in the same order for any thread count.
  void assemble(const Eigen::VectorXd& X, Linearization kind, const SystemPattern& pat, Matrix* A,
                Eigen::VectorXd& R, Eigen::VectorXd* fint = nullptr,
                FlowPointState* state = nullptr) const;

  /// Stores the point operators of Newton's tangent at X (a few numbers per
  /// Gauss point) for apply_tangent.
  void linearize(const Eigen::VectorXd& X);
  /// Jv += J v: the Newton tangent of the cell integrals at the X of the last
  /// linearize() (the matrix assemble() builds with Linearization::newton)
  /// applied to v without forming it, at the cost of a residual evaluation;
  /// with Linearization::picard the Picard matrix's product (the same point
  /// operators without the derivatives of mu and tau), with newton_symmetric
  /// the tangent's without d tau / d v. Jv has size >= 3N.
  void apply_tangent(const Eigen::VectorXd& v, Eigen::VectorXd& Jv,
                     Linearization kind = Linearization::newton) const;

 private:
  static constexpr double two_thirds = 2.0 / 3.0;
  static constexpr int nf = DofLayout::per_node;  // v_x, v_y, p interleaved
  using PointOperator = Eigen::Matrix<double, 7, 7>;

  // The constitutive state at one Gauss point from z = [strain rate rows
  // (ns), p, grad p] (Eqs. 7-9, 14).
  struct PointLaw {
    double Qeps[4], m[4];
    double d, mu, tau, div, pq;
    double dmu_dd_over_d;
    double sx, sy;  // grad p - f (f only with stabilize_body_force)
  };
  // The coefficients of Y on a cell's nodes u, by component: c[k n + i] =
  // Y[3 u_i + k]. Gathered once per cell, so that each Gauss point's loops
  // run over contiguous arrays (vectorized) instead of indexing Y.
  static void gather(std::span<const int> u, const Eigen::VectorXd& Y, double* c) {
    const auto n = u.size();
    for (std::size_t i = 0; i < n; ++i) {
      const int a = u[i];
      c[i] = Y[nf * a];
      c[n + i] = Y[nf * a + 1];
      c[2 * n + i] = Y[nf * a + 2];
    }
  }
  // z = O_q Y at a Gauss point from the cell's gathered coefficients c.
  static void point_rows(const double* c, int n, const double* p, const double* dp, double r, bool axi, int ns,
                         double* z) {
    const double *vx = c, *vy = c + n, *pa = c + 2 * n;
    double exx = 0.0, eyy = 0.0, gxy = 0.0, ett = 0.0, pq = 0.0, px = 0.0, py = 0.0;
    for (int i = 0; i < n; ++i) {
      const double gx = dp[2 * i], gy = dp[2 * i + 1];
      exx += gx * vx[i];
      eyy += gy * vy[i];
      gxy += gy * vx[i] + gx * vy[i];
      ett += p[i] * vx[i];
      pq += p[i] * pa[i];
      px += gx * pa[i];
      py += gy * pa[i];
    }
    z[0] = exx;
    z[1] = eyy;
    if (axi) z[2] = ett / r;  // hoop strain rate v_r / r
    z[ns - 1] = gxy;
    z[ns] = pq;
    z[ns + 1] = px;
    z[ns + 2] = py;
  }
  PointLaw point_law(const double* z, int ns, double rho, const Eigen::Vector2d& bs, int g) const {
    const FlowDiscretization& disc = *disc_;
    PointLaw L;
    double eQe = 0.0;
    L.div = 0.0;
    for (int k = 0; k < ns; ++k) {
      L.Qeps[k] = k == ns - 1 ? 0.5 * z[k] : z[k];  // Q = diag(1, 1, (1), 1/2)
      L.m[k] = k == ns - 1 ? 0.0 : 1.0;
      eQe += z[k] * L.Qeps[k];
      L.div += L.m[k] * z[k];
    }
    L.d = std::sqrt(std::max(0.0, two_thirds * eQe));
    const Viscosity visc = material_.viscosity(MaterialPoint{L.d, disc.points().col(g)});
    L.mu = visc.mu;
    L.dmu_dd_over_d = visc.dmu_dd_over_d;
    MAXENTFLOW_REQUIRE(std::isfinite(L.mu) && L.mu > 0,
                       detail::cat("viscosity ", L.mu, " at d = ", L.d, " (NaN velocity?)"),
                       detail::cat("StabilizedFlowAssembler, Gauss point ", g));
    L.tau = prm_.Cs * rho * rho / L.mu;  // Eq. (14)
    L.sx = z[ns + 1] - bs.x();
    L.sy = z[ns + 2] - bs.y();
    L.pq = z[ns];
    return L;
  }
  // D_q: the linearized point operator (weight w included), Picard or Newton
  // (with or without d tau / d eps).
  static void point_operator(const PointLaw& L, double w, bool newton, bool tau_derivative, int ns,
                             PointOperator& Dq) {
    Dq.setZero();
    for (int k = 0; k < ns; ++k) {
      Dq(k, k) = w * 2.0 * L.mu * (k == ns - 1 ? 0.5 : 1.0);
      Dq(k, ns) = -w * L.m[k];
      Dq(ns, k) = -w * L.m[k];
    }
    Dq(ns + 1, ns + 1) = -w * L.tau;
    Dq(ns + 2, ns + 2) = -w * L.tau;
    if (newton && L.dmu_dd_over_d != 0.0) {
      const double alpha = 2.0 * two_thirds * L.dmu_dd_over_d;  // (4/3) mu'/d
      for (int k = 0; k < ns; ++k)
        for (int l = 0; l < ns; ++l) Dq(k, l) += w * alpha * L.Qeps[k] * L.Qeps[l];
      if (!tau_derivative) return;
      // d tau / d eps = -tau (mu'/d) / mu (2/3) Q eps
      const double beta = -L.tau * L.dmu_dd_over_d / L.mu * two_thirds;
      for (int l = 0; l < ns; ++l) {
        Dq(ns + 1, l) = -w * L.sx * beta * L.Qeps[l];
        Dq(ns + 2, l) = -w * L.sy * beta * L.Qeps[l];
      }
    }
  }
  // out += O_q^T y for the cell's nodes, by component (out[k n + i]).
  static void add_transposed(const double* y, const double* p, const double* dp, int n, double r, bool axi,
                             int ns, double* out) {
    const double yt = axi ? y[2] / r : 0.0, y0 = y[0], y1 = y[1], ys = y[ns - 1];
    const double yp = y[ns], ygx = y[ns + 1], ygy = y[ns + 2];
    double *ox = out, *oy = out + n, *op = out + 2 * n;
    for (int i = 0; i < n; ++i) {
      const double gx = dp[2 * i], gy = dp[2 * i + 1];
      ox[i] += gx * y0 + p[i] * yt + gy * ys;
      oy[i] += gy * y1 + gx * ys;
      op[i] += p[i] * yp + gx * ygx + gy * ygy;
    }
  }

  // A thread's work space for one cell: A_loc = sum_q O_q^T D_q O_q with O_q
  // the point operator (strain rows, phi, grad phi) of every local dof.
  // Column nf i + c of O_q is nonzero only in the rows of component c (v_x:
  // eps_xx, (eps_tt), gamma_xy; v_y: eps_yy, gamma_xy; p: phi, grad phi), so
  // the rows nf i + c of A_loc are Oc[c]^T Tc[c]: Oc[c] those rows of O stacked
  // over q (one column per node), Tc[c] the same rows of T = D O. A third of
  // the dense product's work.
  struct CellWork {
    CellWork(bool axi_, Linearization kind, bool matrix_)
        : axi(axi_), newton(kind != Linearization::picard), tau_derivative(kind == Linearization::newton),
          matrix(matrix_), ns(axi_ ? 4 : 3),
          rows_of{axi_ ? 3 : 2, 2, 3},
          row_index{{0, axi_ ? 2 : ns - 1, ns - 1}, {1, ns - 1, 0}, {ns, ns + 1, ns + 2}} {}
    bool axi, newton, tau_derivative, matrix;
    int ns;  // strain rows: eps_xx, eps_yy, (eps_tt), gamma_xy
    int rows_of[nf];
    int row_index[nf][3];
    Eigen::MatrixXd Oc[nf], Tc[nf], Ac[nf], Tq;
    Eigen::VectorXd xloc, rloc, floc;  // by component (gather)
    std::vector<int> kpos;
    PointOperator Dq;
  };
  void integrate_cell(int t, const Eigen::VectorXd& X, CellWork& cw, FlowPointState* state) const;
  static void point_matrix_rows(int q, int n, const double* p, const double* dp, double r, CellWork& cw);
  static void scatter_cell(const FlowDiscretization& disc, int t, CellWork& cw, int lo, int hi,
                           const SystemPattern& pat, Matrix* A, Eigen::VectorXd& R, Eigen::VectorXd* fint);

  const FlowDiscretization* disc_;
  Material material_;
  params prm_;
  BodyForce body_;
  // Newton's point operator in compact form (see apply_tangent).
  struct PointTangent {
    double w, w2mu, wtau, walpha, wbsx, wbsy;
    double Qeps[4];
  };
  std::vector<PointTangent> tangent_;
  bool linearized_ = false;
};

template <ViscosityLaw Material>
void StabilizedFlowAssembler<Material>::assemble(const Eigen::VectorXd& X, Linearization kind,
                                                 const SystemPattern& pat, Matrix* A,
                                                 Eigen::VectorXd& R, Eigen::VectorXd* fint,
                                                 FlowPointState* state) const {
  const FlowDiscretization& disc = *disc_;
  const int N = disc.number_of_nodes();
  require(X.size() >= nf * N && R.size() >= nf * N, "X and R need 3 entries per node",
          "StabilizedFlowAssembler::assemble");
  if (state) {
    const auto np = static_cast<Eigen::Index>(disc.cells()) * disc.points_per_cell();
    for (Eigen::VectorXd* f : {&state->d, &state->mu, &state->tau, &state->p, &state->div}) f->resize(np);
  }
  const int threads = std::max(1, std::min(max_threads(), N / 64 + 1));
#pragma omp parallel num_threads(threads)
  {
    const int tid = thread_id(), nth = team_size();
    const int lo = static_cast<int>(static_cast<long>(N) * tid / nth);
    const int hi = static_cast<int>(static_cast<long>(N) * (tid + 1) / nth);
    CellWork cw(disc.axisymmetric(), kind, A != nullptr);
    for (int t = 0; t < disc.cells(); ++t) {
      if (disc.max_rank(t) < lo || disc.min_rank(t) >= hi) continue;
      integrate_cell(t, X, cw, disc.min_rank(t) >= lo ? state : nullptr);  // one thread writes each point
      scatter_cell(disc, t, cw, lo, hi, pat, A, R, fint);
    }
  }
}

template <ViscosityLaw Material>
void StabilizedFlowAssembler<Material>::integrate_cell(int t, const Eigen::VectorXd& X, CellWork& cw,
                                                       FlowPointState* state) const {
  const FlowDiscretization& disc = *disc_;
  const auto u = disc.nodes(t);
  const int n = static_cast<int>(u.size()), nd = nf * n, ns = cw.ns, nq = disc.points_per_cell();
  cw.xloc.resize(nd);
  gather(u, X, cw.xloc.data());
  cw.rloc.setZero(nd);
  cw.floc.setZero(nd);
  if (cw.matrix) {
    for (int c = 0; c < nf; ++c) {
      cw.Oc[c].resize(nq * cw.rows_of[c], n);
      cw.Tc[c].resize(nq * cw.rows_of[c], nd);
    }
    cw.Tq.resize(ns + 3, nd);
  }
  double y[7];  // plain arrays: tiny, and no AVX-512 false positives in GCC 12
  for (int q = 0; q < nq; ++q) {
    const int g = t * nq + q;
    const double* p = disc.values(t, q);
    const double* dp = disc.gradients(t, q);
    const double w = disc.weight(g);
    const double r = disc.points()(0, g);
    // Current fields at the point: strain rate, pressure, grad p.
    double z[7];
    point_rows(cw.xloc.data(), n, p, dp, r, cw.axi, ns, z);
    const Eigen::Vector2d b = body_ ? body_(disc.points().col(g)) : Eigen::Vector2d::Zero();
    const Eigen::Vector2d bs = prm_.stabilize_body_force ? b : Eigen::Vector2d::Zero();
    const PointLaw L = point_law(z, ns, disc.rho(g), bs, g);
    if (state) {
      state->d[g] = L.d;
      state->mu[g] = L.mu;
      state->tau[g] = L.tau;
      state->p[g] = L.pq;
      state->div[g] = L.div;
    }
    // Residual: strain rows w (2 mu Q eps - p m); phi row -w div v;
    // grad rows -w tau (grad p - f)  (Eq. 13 with the sign of Eq. 21).
    for (int k = 0; k < ns; ++k) y[k] = w * (2.0 * L.mu * L.Qeps[k] - L.pq * L.m[k]);
    y[ns] = -w * L.div;
    y[ns + 1] = -w * L.tau * L.sx;
    y[ns + 2] = -w * L.tau * L.sy;
    add_transposed(y, p, dp, n, r, cw.axi, ns, cw.rloc.data());
    if (body_)
      for (int i = 0; i < n; ++i) {
        cw.floc[i] -= w * p[i] * b.x();
        cw.floc[n + i] -= w * p[i] * b.y();
      }
    if (!cw.matrix) continue;
    point_operator(L, w, cw.newton, cw.tau_derivative, ns, cw.Dq);
    point_matrix_rows(q, n, p, dp, r, cw);
  }
  cw.rloc += cw.floc;
  if (cw.matrix)
    for (int c = 0; c < nf; ++c) cw.Ac[c].noalias() = cw.Oc[c].transpose() * cw.Tc[c];  // rows nf i + c of A_loc
}

template <ViscosityLaw Material>
void StabilizedFlowAssembler<Material>::point_matrix_rows(int q, int n, const double* p, const double* dp,
                                                          double r, CellWork& cw) {
  // T_q = D_q O_q column by column (O_q's columns have 2-3 nonzeros), and the
  // rows of O_q per component.
  const int ns = cw.ns;
  const auto D = cw.Dq.topLeftCorner(ns + 3, ns + 3);
  for (int i = 0; i < n; ++i) {
    const double gx = dp[2 * i], gy = dp[2 * i + 1], pr = cw.axi ? p[i] / r : 0.0;
    if (cw.axi)
      cw.Tq.col(nf * i) = D.col(0) * gx + D.col(2) * pr + D.col(ns - 1) * gy;
    else
      cw.Tq.col(nf * i) = D.col(0) * gx + D.col(ns - 1) * gy;
    cw.Tq.col(nf * i + 1) = D.col(1) * gy + D.col(ns - 1) * gx;
    cw.Tq.col(nf * i + 2) = D.col(ns) * p[i] + D.col(ns + 1) * gx + D.col(ns + 2) * gy;
    double* o0 = &cw.Oc[0](q * cw.rows_of[0], i);
    o0[0] = gx;
    if (cw.axi) {
      o0[1] = pr;
      o0[2] = gy;
    } else {
      o0[1] = gy;
    }
    double* o1 = &cw.Oc[1](q * cw.rows_of[1], i);
    o1[0] = gy;
    o1[1] = gx;
    double* o2 = &cw.Oc[2](q * cw.rows_of[2], i);
    o2[0] = p[i];
    o2[1] = gx;
    o2[2] = gy;
  }
  for (int c = 0; c < nf; ++c)
    for (int k = 0; k < cw.rows_of[c]; ++k) cw.Tc[c].row(q * cw.rows_of[c] + k) = cw.Tq.row(cw.row_index[c][k]);
}

template <ViscosityLaw Material>
void StabilizedFlowAssembler<Material>::scatter_cell(const FlowDiscretization& disc, int t, CellWork& cw, int lo,
                                                     int hi, const SystemPattern& pat, Matrix* A,
                                                     Eigen::VectorXd& R, Eigen::VectorXd* fint) {
  // The owned rows (residual) and columns (matrix) of this thread's nodes
  // (ranks lo..hi-1).
  const auto u = disc.nodes(t);
  const int n = static_cast<int>(u.size());
  double* values = A ? A->valuePtr() : nullptr;
  const int* outer = A ? A->outerIndexPtr() : nullptr;
  for (int j = 0; j < n; ++j) {
    const int b = u[static_cast<std::size_t>(j)];
    if (disc.rank(b) < lo || disc.rank(b) >= hi) continue;
    for (int c = 0; c < nf; ++c) R[nf * b + c] += cw.rloc[c * n + j];
    if (fint)
      for (int c = 0; c < 2; ++c) (*fint)[nf * b + c] += cw.rloc[c * n + j] - cw.floc[c * n + j];
    if (!A) continue;
    cw.kpos.resize(static_cast<std::size_t>(n));
    const int* it = pat.adjacency_begin(b);
    const int* first = it;
    for (int i = 0; i < n; ++i) {
      while (*it < u[static_cast<std::size_t>(i)]) ++it;
      cw.kpos[static_cast<std::size_t>(i)] = static_cast<int>(it - first);
    }
    for (int cc = 0; cc < nf; ++cc) {
      double* col = values + outer[nf * b + cc];
      const double* a0 = cw.Ac[0].col(nf * j + cc).data();
      const double* a1 = cw.Ac[1].col(nf * j + cc).data();
      const double* a2 = cw.Ac[2].col(nf * j + cc).data();
      for (int i = 0; i < n; ++i) {
        double* blk = col + nf * cw.kpos[static_cast<std::size_t>(i)];
        blk[0] += a0[i];
        blk[1] += a1[i];
        blk[2] += a2[i];
      }
    }
  }
}

template <ViscosityLaw Material>
void StabilizedFlowAssembler<Material>::linearize(const Eigen::VectorXd& X) {
  const FlowDiscretization& disc = *disc_;
  const int N = disc.number_of_nodes();
  const bool axi = disc.axisymmetric();
  const int ns = axi ? 4 : 3;
  const int nq = disc.points_per_cell();
  require(X.size() >= nf * N, "X needs 3 entries per node", "StabilizedFlowAssembler::linearize");
  tangent_.resize(static_cast<std::size_t>(disc.cells()) * nq);
#pragma omp parallel num_threads(std::max(1, std::min(max_threads(), N / 64 + 1)))
  {
    std::vector<double> xloc;
#pragma omp for schedule(static)
    for (int t = 0; t < disc.cells(); ++t) {
      const auto u = disc.nodes(t);
      const int n = static_cast<int>(u.size());
      xloc.resize(static_cast<std::size_t>(nf * n));
      gather(u, X, xloc.data());
      double z[7];
      for (int q = 0; q < nq; ++q) {
        const int g = t * nq + q;
        point_rows(xloc.data(), n, disc.values(t, q), disc.gradients(t, q), disc.points()(0, g), axi, ns, z);
        const Eigen::Vector2d bs = prm_.stabilize_body_force && body_ ? body_(disc.points().col(g))
                                                                      : Eigen::Vector2d::Zero();
        const PointLaw L = point_law(z, ns, disc.rho(g), bs, g);
        const double w = disc.weight(g);
        PointTangent& T = tangent_[static_cast<std::size_t>(g)];
        T.w = w;
        T.w2mu = w * 2.0 * L.mu;
        T.wtau = w * L.tau;
        const double alpha = 2.0 * two_thirds * L.dmu_dd_over_d;  // (4/3) mu'/d
        const double beta = -L.tau * L.dmu_dd_over_d / L.mu * two_thirds;  // d tau / d eps = beta Q eps
        T.walpha = w * alpha;
        T.wbsx = -w * L.sx * beta;
        T.wbsy = -w * L.sy * beta;
        for (int k = 0; k < 4; ++k) T.Qeps[k] = k < ns ? L.Qeps[k] : 0.0;
      }
    }
  }
  linearized_ = true;
}

template <ViscosityLaw Material>
void StabilizedFlowAssembler<Material>::apply_tangent(const Eigen::VectorXd& v, Eigen::VectorXd& Jv,
                                                      Linearization kind) const {
  const FlowDiscretization& disc = *disc_;
  const int N = disc.number_of_nodes();
  const bool axi = disc.axisymmetric();
  const int ns = axi ? 4 : 3;
  const int nq = disc.points_per_cell();
  require(linearized_ && tangent_.size() == static_cast<std::size_t>(disc.cells()) * nq,
          "linearize(X) first", "StabilizedFlowAssembler::apply_tangent");
  require(v.size() >= nf * N && Jv.size() >= nf * N, "v and Jv need 3 entries per node",
          "StabilizedFlowAssembler::apply_tangent");
  const double newton = kind == Linearization::picard ? 0.0 : 1.0;  // Picard drops mu' and tau'
  const double tau_derivative = kind == Linearization::newton ? 1.0 : 0.0;
  const int threads = std::max(1, std::min(max_threads(), N / 64 + 1));
#pragma omp parallel num_threads(threads)
  {
    const int tid = thread_id(), nth = team_size();
    const int lo = static_cast<int>(static_cast<long>(N) * tid / nth);
    const int hi = static_cast<int>(static_cast<long>(N) * (tid + 1) / nth);
    std::vector<double> vloc, jloc;  // by component (gather)
    double zv[7], y[7];
    for (int t = 0; t < disc.cells(); ++t) {
      if (disc.max_rank(t) < lo || disc.min_rank(t) >= hi) continue;
      const auto u = disc.nodes(t);
      const int n = static_cast<int>(u.size());
      vloc.resize(static_cast<std::size_t>(nf * n));
      gather(u, v, vloc.data());
      jloc.assign(static_cast<std::size_t>(nf * n), 0.0);
      for (int q = 0; q < nq; ++q) {
        const int g = t * nq + q;
        const double* p = disc.values(t, q);
        const double* dp = disc.gradients(t, q);
        const double r = disc.points()(0, g);
        point_rows(vloc.data(), n, p, dp, r, axi, ns, zv);
        // y = D_q zv, D_q as point_operator builds it for Newton.
        const PointTangent& T = tangent_[static_cast<std::size_t>(g)];
        double qz = 0.0, div = 0.0;
        for (int k = 0; k < ns; ++k) qz += T.Qeps[k] * zv[k];
        qz *= newton;
        for (int k = 0; k + 1 < ns; ++k) div += zv[k];
        for (int k = 0; k < ns; ++k) {
          const bool shear = k == ns - 1;
          y[k] = T.w2mu * (shear ? 0.5 : 1.0) * zv[k] - (shear ? 0.0 : T.w * zv[ns]) + T.walpha * T.Qeps[k] * qz;
        }
        y[ns] = -T.w * div;
        y[ns + 1] = -T.wtau * zv[ns + 1] + tau_derivative * T.wbsx * qz;
        y[ns + 2] = -T.wtau * zv[ns + 2] + tau_derivative * T.wbsy * qz;
        add_transposed(y, p, dp, n, r, axi, ns, jloc.data());
      }
      for (int j = 0; j < n; ++j) {
        const int b = u[static_cast<std::size_t>(j)];
        if (disc.rank(b) < lo || disc.rank(b) >= hi) continue;
        for (int c = 0; c < nf; ++c) Jv[nf * b + c] += jloc[static_cast<std::size_t>(c * n + j)];
      }
    }
  }
}

}  // namespace maxentflow

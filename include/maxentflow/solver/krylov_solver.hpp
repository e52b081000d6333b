// maxentflow: restarted GMRES for the saddle system (21), right-preconditioned
// by the LU of a sparse companion matrix (the linear-triangle system of
// FlowSystem::assemble_preconditioner), with a direct fallback.
#pragma once

#include <algorithm>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <limits>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/SparseCore>

#include <maxentflow/core/dof_layout.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/core/parallel.hpp>
#include <maxentflow/solver/linear_solver.hpp>
#include <maxentflow/solver/mumps_solver.hpp>

namespace maxentflow {

/// A linear-solver policy that solves A x = b iteratively with a
/// preconditioner P it factorizes (NonlinearSolver hands it both).
template <class S>
concept PreconditionedLinearSolver =
    requires(S& s, const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& A,
             const Eigen::VectorXd& b) {
      s.analyze_preconditioner(A);
      s.factorize_preconditioner(A);
      { s.solve(A, b) } -> std::convertible_to<Eigen::VectorXd>;
      { s.last_iterations() } -> std::convertible_to<int>;
    };

/// A Krylov policy NonlinearSolver can steer: a tolerance per solve (the
/// inexact-Newton forcing term), a solve that may not fall back to a direct
/// LU (so that a stale preconditioner is rebuilt first), and what the last
/// solve did. A PreconditionedLinearSolver without these is solved to its own
/// tolerance, every time with its fallback.
template <class S>
concept SteerableKrylovSolver =
    PreconditionedLinearSolver<S> &&
    requires(S& s, const S& cs, const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& A,
             const Eigen::VectorXd& b) {
      s.set_tolerance(1.0);
      { s.solve(A, b, false) } -> std::convertible_to<Eigen::VectorXd>;
      { cs.converged() } -> std::convertible_to<bool>;
      { cs.last_residual() } -> std::convertible_to<double>;
      { cs.direct_fallbacks() } -> std::convertible_to<int>;
    };

/// A steerable Krylov policy that can also solve with A given only by its
/// product (an operator), preconditioned as solve() is, without a direct
/// fallback (that needs A): converged() then says whether the caller must
/// assemble A after all.
template <class S>
concept MatrixFreeKrylovSolver =
    SteerableKrylovSolver<S> &&
    requires(S& s, const Eigen::VectorXd& b, Eigen::VectorXd (*op)(const Eigen::VectorXd&)) {
      { s.solve_operator(op, b) } -> std::convertible_to<Eigen::VectorXd>;
      s.equilibrate_by(Eigen::SparseMatrix<double, Eigen::ColMajor, int>());
    };

/// A Krylov policy that can also keep a direct LU of a full system matrix
/// and precondition solves by it, with the matrix-vector product given as an
/// operator (so that Newton's tangent need not be assembled).
template <class S>
concept KeptLuLinearSolver =
    PreconditionedLinearSolver<S> &&
    requires(S& s, const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& A, const Eigen::VectorXd& b,
             const DofLayout& layout, Eigen::VectorXd (*op)(const Eigen::VectorXd&)) {
      s.set_layout(layout);
      { s.kept_usable(b.size()) } -> std::convertible_to<bool>;
      s.factorize_kept(A);
      { s.solve_kept(op, b, 1) } -> std::convertible_to<Eigen::VectorXd>;
      { s.converged() } -> std::convertible_to<bool>;
    };

struct GmresParams {
  double tol = 1e-9;       ///< |b - A x| <= tol |b|
  int restart = 120;       ///< Krylov basis size before a restart
  /// Then a direct LU of A, kept as the preconditioner. When GMRES fails here
  /// it stagnates (E2, 32 x 32: still 1e-3..1e-4 after 600 iterations), so
  /// more iterations would not save the LU.
  int max_iterations = 150;
  bool direct_fallback = true;  ///< no convergence: factorize A itself (slow but sure)
  /// The kept LU preconditions a layout that differs from its own by at most
  /// this many multiplier rows (added plus removed).
  int kept_max_changed_rows = 16;
  /// Solves preconditioned by the companion's LU run on rows scaled by A's
  /// largest entry in each (D A x = D b, preconditioner (D P)^-1); their
  /// tolerance holds in that scaled norm. Solves given A's product only
  /// (solve_operator) scale by P's largest entries, A's being unknown (the
  /// companion has A's physics on the same rows). The momentum rows scale
  /// with the viscosity (up to mu(d_min) at rest), the multiplier rows do not:
  /// unscaled, GMRES's norm is that of a few rows and it stalls (bench_flow
  /// from rest: 157 iterations to 1e-4, scaled 12; docs/method.md section 8).
  bool equilibrate = true;
};

/// Why a sparse companion and not an incomplete factorization: max-ent
/// couples each node to ~90 others, so ILU fill is large and its quality poor
/// on the indefinite saddle system; the linear-triangle system on the same
/// Delaunay mesh has the same physics (viscosity, incompressibility, tau, the
/// same multiplier rows), 7 neighbours per node, and an exact LU whose fill
/// grows like N log N in 2-D. Measured (rows equilibrated): 10-70
/// iterations per solve, independent of the thread count and of N from 1k
/// to 64k nodes (benchmarks/flow). The companion's LU is MUMPS's where the
/// build has it, in single precision (CompanionLuSolver): at 64k nodes MUMPS
/// in double took 7.8 s of factorization against UMFPACK's 30 s, 2.5 against
/// 3.0 GB peak, the same iterations.
/// Kept: the LU of full system matrices (the kept LU, the direct fallback),
/// MUMPS with single-precision factors where the build has it (KeptLuSolver):
/// GMRES corrects what a preconditioner leaves, and the fallback's solve is
/// refined by GMRES too.
template <LinearSolver Preconditioner = CompanionLuSolver, LinearSolver Kept = KeptLuSolver>
class GmresSolver {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  using params = GmresParams;

  GmresSolver() { no_refinement(); }
  explicit GmresSolver(params prm) : prm_(prm) { no_refinement(); }
  params& parameters() { return prm_; }
  /// The relative tolerance of the next solves (NonlinearSolver's forcing term).
  void set_tolerance(double tol) { prm_.tol = tol; }

  /// A preconditioner that cannot be factorized (singular: e.g. a node that
  /// only slivers touch) is not an error while the direct fallback is on:
  /// the next solves factorize A itself.
  /// `symmetric`: P is symmetric (a Picard matrix), and a Preconditioner
  /// policy that can factorizes it as L D L^T: half the factors GMRES reads
  /// at every iteration.
  void analyze_preconditioner(const Matrix& P, bool symmetric = false) {
    if constexpr (requires(Preconditioner& p) { p.set_symmetric(true); }) M_.set_symmetric(symmetric);
    analyzed_ = guard([&] { M_.analyze(P); });
    frozen_ = false;  // a new structure: back to the linear-triangle preconditioner
  }
  void factorize_preconditioner(const Matrix& P) {
    usable_ = analyzed_ && guard([&] { M_.factorize(P); });
    if (usable_) equilibrate_by(P);
  }
  /// The row scales of solve_operator: P's largest entries, P the
  /// preconditioner matrix at the current iterate (rows scale with the
  /// current viscosity, which a kept preconditioner's do not).
  void equilibrate_by(const Matrix& P) {
    if (prm_.equilibrate) row_maxima(P, pre_row_max_);
  }

  /// x with |b - A x| <= tol |b|, from x = 0. With allow_fallback false a
  /// solve that does not converge in one restart cycle returns GMRES's last
  /// iterate (converged() is then false) instead of going on and falling
  /// back to a direct LU (for a caller that can first try a new preconditioner).
  Eigen::VectorXd solve(const Matrix& A, const Eigen::VectorXd& b, bool allow_fallback = true) {
    const char* where = "GmresSolver::solve";
    require(A.rows() == b.size() && A.cols() == b.size(), "A and b sizes differ", where);
    last_iterations_ = 0;
    last_residual_ = 0.0;
    if (b.norm() == 0.0) return Eigen::VectorXd::Zero(b.size());
    if (frozen_ && kept_n_ != A.rows()) frozen_ = false;  // the kept LU is another system's
    if (!usable_ && !frozen_) return direct(A, b);
    // After a fallback this structure's solves use the LU of that earlier A:
    // Newton's next matrices differ little from it, so GMRES needs a few
    // iterations where the linear-triangle preconditioner needed hundreds.
    const int max_iterations = allow_fallback ? prm_.max_iterations : std::min(prm_.max_iterations, prm_.restart);
    if (!frozen_ && prm_.equilibrate) row_maxima(A, row_max_);
    Eigen::VectorXd x = preconditioned([&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return product(A, v); },
                                       b, row_max_, max_iterations);
    if (last_residual_ <= prm_.tol || !allow_fallback) return x;
    require(prm_.direct_fallback,
            detail::cat("GMRES did not converge in ", last_iterations_, " iterations (relative residual ",
                        last_residual_, ")"),
            where);
    return direct(A, b);
  }

  /// solve(A, b, false) with A given by its product op(v) = A v, so that A
  /// need not be assembled (a matrix-free system: an assembly costs ~70
  /// sparse products at 16k nodes); rows scaled by the preconditioner
  /// matrix's largest entries (equilibrate_by). Without a usable
  /// preconditioner it returns 0 at once: converged() is then false, as
  /// after a cycle that did not converge, and the caller assembles A and
  /// calls solve().
  template <class Op>
  Eigen::VectorXd solve_operator(Op&& op, const Eigen::VectorXd& b) {
    const Eigen::Index n = b.size();
    last_iterations_ = 0;
    last_residual_ = 0.0;
    if (b.norm() == 0.0) return Eigen::VectorXd::Zero(n);
    if (frozen_ && kept_n_ != n) frozen_ = false;
    if ((!usable_ && !frozen_) || (!frozen_ && prm_.equilibrate && pre_row_max_.size() != n)) {
      last_residual_ = std::numeric_limits<double>::infinity();
      return Eigen::VectorXd::Zero(n);
    }
    return preconditioned(op, b, pre_row_max_, std::min(prm_.max_iterations, prm_.restart));
  }

  /// A v in parallel, the same for any thread count (column_product).
  Eigen::VectorXd product(const Matrix& A, const Eigen::VectorXd& v) {
    Eigen::VectorXd y;
    column_product(A, v, y, product_part_);
    return y;
  }

  // The kept LU: a direct factorization of a full system matrix (Newton's
  // tangent, or A after a fallback), kept across iterations, steps and
  // structures, as the preconditioner of solves whose matrices have moved on
  // a little. Unknowns are matched through their layout: the same field
  // unknowns, and multipliers by key. A few rows that came or went (contact
  // taken or released) are not left to GMRES: the preconditioner is the
  // exact inverse of the kept matrix with the released rows and columns
  // taken out (Sherman-Morrison-Woodbury, one LU solve per released row)
  // and the new rows bordered on (their columns from the operator, their
  // rows taken as the columns' transpose, as the saddle system's L and L^T
  // are). Left to GMRES (a released row's residual set to zero, a new row's
  // multiplier passed unchanged), changed rows cost iterations: in
  // test_flow's saddle system 13 for one released row, no convergence in 40
  // for four; on E3 the LU then failed its 20 and was made again.

  /// The layout of the next solves' unknowns.
  void set_layout(const DofLayout& layout) {
    if (layout == layout_) return;
    layout_ = layout;
    remap();
  }
  /// A kept LU can precondition solves of the current layout and size.
  bool kept_usable(Eigen::Index n) const { return kept_ok_ && map_ok_ && layout_.size() == n; }
  /// LU of A, kept for the current layout; `exact`: in double precision
  /// where the Kept policy factorizes in single precision by default;
  /// `symmetric`: A is symmetric, and the Kept policy may factorize it as
  /// L D L^T (half the work) where it can.
  void factorize_kept(const Matrix& A, bool exact = false, bool symmetric = false) {
    kept_ok_ = false;
    if constexpr (symmetric_kept) kept_.set_symmetric(symmetric);
    if constexpr (single_precision_kept) {
      kept_.set_exact(exact);
      if (exact) ++exact_factorizations_;
    }
    kept_.analyze(A);
    kept_.factorize(A);
    if constexpr (single_precision_kept)
      if (!exact && kept_.exact()) ++exact_factorizations_;  // float pivots vanished
    kept_ok_ = true;
    kept_layout_ = layout_;
    if (layout_.size() != A.rows()) kept_layout_ = DofLayout{-1, {}};  // no layout given: matches none
    kept_n_ = A.rows();
    keep_multiplier_rows(A);
    ++kept_factorizations_;
    remap();
  }
  /// GMRES on op(x) = b (op: the matrix-vector product, e.g. matrix-free)
  /// preconditioned by the kept LU, at most max_iterations, no fallback: the
  /// last iterate, with converged() saying whether it reached the tolerance.
  template <class Op>
  Eigen::VectorXd solve_kept(Op&& op, const Eigen::VectorXd& b, int max_iterations) {
    require(kept_usable(b.size()), "no kept LU for this layout", "GmresSolver::solve_kept");
    last_iterations_ = 0;
    last_residual_ = 0.0;
    if (b.norm() == 0.0) return Eigen::VectorXd::Zero(b.size());
    if (!identity_ && !update_.built) build_update(op);
    return gmres(std::forward<Op>(op), [this](const Eigen::VectorXd& v) { return kept_apply(v); }, b,
                 max_iterations);
  }
  /// Multiplier rows of the current layout the kept LU takes exactly by a
  /// low-rank update (released plus new), once a solve has built it; -1
  /// while none is built, or the update was singular (GMRES then sees the
  /// plain mapping: a released row's residual set to zero, a new row's
  /// multiplier passed unchanged).
  int kept_updated_rows() const {
    return update_.built && update_.usable ? static_cast<int>(released_.size() + added_.size()) : -1;
  }
  /// LU factorizations made for the kept preconditioner (direct fallbacks included).
  int kept_factorizations() const { return kept_factorizations_; }
  /// The Kept policy factorizes in single precision unless asked (set_exact).
  static constexpr bool single_precision_kept = requires(Kept& k) { k.set_exact(true); };
  /// The Kept policy can factorize a symmetric matrix as L D L^T.
  static constexpr bool symmetric_kept = requires(Kept& k) { k.set_symmetric(true); };
  /// Kept LUs made in double precision because a single-precision LU of the
  /// same matrix left GMRES short of its tolerance or was singular.
  int exact_factorizations() const { return exact_factorizations_; }

  int last_iterations() const { return last_iterations_; }
  /// The last solve reached the tolerance (after a direct fallback: its own residual did).
  bool converged() const { return last_residual_ <= prm_.tol; }
  /// False after the preconditioner failed to factorize (solves go direct).
  bool preconditioner_usable() const { return usable_; }
  /// The last solve's relative residual; in the equilibrated rows' norm
  /// where the companion preconditioned it (GmresParams::equilibrate).
  double last_residual() const { return last_residual_; }
  /// Solves done by a direct LU of A instead (GMRES did not converge in
  /// max_iterations, or P could not be factorized); that LU then
  /// preconditions the rest of the structure's solves.
  int direct_fallbacks() const { return direct_fallbacks_; }
  static constexpr const char* name() { return "GMRES + linear-triangle LU"; }

 private:
  // GMRES corrects what the preconditioner leaves; refining its solves (LU
  // solvers that can) would only repeat products with P.
  void no_refinement() {
    if constexpr (requires(Preconditioner& p) { p.set_refinement_steps(0); }) M_.set_refinement_steps(0);
    if constexpr (requires(Kept& p) { p.set_refinement_steps(0); }) kept_.set_refinement_steps(0);
  }
  // The largest |entry| of each row of A (1 for an empty row).
  static void row_maxima(const Matrix& A, Eigen::VectorXd& m) {
    m.setZero(A.rows());
    for (int j = 0; j < A.outerSize(); ++j)
      for (int k = A.outerIndexPtr()[j]; k < A.outerIndexPtr()[j + 1]; ++k)
        m[A.innerIndexPtr()[k]] = std::max(m[A.innerIndexPtr()[k]], std::abs(A.valuePtr()[k]));
    for (Eigen::Index i = 0; i < m.size(); ++i)
      if (!(m[i] > 0)) m[i] = 1.0;
  }
  template <class F>
  bool guard(F&& f) {
    try {
      f();
      return true;
    } catch (const Error&) {
      if (!prm_.direct_fallback) throw;
      return false;
    }
  }
  // Matches the current layout's multipliers to the kept LU's.
  void remap() {
    map_ok_ = identity_ = false;
    update_ = Update{};
    released_.clear();
    added_.clear();
    if (!kept_ok_ || kept_layout_.fields != layout_.fields) return;
    if (kept_layout_ == layout_) {
      map_ok_ = identity_ = true;
      return;
    }
    std::unordered_map<std::uint64_t, int> old;
    for (std::size_t j = 0; j < kept_layout_.multipliers.size(); ++j)
      old.emplace(kept_layout_.multipliers[j], static_cast<int>(j));
    map_.assign(layout_.multipliers.size(), -1);
    std::vector<char> used(kept_layout_.multipliers.size(), 0);
    for (std::size_t i = 0; i < layout_.multipliers.size(); ++i) {
      const auto it = old.find(layout_.multipliers[i]);
      if (it == old.end() || it->second < 0) {
        added_.push_back(static_cast<int>(i));
        continue;
      }
      map_[i] = it->second;
      used[static_cast<std::size_t>(it->second)] = 1;
      it->second = -1;  // each old row serves one new row
    }
    for (std::size_t j = 0; j < used.size(); ++j)
      if (!used[j]) released_.push_back(static_cast<int>(j));
    map_ok_ = static_cast<int>(released_.size() + added_.size()) <= prm_.kept_max_changed_rows;
  }
  // The kept matrix's multiplier rows (row F + j as column j), for the
  // update that takes released rows out.
  void keep_multiplier_rows(const Matrix& A) {
    const Eigen::Index F = kept_layout_.fields > 0 ? kept_layout_.fields : A.rows();
    std::vector<Eigen::Triplet<double>> t;
    for (int j = 0; j < A.outerSize(); ++j)
      for (int k = A.outerIndexPtr()[j]; k < A.outerIndexPtr()[j + 1]; ++k)
        if (A.innerIndexPtr()[k] >= F) t.emplace_back(j, A.innerIndexPtr()[k] - F, A.valuePtr()[k]);
    kept_rows_.resize(A.rows(), A.rows() - F);
    kept_rows_.setFromTriplets(t.begin(), t.end());
  }

  // The low-rank update of the kept LU to the current layout. Released old
  // rows J: K_J = K + sum_j (a_j e_j^T + e_j b_j^T) puts identity in their
  // rows and columns (a_j = e_j - K e_j, b_j = -(row j of K) off the
  // diagonal and off J); with W = K^-1 E_J, K^-1 a_j = W_j - e_j, so the
  // capacitance matrix is [[W_JJ, W_JJ], [B^T W, I + B^T W]]. New rows k
  // border K_J: [[K_J, C], [C^T, D]] with C, D the operator's columns, solved
  // through the Schur complement S = C^T K_J^-1 C - D.
  struct Update {
    bool built = false, usable = false;
    Eigen::MatrixXd W, B, C, G, D;
    Eigen::PartialPivLU<Eigen::MatrixXd> cap, schur;
  };
  template <class Op>
  void build_update(Op&& op) {
    update_ = Update{};
    update_.built = true;
    const Eigen::Index n0 = kept_n_, F = layout_.fields;
    const auto J = static_cast<Eigen::Index>(released_.size());
    const auto nk = static_cast<Eigen::Index>(added_.size());
    Update u;
    u.built = true;
    if (J > 0) {
      u.W.resize(n0, J);
      u.B = Eigen::MatrixXd::Zero(n0, J);
      for (Eigen::Index j = 0; j < J; ++j) {
        const Eigen::Index row = F + released_[static_cast<std::size_t>(j)];
        u.W.col(j) = kept_.solve(Eigen::VectorXd::Unit(n0, row));
        for (Matrix::InnerIterator it(kept_rows_, row - F); it; ++it) u.B(it.row(), j) = -it.value();
      }
      for (Eigen::Index j = 0; j < J; ++j) u.B.row(F + released_[static_cast<std::size_t>(j)]).setZero();
      Eigen::MatrixXd WJJ(J, J);
      for (Eigen::Index i = 0; i < J; ++i) WJJ.row(i) = u.W.row(F + released_[static_cast<std::size_t>(i)]);
      const Eigen::MatrixXd BW = u.B.transpose() * u.W;
      Eigen::MatrixXd cap(2 * J, 2 * J);
      cap << WJJ, WJJ, BW, Eigen::MatrixXd::Identity(J, J) + BW;
      u.cap.compute(cap);
      if (!(u.cap.rcond() > 1e-12)) return;  // K_J singular: the released rows held a mode
    }
    if (nk > 0) {
      u.C = Eigen::MatrixXd::Zero(n0, nk);
      u.D.resize(nk, nk);
      const Eigen::Index n = layout_.size();
      for (Eigen::Index k = 0; k < nk; ++k) {
        const Eigen::VectorXd col = op(Eigen::VectorXd::Unit(n, F + added_[static_cast<std::size_t>(k)]));
        u.C.col(k).head(F) = col.head(F);
        for (std::size_t i = 0; i < map_.size(); ++i)
          if (map_[i] >= 0) u.C(F + map_[i], k) = col[F + static_cast<Eigen::Index>(i)];
        for (Eigen::Index l = 0; l < nk; ++l) u.D(l, k) = col[F + added_[static_cast<std::size_t>(l)]];
      }
      u.G.resize(n0, nk);
      for (Eigen::Index k = 0; k < nk; ++k) u.G.col(k) = solve_released(u, u.C.col(k));
      u.schur.compute(u.C.transpose() * u.G - u.D);
      if (!(u.schur.rcond() > 1e-12)) return;  // a new row dependent on the others
    }
    u.usable = true;
    update_ = std::move(u);
  }
  // K_J^-1 r (r zero in the released rows).
  Eigen::VectorXd solve_released(const Update& u, const Eigen::VectorXd& r) const {
    Eigen::VectorXd y = kept_.solve(r);
    const auto J = static_cast<Eigen::Index>(released_.size());
    if (J == 0) return y;
    const Eigen::Index F = layout_.fields;
    Eigen::VectorXd v(2 * J);
    for (Eigen::Index j = 0; j < J; ++j) v[j] = y[F + released_[static_cast<std::size_t>(j)]];
    v.tail(J).noalias() = u.B.transpose() * y;
    const Eigen::VectorXd t = u.cap.solve(v);
    y.noalias() -= u.W * (t.head(J) + t.tail(J));
    for (Eigen::Index j = 0; j < J; ++j) y[F + released_[static_cast<std::size_t>(j)]] += t[j];
    return y;
  }
  // z = M^-1 r with M the kept LU, through the layout map (and its update).
  Eigen::VectorXd kept_apply(const Eigen::VectorXd& r) const {
    if (identity_) return kept_.solve(r);
    const int F = layout_.fields;
    Eigen::VectorXd r0 = Eigen::VectorXd::Zero(kept_n_);
    r0.head(F) = r.head(F);
    for (std::size_t i = 0; i < map_.size(); ++i)
      if (map_[i] >= 0) r0[F + map_[i]] = r[F + static_cast<Eigen::Index>(i)];
    const bool exact = update_.built && update_.usable;
    Eigen::VectorXd z0 = exact ? solve_released(update_, r0) : kept_.solve(r0);
    Eigen::VectorXd mu;
    if (exact && !added_.empty()) {
      Eigen::VectorXd rk(static_cast<Eigen::Index>(added_.size()));
      for (std::size_t k = 0; k < added_.size(); ++k) rk[static_cast<Eigen::Index>(k)] = r[F + added_[k]];
      mu = update_.schur.solve(update_.C.transpose() * z0 - rk);
      z0.noalias() -= update_.G * mu;
    }
    Eigen::VectorXd z(r.size());
    z.head(F) = z0.head(F);
    for (std::size_t i = 0; i < map_.size(); ++i) {
      const Eigen::Index k = F + static_cast<Eigen::Index>(i);
      z[k] = map_[i] >= 0 ? z0[F + map_[i]] : r[k];
    }
    if (mu.size() > 0)
      for (std::size_t k = 0; k < added_.size(); ++k) z[F + added_[k]] = mu[static_cast<Eigen::Index>(k)];
    return z;
  }

  // GMRES on op(x) = b preconditioned by the companion's LU, rows scaled by
  // `scale` (GmresParams::equilibrate), or after a direct fallback by the
  // kept LU of that A.
  template <class Op>
  Eigen::VectorXd preconditioned(Op&& op, const Eigen::VectorXd& b, const Eigen::VectorXd& scale,
                                 int max_iterations) {
    if (!frozen_ && prm_.equilibrate)
      return gmres([&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return op(v).cwiseQuotient(scale); },
                   [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return M_.solve(v.cwiseProduct(scale)); },
                   b.cwiseQuotient(scale), max_iterations);
    return gmres(
        op, [this](const Eigen::VectorXd& v) -> Eigen::VectorXd { return frozen_ ? kept_.solve(v) : M_.solve(v); },
        b, max_iterations);
  }

  // Below this tolerance GMRES confirms convergence by a product (its
  // estimate drops below b - A x's rounding floor near 1e-13 relative).
  static constexpr double confirm_tol = 1e-10;

  // Restarted GMRES from x = 0, right-preconditioned: op(M^-1 u) = b, x = M^-1 u
  // (pre(v) = M^-1 v).
  template <class Op, class Pre>
  Eigen::VectorXd gmres(Op&& op, Pre&& pre, const Eigen::VectorXd& b, int max_iterations) {
    const Eigen::Index n = b.size();
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    const int m = std::max(1, std::min(prm_.restart, max_iterations));  // the basis a solve can use
    V_.resize(n, m + 1);
    Z_.resize(n, m);
    H_.setZero(m + 1, m);
    cs_.resize(m);
    sn_.resize(m);
    g_.resize(m + 1);
    const double bnorm = b.norm();
    Eigen::VectorXd r = b, w;
    double rnorm = bnorm;
    const double target = prm_.tol * bnorm;
    while (last_iterations_ < max_iterations) {
      V_.col(0) = r / rnorm;
      g_.setZero();
      g_[0] = rnorm;
      int j = 0;
      for (; j < m && last_iterations_ < max_iterations; ++j) {
        ++last_iterations_;
        // Kept: x is then a sum of Z's columns, no further solve (and no
        // solve with a single-precision LU, which is linear only to ~1e-7).
        Z_.col(j) = pre(V_.col(j));
        w = op(Z_.col(j));
        // Classical Gram-Schmidt, repeated once ("twice is enough") for the
        // orthogonality a tight tolerance needs; as matrix-vector products,
        // which stay cheap next to A's product up to the restart length.
        for (int pass = 0; pass < 2; ++pass) {
          h_.noalias() = V_.leftCols(j + 1).transpose() * w;
          w.noalias() -= V_.leftCols(j + 1) * h_;
          H_.col(j).head(j + 1) += h_;
        }
        H_(j + 1, j) = w.norm();
        if (H_(j + 1, j) > 0) V_.col(j + 1) = w / H_(j + 1, j);
        for (int i = 0; i < j; ++i) {  // previous Givens rotations
          const double t = cs_[i] * H_(i, j) + sn_[i] * H_(i + 1, j);
          H_(i + 1, j) = -sn_[i] * H_(i, j) + cs_[i] * H_(i + 1, j);
          H_(i, j) = t;
        }
        const double den = std::hypot(H_(j, j), H_(j + 1, j));
        cs_[j] = den > 0 ? H_(j, j) / den : 1.0;
        sn_[j] = den > 0 ? H_(j + 1, j) / den : 0.0;
        H_(j, j) = den;
        H_(j + 1, j) = 0.0;
        g_[j + 1] = -sn_[j] * g_[j];
        g_[j] = cs_[j] * g_[j];
        if (std::abs(g_[j + 1]) <= target || den == 0.0) {
          ++j;
          break;
        }
      }
      // x += M^-1 V y = Z y with H y = g (upper triangular j x j).
      const Eigen::VectorXd y =
          H_.topLeftCorner(j, j).template triangularView<Eigen::Upper>().solve(g_.head(j));
      x.noalias() += Z_.leftCols(j) * y;
      // |g_j| is |b - op(x)| while it stays above the rounding floor of that
      // difference (Z is kept, so a nonlinear pre does not spoil it): a
      // converged cycle needs no product to confirm it, except for tight
      // tolerances, where the estimate can fall below the true residual.
      const bool estimate_holds = prm_.tol >= confirm_tol && H_(j - 1, j - 1) != 0.0;
      if (estimate_holds && std::abs(g_[j]) <= target) {
        rnorm = std::abs(g_[j]);
        H_.setZero();
        break;
      }
      r = b - op(x);
      rnorm = r.norm();
      H_.setZero();
      if (rnorm <= target) break;
    }
    last_residual_ = rnorm / bnorm;
    MAXENTFLOW_REQUIRE(x.allFinite(), "GMRES produced NaN/Inf (singular preconditioner?)", "GmresSolver");
    return x;
  }
  Eigen::VectorXd direct(const Matrix& A, const Eigen::VectorXd& b) {
    require(prm_.direct_fallback, "no usable preconditioner and no direct fallback", "GmresSolver::solve");
    ++direct_fallbacks_;
    factorize_kept(A);
    frozen_ = true;
    // GMRES preconditioned by the LU of A itself: one or two iterations with
    // double-precision factors, a few with single-precision ones, which are
    // made again in double if they leave GMRES short. The iterations count
    // on from those of a GMRES that failed before.
    const int before = last_iterations_;
    auto refined = [&] {
      last_iterations_ = 0;
      return gmres([&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return product(A, v); },
                   [this](const Eigen::VectorXd& v) -> Eigen::VectorXd { return kept_.solve(v); }, b,
                   prm_.restart);
    };
    Eigen::VectorXd x = refined();
    int its = before + last_iterations_;
    if (single_precision_kept && last_residual_ > prm_.tol) {
      factorize_kept(A, true);
      x = refined();
      its += last_iterations_;
    }
    last_iterations_ = its;
    return x;
  }

  params prm_;
  bool analyzed_ = false, usable_ = false, frozen_ = false;
  Preconditioner M_;
  Kept kept_;
  bool kept_ok_ = false, map_ok_ = false, identity_ = false;
  DofLayout layout_, kept_layout_;
  std::vector<int> map_;  // current multiplier -> the kept LU's (-1: new)
  std::vector<int> released_, added_;  // the kept LU's rows not in the layout; the layout's new rows
  Matrix kept_rows_;                   // the kept matrix's multiplier rows, as columns
  Update update_;
  Eigen::Index kept_n_ = -1;
  int kept_factorizations_ = 0, exact_factorizations_ = 0;
  Eigen::VectorXd row_max_;       // A's largest |entry| per row (equilibrate)
  Eigen::VectorXd pre_row_max_;   // P's, for solve_operator
  Eigen::MatrixXd product_part_;  // column_product's storage
  Eigen::MatrixXd V_, Z_, H_;
  Eigen::VectorXd cs_, sn_, g_, h_;
  int last_iterations_ = 0, direct_fallbacks_ = 0;
  double last_residual_ = 0.0;
};

static_assert(PreconditionedLinearSolver<GmresSolver<>>);
static_assert(SteerableKrylovSolver<GmresSolver<>>);
static_assert(MatrixFreeKrylovSolver<GmresSolver<>>);
static_assert(KeptLuLinearSolver<GmresSolver<>>);

}  // namespace maxentflow

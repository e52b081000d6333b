// maxentflow: direct (Picard) iteration, then Newton with the consistent
// tangent, as the paper recommends (section "The stabilized viscoplastic formulation").
#pragma once

#include <algorithm>
#include <chrono>
#include <limits>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <iosfwd>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <maxentflow/core/dof_layout.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/core/linearization.hpp>
#include <maxentflow/core/parallel.hpp>
#include <maxentflow/solver/krylov_solver.hpp>
#include <maxentflow/solver/linear_solver.hpp>

namespace maxentflow {

/// What NonlinearSolver needs from a system (FlowSystem is one).
template <class S>
concept NonlinearSystem =
    requires(S& s, const Eigen::VectorXd& x, Eigen::VectorXd& r,
             Eigen::SparseMatrix<double, Eigen::ColMajor, int>& A) {
      { s.size() } -> std::convertible_to<int>;
      { s.structure_generation() } -> std::convertible_to<long>;
      s.assemble(x, Linearization::picard, A, r);
      s.residual(x, r);
      { s.relative_residual(r) } -> std::convertible_to<double>;
      { s.velocity_norm(x) } -> std::convertible_to<double>;
    };

/// A system that also assembles a preconditioner (for Krylov policies).
template <class S>
concept PreconditionedSystem =
    NonlinearSystem<S> && requires(S& s, const Eigen::VectorXd& x,
                                   Eigen::SparseMatrix<double, Eigen::ColMajor, int>& P) {
      s.assemble_preconditioner(x, P);
      { s.preconditioner_generation() } -> std::convertible_to<long>;
    };

/// A system that says what its unknowns mean (FlowSystem::layout), so that a
/// factorization can be kept across systems, and applies its tangent.
template <class S>
concept LayoutKeyedSystem = NonlinearSystem<S> && requires(S& s, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  { s.layout() } -> std::convertible_to<const DofLayout&>;
  s.apply_tangent(x, x, y);  // y = J(x) x: Newton's tangent applied matrix-free
};
/// ... and its Picard matrix too, so that a Picard iteration served by a kept
/// LU assembles no matrix either.
template <class S>
concept MatrixFreePicardSystem = LayoutKeyedSystem<S> && requires(S& s, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  s.apply_tangent(x, x, y, Linearization::picard);
};

/// A system that says which of its matrices are symmetric, and can assemble
/// Newton's tangent without d tau / d v (Linearization::newton_symmetric),
/// so that kept LUs can be L D L^T (NonlinearSolverParams::symmetric_lu).
template <class S>
concept SymmetricSystem = LayoutKeyedSystem<S> && requires(const S& s, Linearization kind) {
  { s.symmetric(kind) } -> std::convertible_to<bool>;
};

/// Either kind of linear-solver policy: direct (LinearSolver) or Krylov
/// with a preconditioner the system assembles (PreconditionedLinearSolver).
template <class S>
concept LinearSolverPolicy = LinearSolver<S> || PreconditionedLinearSolver<S>;

struct IterationRecord {
  int iteration = 0;
  Linearization kind = Linearization::picard;
  double residual = 0.0;   ///< relative momentum residual at the start of the iteration
  double increment = 0.0;  ///< |dv|_inf / |v|_inf of the update made
  double step = 1.0;       ///< line-search step length
  int linear_iterations = 0;  ///< Krylov iterations of the solve (0: direct)
};

struct SolveReport {
  bool converged = false;
  int picard = 0, newton = 0;
  int linear_iterations = 0;  ///< Krylov iterations, all solves
  int max_linear_iterations = 0;  ///< Krylov iterations of the longest solve
  int preconditioner_updates = 0;  ///< preconditioner factorizations (Krylov policies)
  int direct_fallbacks = 0;  ///< Krylov solves that fell back to a direct LU of A
  double residual = 0.0, increment = 0.0;
  double assembly_seconds = 0.0, factorization_seconds = 0.0, solve_seconds = 0.0;
  std::vector<IterationRecord> history;
  int iterations() const { return picard + newton; }
  /// One line per iteration: it, kind, residual, increment, step.
  std::string log() const {
    std::ostringstream os;
    char line[128];
    for (const auto& h : history) {
      std::snprintf(line, sizeof line,
                    "  %3d %-6s residual %.3e  increment %.3e  step %.3g  linear its %d\n",
                    h.iteration, h.kind == Linearization::picard ? "picard" : "newton", h.residual,
                    h.increment, h.step, h.linear_iterations);
      os << line;
    }
    return os.str();
  }
};

struct NonlinearSolverParams {
  int max_iterations = 60;
  int max_picard = 40;             ///< Picard iterations before Newton is forced
  double switch_increment = 1e-2;  ///< Picard -> Newton when the increment falls below
  bool newton = true;              ///< false: Picard only
  /// Start with Newton when X comes in with a velocity (a warm start, e.g. the
  /// previous step's solution); a failed line search still falls back to Picard.
  bool newton_from_warm_start = true;
  /// Converged after a full Newton step once the residual is below
  /// residual_tol, without the solve that confirms the increment. Saves one
  /// solve per step, but leaves velocity errors of the order residual_tol,
  /// which an updated-Lagrangian run accumulates in the node positions (a
  /// straight free side then drifts off straight by ~1e-10 h per step, the
  /// scale of the basis's hull tolerance); off by default.
  bool accept_newton_on_residual = false;
  /// Converged when the relative velocity increment and the relative momentum
  /// residual are both below these. Newton's last step then leaves errors far
  /// below them (E1's force stays exact to 1e-10 at 1e-7). At 1e-9 an inexact
  /// (Krylov) Newton can stall at residuals of ~1e-8 on a sticking block
  /// (bench_flow, 1k nodes), where the direct solver still converges.
  double velocity_tol = 1e-7;
  double residual_tol = 1e-7;
  int line_search = 8;             ///< step halvings
  /// Newton that makes only short steps (line search at or below
  /// newton_stall_step) for newton_stall_iterations in a row is stalled, not
  /// converging: back to Picard, as after a failed line search. Seen where
  /// the Norton-Hoff viscosity of a dead zone (strain rate near d_min) bends
  /// the residual faster than the tangent follows. 0: never.
  int newton_stall_iterations = 3;
  double newton_stall_step = 1.0 / 16;
  /// After Newton's k-th failed line search (or stall) in a solve, Picard
  /// takes 2^(k-1) iterations before Newton is tried again, and the solve
  /// stops (Error) at the max_newton_failures-th, rather than alternate one
  /// Picard iteration with a failing Newton one up to max_iterations: where
  /// Newton keeps failing, Picard alone converges too slowly to finish (E3:
  /// 30 failures, 60 iterations, 90 s, then the step's retry at dt / 2
  /// converged in 18 iterations). 0: never stop.
  int max_newton_failures = 4;
  /// Krylov policies: solve each linearization only as far as the outer
  /// iteration can use (inexact Newton forcing term, Eisenstat-Walker style):
  /// |R + A dx| <= eta |R| with eta = clamp(max(res, 0.5 residual_tol / res),
  /// eta_min, eta_max), res the current relative residual.
  double eta_max = 1e-2;
  /// The cap for Picard solves. Picard's increments decide the switch to
  /// Newton, and a loose solve understates them: at 1e-2 the sticking block of
  /// bench_flow (1k nodes) switched with the residual still at 0.67 and Newton
  /// diverged; at 1e-3 and 1e-4 it takes the Picard path of an exact solve.
  double eta_picard = 1e-4;
  /// The cap for Picard solves of a warm-started solve (X comes in with a
  /// velocity): there Picard only brings a start a few per cent off into
  /// Newton's basin, and the looser solve does it in the same iterations
  /// (E2, 15 steps: 45 Picard iterations, 1.9k Krylov iterations against
  /// 3.7k at 1e-4; docs/method.md section 8).
  double eta_picard_warm = 1e-2;
  double eta_min = 1e-12;
  /// Krylov policies: the preconditioner is rebuilt (assembled, factorized)
  /// once a solve needs more than this times the Krylov iterations per decade
  /// of residual reduction of the first solve with it; <= 0: every iteration.
  double preconditioner_refresh = 1.1;
  /// Policies that keep an LU (KeptLuLinearSolver) on systems that give their
  /// layout (LayoutKeyedSystem): Newton iterations solve with GMRES
  /// preconditioned by an LU of Newton's tangent kept across iterations and
  /// solves (steps), with the tangent applied matrix-free (apply_tangent,
  /// which costs a few per cent of an assembly), so that a warm-started Newton
  /// iteration assembles no matrix. The LU is made again (tangent assembled at
  /// the current iterate) when GMRES does not converge in kept_lu_iterations,
  /// the layout changes too much, or preconditioner_refresh <= 0. Systems with
  /// more unknowns than kept_lu_max_unknowns use the linear-triangle
  /// preconditioner instead (the LU's memory). kept_lu_iterations is a count,
  /// not a measured cost, so that a run does not depend on the machine's load:
  /// a factorization costs about 50 GMRES iterations with it (measured at 525,
  /// 1k and 4k nodes), and an LU a step or two old needs 5-20.
  bool kept_lu = true;
  int kept_lu_iterations = 20;
  /// The LU is also made again, before a solve, once the solves since it was
  /// made have needed this many GMRES iterations more than its first one did
  /// (an LU ages as the configuration moves on). A count, as above; E1's run
  /// time is flat from about 90 to 300 and 20 % longer with no such renewal.
  int kept_lu_aged_iterations = 100;
  /// An LU carried into a new solve (the next active set or step) that failed
  /// there is not tried at the start of the next this-many solves: they make
  /// their own at once (a configuration that moves fast, as E2's, would lose
  /// kept_lu_iterations each time).
  int kept_lu_skip_carry = 4;
  /// The forcing-term cap of those solves: a tighter linear solve saves
  /// Newton iterations (E1: 229 instead of 303 in 100 steps) and leaves the
  /// unknowns the convergence test does not read (pressure, multipliers)
  /// closer to the exact solution. Where Newton iterations assemble nothing
  /// the GMRES iterations and LUs made again can cost more than the Newton
  /// iterations save: the extrusion and cutting examples use 1e-2
  /// (docs/method.md section 8).
  double eta_kept_lu = 1e-4;
  /// Picard iterations of a warm-started solve also solve with GMRES
  /// preconditioned by a kept LU, of a Picard matrix (a second one, kept as
  /// Newton's is), instead of the linear-triangle preconditioner: a step's
  /// Picard matrices differ little from the last step's, and with the
  /// companion each Picard solve took ~40 GMRES iterations, 3/4 of all of
  /// E2's (docs/method.md section 8). Solves from rest keep the companion.
  /// Where the system applies its Picard matrix matrix-free
  /// (MatrixFreePicardSystem), such an iteration assembles no matrix either.
  bool kept_lu_picard = true;
  /// Kept LUs of symmetric matrices are L D L^T, where the policy can and
  /// the system says its matrix is symmetric (SymmetricSystem): Picard's,
  /// and for Newton the tangent without d tau / d v
  /// (Linearization::newton_symmetric), GMRES taking that term in. Half the
  /// flops and factor memory of an LU; E2: 1-2 % more GMRES iterations,
  /// 100 steps 31.7-33.2 -> 23.8-27.8 s (docs/method.md section 8).
  bool symmetric_lu = true;
  int kept_lu_max_unknowns = 20000;
  /// Iterations the linear-triangle preconditioner serves (solves from rest,
  /// systems above kept_lu_max_unknowns) evaluate the residual only and give
  /// GMRES the system's matrix-free product (MatrixFreePicardSystem), where
  /// the policy can (MatrixFreeKrylovSolver): the matrix is assembled only
  /// for a direct fallback. An assembly costs about 30 residuals or 70
  /// sparse products (bench_flow, 16k nodes), a matrix-free product 1.3
  /// sparse ones, and the matrix is 752 MB at 64k nodes.
  bool matrix_free_krylov = true;
  std::ostream* log = nullptr;     ///< per-iteration log
};

/// Picard until the relative velocity increment drops below switch_increment
/// (or max_picard iterations), then Newton with a backtracking line search on
/// |R|; a Newton step the line search cannot make fall back to Picard.
/// Converged when increment <= velocity_tol and residual <= residual_tol.
template <LinearSolverPolicy Linear = UmfpackSolver>
class NonlinearSolver {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  using params = NonlinearSolverParams;

  NonlinearSolver() = default;
  explicit NonlinearSolver(params prm) : prm_(prm) {}
  params& parameters() { return prm_; }
  Linear& linear_solver() { return linear_; }

  /// Solves R(X) = 0 from the start X (e.g. the previous step's fields; zero is
  /// fine: the first Picard iteration is then a Newtonian solve).
  template <NonlinearSystem System>
  SolveReport solve(System& sys, Eigen::VectorXd& X) {
    return solve(sys, X, Start::fresh);
  }

  /// Continues the last solve, on the same system and from its result X, to
  /// tolerances set since (parameters()): Newton from the first iteration, and
  /// the LUs that solve made count as this one's (they are of these very
  /// systems). For a solve first taken only as far as a decision needs (the
  /// stepper's contact active set), then finished.
  template <NonlinearSystem System>
  SolveReport resume(System& sys, Eigen::VectorXd& X) {
    return solve(sys, X, Start::resume);
  }

  /// Solves again on the configuration of the last solve with some
  /// constraint rows changed (the stepper's next active-set iteration), from
  /// its result X, as solve() does; the LUs the last solve made count as this
  /// one's: they are of the same matrices but for those rows, which the kept
  /// LU takes by its low-rank update. (An LU carried from another
  /// configuration, the last step's, is not tried first after one failed.)
  template <NonlinearSystem System>
  SolveReport resolve(System& sys, Eigen::VectorXd& X) {
    return solve(sys, X, Start::same_configuration);
  }

 private:
  enum class Start { fresh, same_configuration, resume };
  template <NonlinearSystem System>
  SolveReport solve(System& sys, Eigen::VectorXd& X, Start start) {
    SolveReport rep;
    const int n = sys.size();
    const bool resume = start == Start::resume;
    fit_start(X, n);
    if (start == Start::fresh)
      for (auto* k : {&newton_lu_, &picard_lu_}) {
        k->made_this_solve = false;
        if (k->skip_carry > 0) --k->skip_carry;
      }
    warm_start_ = sys.velocity_norm(X) > 0;
    Linearization phase =
        prm_.newton && ((prm_.newton_from_warm_start && warm_start_) || resume) ? Linearization::newton
                                                                                 : Linearization::picard;
    int fallbacks_before = 0;
    if constexpr (SteerableKrylovSolver<Linear>)
      fallbacks_before = linear_.direct_fallbacks() + picard_linear_.direct_fallbacks();
    bool full_newton_step = false;
    int newton_failures = 0, picard_due = 0;  // failed or stalled Newton phases; Picard iterations before the next
    int short_steps = 0;  // Newton steps in a row at or below newton_stall_step
    double increment = std::numeric_limits<double>::infinity();
    Eigen::VectorXd R, dx;
    for (int it = 0; it < prm_.max_iterations; ++it) {
      // 1. Residual (and the matrix, unless the kept LU serves this iteration).
      const Linearization kind = phase;
      const bool kept = use_kept_lu(sys, n) &&
                        (kind == Linearization::newton || (prm_.kept_lu_picard && warm_start_));
      auto t0 = clock::now();
      // An iteration the kept LU serves applies its matrix matrix-free (a
      // Picard one where the system can): only the residual is evaluated.
      const bool newton = kind == Linearization::newton;
      // Newton's kept LU, where it is made of newton_symmetric's matrix, needs
      // no assembly of Newton's tangent (applied matrix-free).
      const bool free_krylov = !kept && matrix_free_krylov<System>();
      const bool assembled = !free_krylov && !(kept && (newton || MatrixFreePicardSystem<System>) &&
                                               (kept_lu_current(newton ? linear_ : picard_linear_, n) ||
                                                (newton && symmetric_newton_lu(sys))));
      // A kept Newton LU of newton_symmetric's matrix that is due for this
      // layout: that matrix with the residual, in one pass.
      symmetric_assembled_ = !assembled && newton && kept && symmetric_newton_lu(sys) && !kept_lu_current(linear_, n);
      if (assembled)
        sys.assemble(X, kind, A_, R);
      else if (symmetric_assembled_)
        sys.assemble(X, Linearization::newton_symmetric, S_, R);
      else
        sys.residual(X, R);
      rep.assembly_seconds += seconds(t0);
      const double res = sys.relative_residual(R);
      rep.residual = res;
      if (it > 0 && res <= prm_.residual_tol &&
          (increment <= prm_.velocity_tol || (prm_.accept_newton_on_residual && full_newton_step))) {
        rep.converged = true;
        break;
      }
      // 2. The direction: kept-LU Newton, preconditioned Krylov, or direct.
      int linear_its = 0;
      if (kept) {
        if constexpr (KeptLuLinearSolver<Linear> && LayoutKeyedSystem<System>)
          dx = kept_lu_direction(sys, X, R, res, kind, assembled, rep, linear_its);
      } else if constexpr (PreconditionedLinearSolver<Linear>) {
        dx = krylov_direction(sys, X, R, res, kind, free_krylov, rep, linear_its);
      } else {
        dx = direct_direction(sys, R, rep);
      }
      MAXENTFLOW_REQUIRE(dx.allFinite(),
                         detail::cat("the linear solve gave NaN/Inf (singular system?) at iteration ",
                                     it, "\n", rep.log()),
                         "NonlinearSolver::solve");
      // 3. The step: full for Picard, backtracking on |R| for Newton.
      const double step = kind == Linearization::newton ? line_search(sys, X, R, dx, rep) : 1.0;
      if (step == 0.0) {  // Newton is outside its basin: back to direct iteration
        rep.history.push_back({it, kind, res, 0.0, 0.0, linear_its});
        ++rep.newton;
        if (prm_.log) *prm_.log << "  newton line search failed; back to picard\n";
        newton_failed(++newton_failures, picard_due, rep);
        phase = Linearization::picard;
        picard_since_switch_ = 0;
        full_newton_step = false;
        continue;
      }
      X += step * dx;
      // The first Picard iterate from rest has mu(d_min)'s pressure scale.
      if constexpr (requires { sys.rescale_stresses(X); })
        if (it == 0 && !warm_start_ && !resume && kind == Linearization::picard) sys.rescale_stresses(X);
      full_newton_step = kind == Linearization::newton && step == 1.0;
      short_steps = kind == Linearization::newton && step <= prm_.newton_stall_step ? short_steps + 1 : 0;
      const double vnorm = sys.velocity_norm(X);
      increment = step * sys.velocity_norm(dx) / (vnorm > 0 ? vnorm : 1.0);
      rep.increment = increment;
      rep.history.push_back({it, kind, res, increment, step, linear_its});
      (kind == Linearization::picard ? rep.picard : rep.newton) += 1;
      log_iteration(it, kind, res, increment, step, linear_its);
      // 4. Picard hands over to Newton once the increment is small; a
      //    stalled Newton hands back.
      if (prm_.newton_stall_iterations > 0 && short_steps >= prm_.newton_stall_iterations) {
        if (prm_.log) *prm_.log << "  newton stalled (" << short_steps << " short steps); back to picard\n";
        newton_failed(++newton_failures, picard_due, rep);
        phase = Linearization::picard;
        picard_since_switch_ = 0;
        short_steps = 0;
        continue;
      }
      if (phase == Linearization::picard) ++picard_since_switch_;
      if (phase == Linearization::picard && prm_.newton && picard_since_switch_ >= picard_due &&
          (increment < prm_.switch_increment || picard_since_switch_ >= prm_.max_picard))
        phase = Linearization::newton;
    }
    picard_since_switch_ = 0;
    if constexpr (SteerableKrylovSolver<Linear>)
      rep.direct_fallbacks = linear_.direct_fallbacks() + picard_linear_.direct_fallbacks() - fallbacks_before;
    if (!rep.converged)
      throw Error(detail::cat("no convergence in ", prm_.max_iterations, " iterations (residual ",
                              rep.residual, ", increment ", rep.increment, "); history:\n", rep.log()),
                  "NonlinearSolver::solve");
    return rep;
  }

  using clock = std::chrono::steady_clock;
  // Newton failed (line search or stall) for the k-th time in this solve.
  void newton_failed(int k, int& picard_due, const SolveReport& rep) const {
    if (prm_.max_newton_failures > 0 && k >= prm_.max_newton_failures)
      throw Error(detail::cat("Newton failed ", k, " times (line search or stall; residual ", rep.residual,
                              "); history:\n", rep.log()),
                  "NonlinearSolver::solve");
    picard_due = 1 << std::min(k - 1, 20);
  }
  // A start of another size: cut, or padded with zeros.
  static void fit_start(Eigen::VectorXd& X, int n) {
    if (X.size() == n) return;
    Eigen::VectorXd Y = Eigen::VectorXd::Zero(n);
    Y.head(std::min<Eigen::Index>(n, X.size())) = X.head(std::min<Eigen::Index>(n, X.size()));
    X = Y;
  }
  static double seconds(clock::time_point a) { return std::chrono::duration<double>(clock::now() - a).count(); }

  // A direction from the preconditioned Krylov policy; the preconditioner's LU
  // is kept while GMRES needs no more iterations per decade of residual than
  // just after it was made.
  template <class System>
  Eigen::VectorXd krylov_direction(System& sys, const Eigen::VectorXd& X, const Eigen::VectorXd& R,
                                   double res, Linearization kind, bool matrix_free, SolveReport& rep,
                                   int& linear_its) {
    static_assert(PreconditionedSystem<System>, "a Krylov policy needs a system with assemble_preconditioner()");
    const int n = sys.size();
    auto t0 = clock::now();
    auto refresh = [&] {
      t0 = clock::now();
      sys.assemble_preconditioner(X, P_);
      rep.assembly_seconds += seconds(t0);
      t0 = clock::now();
      if (sys.preconditioner_generation() != analyzed_generation_ || analyzed_size_ != n) {
        if constexpr (requires { linear_.analyze_preconditioner(P_, true); })
          linear_.analyze_preconditioner(P_, symmetric_matrix(sys, Linearization::picard));
        else
          linear_.analyze_preconditioner(P_);
        analyzed_generation_ = sys.preconditioner_generation();
        analyzed_size_ = n;
      }
      linear_.factorize_preconditioner(P_);
      rep.factorization_seconds += seconds(t0);
      fresh_rate_ = -1.0;
      ++rep.preconditioner_updates;
    };
    const bool kept = sys.preconditioner_generation() == analyzed_generation_ && analyzed_size_ == n &&
                      prm_.preconditioner_refresh > 0 && rate_ <= prm_.preconditioner_refresh * fresh_rate_;
    if (!kept) refresh();
    Eigen::VectorXd dx;
    if constexpr (SteerableKrylovSolver<Linear>) {
      const double eta = std::max(res, 0.5 * prm_.residual_tol / std::max(res, 1e-300));
      const double cap = kind != Linearization::picard ? prm_.eta_max
                         : warm_start_                  ? prm_.eta_picard_warm
                                                        : prm_.eta_picard;
      linear_.set_tolerance(std::clamp(eta, prm_.eta_min, cap));
      // A kept preconditioner that GMRES cannot converge with is rebuilt
      // before the (costly) direct fallback is tried.
      t0 = clock::now();
      // Matrix-free (the matrix is then assembled only for the fallback), or
      // with A_; `last`: the assembled solve may fall back to a direct LU.
      constexpr bool can_free = MatrixFreeKrylovSolver<Linear> && MatrixFreePicardSystem<System>;
      auto attempt = [&](bool last) -> Eigen::VectorXd {
        if constexpr (can_free)
          if (matrix_free)
            return linear_.solve_operator(
                [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
                  sys.apply_tangent(X, v, Jv_, kind);
                  return Jv_;
                },
                -R);
        return linear_.solve(A_, -R, last);
      };
      if constexpr (can_free)
        if (matrix_free && kept) {  // the rows' scales at this iterate (the LU stays P's of an earlier one)
          sys.assemble_preconditioner(X, P_);
          linear_.equilibrate_by(P_);
          rep.assembly_seconds += seconds(t0);
        }
      t0 = clock::now();
      dx = attempt(!kept);
      if (kept && !linear_.converged()) {
        rep.linear_iterations += linear_.last_iterations();
        rep.solve_seconds += seconds(t0);
        refresh();
        t0 = clock::now();
        dx = attempt(true);
      }
      if (can_free && matrix_free && !linear_.converged()) {  // the fallback needs the matrix itself
        rep.linear_iterations += linear_.last_iterations();
        rep.solve_seconds += seconds(t0);
        t0 = clock::now();
        Eigen::VectorXd R2;
        sys.assemble(X, kind, A_, R2);
        rep.assembly_seconds += seconds(t0);
        t0 = clock::now();
        dx = linear_.solve(A_, -R);
      }
    } else {
      t0 = clock::now();
      dx = linear_.solve(A_, -R);
    }
    rep.solve_seconds += seconds(t0);
    linear_its = linear_.last_iterations();
    rep.linear_iterations += linear_its;
    rep.max_linear_iterations = std::max(rep.max_linear_iterations, linear_its);
    if constexpr (SteerableKrylovSolver<Linear>) {
      const double decades = -std::log10(std::clamp(linear_.last_residual(), 1e-16, 0.5));
      rate_ = linear_its / decades;
      if (fresh_rate_ < 0) fresh_rate_ = std::max(rate_, 1.0);
    }
    return dx;
  }

  // A direction from a direct policy (analysed once per structure).
  template <class System>
  Eigen::VectorXd direct_direction(System& sys, const Eigen::VectorXd& R, SolveReport& rep) {
    const int n = sys.size();
    auto t0 = clock::now();
    if (sys.structure_generation() != analyzed_generation_ || analyzed_size_ != n) {
      linear_.analyze(A_);
      analyzed_generation_ = sys.structure_generation();
      analyzed_size_ = n;
    }
    linear_.factorize(A_);
    rep.factorization_seconds += seconds(t0);
    t0 = clock::now();
    Eigen::VectorXd dx = linear_.solve(-R);
    rep.solve_seconds += seconds(t0);
    return dx;
  }

  // Backtracking (halving) on |R| with sufficient decrease; 0 when no step of
  // the line search decreases it.
  template <class System>
  double line_search(System& sys, const Eigen::VectorXd& X, const Eigen::VectorXd& R,
                     const Eigen::VectorXd& dx, SolveReport& rep) {
    const double phi0 = R.norm();
    double step = 1.0;
    for (int ls = 0; ls <= prm_.line_search; ++ls, step *= 0.5) {
      Xtry_ = X + step * dx;
      const auto t0 = clock::now();
      sys.residual(Xtry_, Rtry_);
      rep.assembly_seconds += seconds(t0);
      if (Rtry_.norm() <= (1.0 - 1e-4 * step) * phi0) return step;
    }
    return 0.0;
  }

  void log_iteration(int it, Linearization kind, double res, double increment, double step, int linear_its) const {
    if (!prm_.log) return;
    char line[128];
    std::snprintf(line, sizeof line, "  %3d %-6s residual %.3e  increment %.3e  step %.3g  linear its %d\n", it,
                  kind == Linearization::picard ? "picard" : "newton", res, increment, step, linear_its);
    *prm_.log << line;
  }

  // Iterations without a kept LU go matrix-free (matrix_free_krylov).
  template <class System>
  bool matrix_free_krylov() const {
    if constexpr (MatrixFreeKrylovSolver<Linear> && MatrixFreePicardSystem<System> &&
                  PreconditionedSystem<System>)
      return prm_.matrix_free_krylov;
    else
      return false;
  }

  // The system says its matrix of this kind is symmetric (SymmetricSystem),
  // and symmetric_lu lets the kept LUs use that.
  template <class System>
  bool symmetric_matrix(System& sys, Linearization kind) const {
    if constexpr (SymmetricSystem<System>)
      return prm_.symmetric_lu && sys.symmetric(kind);
    else
      return false;
  }

  // Newton's kept LU is the L D L^T of the system's newton_symmetric matrix
  // (symmetric_lu, where the policy has symmetric kept LUs and the system
  // that matrix).
  template <class System>
  bool symmetric_newton_lu(System& sys) const {
    if constexpr (requires { Linear::symmetric_kept; })
      return Linear::symmetric_kept && symmetric_matrix(sys, Linearization::newton_symmetric);
    else
      return false;
  }

  // Newton with the kept LU applies (KeptLuLinearSolver, LayoutKeyedSystem, size).
  template <class System>
  bool use_kept_lu(System& sys, int n) {
    if constexpr (KeptLuLinearSolver<Linear> && LayoutKeyedSystem<System>) {
      // Every iteration: a direct fallback of a Picard solve also keeps its LU.
      linear_.set_layout(sys.layout());
      picard_linear_.set_layout(sys.layout());
      return prm_.kept_lu && n <= prm_.kept_lu_max_unknowns;
    } else {
      return false;
    }
  }
  // The kept LU can serve this iteration without a new factorization.
  bool kept_lu_current(const Linear& L, int n) const {
    if constexpr (KeptLuLinearSolver<Linear>)
      return prm_.preconditioner_refresh > 0 && L.kept_usable(n);
    else
      return false;
  }

  // One direction: GMRES on J dx = -R, preconditioned by the kept LU of
  // this kind (made from the matrix assembled at X when there is none for
  // this layout, or when it no longer brings GMRES below the tolerance in
  // kept_lu_iterations). GMRES applies A_ where this iteration assembled
  // it, else the system's matrix-free product of this kind.
  template <class System>
  Eigen::VectorXd kept_lu_direction(System& sys, const Eigen::VectorXd& X, const Eigen::VectorXd& R,
                                    double res, Linearization kind, bool assembled, SolveReport& rep,
                                    int& linear_its) {
    const int n = sys.size();
    const bool newton = kind == Linearization::newton;
    Linear& L = newton ? linear_ : picard_linear_;
    KeptLuState& st = newton ? newton_lu_ : picard_lu_;
    // full: of Newton's whole tangent even where its LU is of newton_symmetric's matrix.
    auto refactor = [&](const char* why, bool exact = false, bool full = false) {
      if (prm_.log) *prm_.log << "  kept " << (newton ? "newton" : "picard") << " LU made: " << why << "\n";
      auto t0 = clock::now();
      const bool symmetric_newton = newton && !full && symmetric_newton_lu(sys);
      Eigen::VectorXd R2;
      if (symmetric_newton) {
        if (!symmetric_assembled_) sys.assemble(X, Linearization::newton_symmetric, S_, R2);
        symmetric_assembled_ = false;  // factorized
      } else if (!assembled) {
        sys.assemble(X, kind, A_, R2);
        assembled = true;
      }
      rep.assembly_seconds += seconds(t0);
      t0 = clock::now();
      const Matrix& M = symmetric_newton ? S_ : A_;
      if constexpr (requires { L.factorize_kept(M, true, true); })
        L.factorize_kept(M, exact, symmetric_newton || symmetric_matrix(sys, kind));
      else if constexpr (requires { L.factorize_kept(M, true); })
        L.factorize_kept(M, exact);
      else
        L.factorize_kept(M);
      rep.factorization_seconds += seconds(t0);
      ++rep.preconditioner_updates;
      st.made_this_solve = true;
    };
    bool fresh = false;
    const bool carried = !st.made_this_solve;
    if (!kept_lu_current(L, n)) {
      refactor(L.kept_factorizations() == 0 ? "first" : "layout");
      fresh = true;
    } else if (carried && st.skip_carry > 0) {
      refactor("carried LU failed recently");
      fresh = true;
    } else if (st.excess >= prm_.kept_lu_aged_iterations) {
      refactor("aged");
      fresh = true;
    }
    const double eta = std::max(res, 0.5 * prm_.residual_tol / std::max(res, 1e-300));
    const double cap = newton ? std::min(prm_.eta_max, prm_.eta_kept_lu) : prm_.eta_picard_warm;
    L.set_tolerance(std::clamp(eta, prm_.eta_min, cap));
    // The assembled matrix where this iteration has it (a sparse product is
    // cheaper than a matrix-free one), else the system's matrix-free product.
    auto op = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
      if (assembled) {
        column_product(A_, v, Av_, product_part_);
        return Av_;
      }
      if constexpr (MatrixFreePicardSystem<System>)
        sys.apply_tangent(X, v, Jv_, kind);
      else
        sys.apply_tangent(X, v, Jv_);
      return Jv_;
    };
    const int max_its = prm_.kept_lu_iterations;
    auto t0 = clock::now();
    Eigen::VectorXd dx = L.solve_kept(op, -R, max_its);
    linear_its = L.last_iterations();
    if (!L.converged() && !fresh) {
      rep.solve_seconds += seconds(t0);
      if (carried) st.skip_carry = prm_.kept_lu_skip_carry + 1;  // counted down at each solve's start
      refactor("slow GMRES");
      fresh = true;
      t0 = clock::now();
      dx = L.solve_kept(op, -R, max_its);
      linear_its += L.last_iterations();
    }
    // A fresh LU of this very matrix that leaves GMRES short: its
    // single-precision factors are (an ill-conditioned matrix), not its age.
    if constexpr (requires { Linear::single_precision_kept; }) {
      if (Linear::single_precision_kept && !L.converged()) {
        rep.solve_seconds += seconds(t0);
        refactor("single precision short", true);
        t0 = clock::now();
        dx = L.solve_kept(op, -R, max_its);
        linear_its += L.last_iterations();
      }
    }
    // A fresh double-precision LU of newton_symmetric's matrix that leaves
    // GMRES short: d tau / d v, which that matrix leaves out, is no longer
    // small (seen on E3 next to the tool's tip, where the direction then
    // failed its line search step after step). The LU of the whole tangent.
    if (newton && !L.converged() && symmetric_newton_lu(sys)) {
      rep.solve_seconds += seconds(t0);
      refactor("symmetric part short", true, true);
      fresh = true;
      t0 = clock::now();
      dx = L.solve_kept(op, -R, max_its);
      linear_its += L.last_iterations();
    }
    // The LU's age: iterations beyond those of its first solve.
    if (fresh) {
      st.fresh_its = L.last_iterations();
      st.excess = 0;
    } else {
      st.excess += std::max(0, L.last_iterations() - st.fresh_its);
    }
    rep.solve_seconds += seconds(t0);
    rep.linear_iterations += linear_its;
    rep.max_linear_iterations = std::max(rep.max_linear_iterations, linear_its);
    return dx;
  }

  params prm_;
  Linear linear_;
  Linear picard_linear_;  // holds the kept Picard LU (kept_lu_picard)
  Matrix A_, P_, S_;  // S_: newton_symmetric's matrix, for the kept LU
  bool symmetric_assembled_ = false;  // S_ is at this iteration's X, not yet factorized
  Eigen::VectorXd Jv_, Av_, Xtry_, Rtry_;
  Eigen::MatrixXd product_part_;  // column_product's storage
  long analyzed_generation_ = -1;
  int analyzed_size_ = -1;
  int picard_since_switch_ = 0;
  bool warm_start_ = false;  // this solve's X came in with a velocity
  // A kept LU's history: made in the current solve(); solves left that make
  // their own at once; its first solve's iterations and the excess since.
  struct KeptLuState {
    bool made_this_solve = false;
    int skip_carry = 0, fresh_its = 0, excess = 0;
  };
  KeptLuState newton_lu_, picard_lu_;
  double rate_ = 0.0, fresh_rate_ = -1.0;  // Krylov iterations per decade: last, after the last refresh
};

}  // namespace maxentflow

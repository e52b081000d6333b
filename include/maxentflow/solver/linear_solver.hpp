// maxentflow: sparse direct solvers for the saddle system (21), as policies.
#pragma once

#include <concepts>
#include <string>

#include <Eigen/SparseCore>
#include <Eigen/UmfPackSupport>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

/// A linear-solver policy: analyze a structure once, factorize new values of
/// that structure many times, solve.
template <class S>
concept LinearSolver = requires(S& s, const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& A,
                                const Eigen::VectorXd& b) {
  s.analyze(A);
  s.factorize(A);
  { s.solve(b) } -> std::convertible_to<Eigen::VectorXd>;
};

/// UMFPACK (SuiteSparse) LU through Eigen: the system is indefinite and, with
/// the Newton tau term, unsymmetric. The symbolic analysis (column ordering)
/// is kept until analyze() is called again with a new structure.
class UmfpackSolver {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  void analyze(const Matrix& A) {
    lu_.analyzePattern(A);
    require(lu_.info() == Eigen::Success, "UMFPACK symbolic analysis failed", "UmfpackSolver::analyze");
  }
  void factorize(const Matrix& A) {
    lu_.factorize(A);
    if (lu_.info() == Eigen::Success) return;
    const int status = lu_.umfpackFactorizeReturncode();
    const char* why = status == UMFPACK_WARNING_singular_matrix
                          ? "the system is singular, e.g. a rigid-body mode is not constrained or a "
                            "constraint is given twice"
                      : status == UMFPACK_ERROR_out_of_memory
                          ? "out of memory (the LU factors do not fit; fewer nodes or a larger tol0)"
                          : "UMFPACK error";
    throw Error(detail::cat("UMFPACK factorization failed (status ", status, "): ", why, "; ",
                            A.rows(), " unknowns, ", A.nonZeros(), " nonzeros"),
                "UmfpackSolver::factorize");
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const {
    Eigen::VectorXd x = lu_.solve(b);
    require(lu_.info() == Eigen::Success, "UMFPACK solve failed", "UmfpackSolver::solve");
    return x;
  }
  static constexpr const char* name() { return "UMFPACK"; }
  /// Iterative-refinement steps per solve (UMFPACK's default: up to 2, each a
  /// product with A and a pair of triangular solves). A preconditioner needs none.
  void set_refinement_steps(int steps) { lu_.umfpackControl()(UMFPACK_IRSTEP) = steps; }
  void control(int strategy, int ordering) {
    if (strategy >= 0) lu_.umfpackControl()(UMFPACK_STRATEGY) = strategy;
    if (ordering >= 0) lu_.umfpackControl()(UMFPACK_ORDERING) = ordering;
  }

 private:
  Eigen::UmfPackLU<Matrix> lu_;
};

static_assert(LinearSolver<UmfpackSolver>);

}  // namespace maxentflow

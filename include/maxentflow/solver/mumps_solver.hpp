// maxentflow: MUMPS (sequential, Debian libmumps-seq-dev) sparse LU as a
// LinearSolver policy, and DirectSolver: MUMPS where the build has it
// (MAXENTFLOW_HAVE_MUMPS, set by CMake), UMFPACK otherwise.
#pragma once

#include <maxentflow/solver/linear_solver.hpp>

#ifdef MAXENTFLOW_HAVE_MUMPS

#include <cstdint>
#include <memory>
#include <vector>

#include <dmumps_c.h>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

/// MUMPS multifrontal LU (unsymmetric, centralized input). Why next to
/// UMFPACK: the kept LU of Newton's max-ent tangent (~85 nodes per row) is
/// dense-ish (fronts of 500-1700 rows), where MUMPS's dense kernels run
/// 2-2.7x faster than UMFPACK's (E2 tangent, 1k and 4k nodes: 0.13 / 0.95 s
/// against 0.35 / 2.0 s; docs/method.md section 8).
class MumpsSolver {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  MumpsSolver() : id_(std::make_unique<DMUMPS_STRUC_C>()) {
    id_->comm_fortran = -987654;  // MUMPS's "no MPI communicator" (sequential library)
    id_->par = 1;
    id_->sym = 0;
    call(-1, "initialization");
    id_->icntl[0] = id_->icntl[1] = id_->icntl[2] = -1;  // no output
    id_->icntl[3] = 0;
  }
  MumpsSolver(MumpsSolver&&) noexcept = default;
  MumpsSolver& operator=(MumpsSolver&& o) noexcept {
    end();
    id_ = std::move(o.id_);
    irn_ = std::move(o.irn_), jcn_ = std::move(o.jcn_), a_ = std::move(o.a_);
    factorized_ = o.factorized_;
    return *this;
  }
  MumpsSolver(const MumpsSolver&) = delete;
  MumpsSolver& operator=(const MumpsSolver&) = delete;
  ~MumpsSolver() { end(); }

  /// Symbolic analysis (ordering) of A's pattern.
  void analyze(const Matrix& A) {
    const char* where = "MumpsSolver::analyze";
    require(A.rows() == A.cols() && A.rows() > 0, detail::cat("A is ", A.rows(), " x ", A.cols()), where);
    require(A.isCompressed(), "A must be compressed", where);
    irn_.resize(static_cast<std::size_t>(A.nonZeros()));
    jcn_.resize(irn_.size());
    for (int j = 0; j < A.outerSize(); ++j)
      for (int k = A.outerIndexPtr()[j]; k < A.outerIndexPtr()[j + 1]; ++k) {
        irn_[static_cast<std::size_t>(k)] = A.innerIndexPtr()[k] + 1;
        jcn_[static_cast<std::size_t>(k)] = j + 1;
      }
    a_.assign(A.valuePtr(), A.valuePtr() + A.nonZeros());
    id_->n = static_cast<MUMPS_INT>(A.rows());
    id_->nnz = static_cast<MUMPS_INT8>(A.nonZeros());
    id_->irn = irn_.data();
    id_->jcn = jcn_.data();
    id_->a = a_.data();
    factorized_ = false;
    call(1, "analysis");
  }
  /// Numerical LU of A (the pattern analyze() saw).
  void factorize(const Matrix& A) {
    const char* where = "MumpsSolver::factorize";
    require(A.rows() == id_->n && static_cast<std::size_t>(A.nonZeros()) == a_.size(),
            detail::cat("A (", A.rows(), " unknowns, ", A.nonZeros(), " nonzeros) has not the analysed pattern (",
                        id_->n, ", ", a_.size(), ")"),
            where);
    a_.assign(A.valuePtr(), A.valuePtr() + A.nonZeros());
    id_->a = a_.data();
    factorized_ = false;
    // The workspace MUMPS estimates in the analysis can fall short when
    // pivoting delays eliminations (the saddle system's multiplier rows):
    // more room, a few times, before giving up.
    for (int relax = 20;; relax *= 2) {
      id_->icntl[13] = relax;  // ICNTL(14): workspace relaxation, per cent
      id_->job = 2;
      dmumps_c(id_.get());
      const int info = id_->infog[0];
      if (info >= 0) break;
      const bool room = info == -8 || info == -9 || info == -14 || info == -15 || info == -17 || info == -20;
      if (!room || relax >= 640) throw_error("factorization", info);
    }
    factorized_ = true;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const {
    require(factorized_ && b.size() == id_->n, "no factorization of this size", "MumpsSolver::solve");
    Eigen::VectorXd x = b;
    id_->rhs = x.data();
    id_->nrhs = 1;
    id_->lrhs = id_->n;
    call(3, "solve");
    return x;
  }
  static constexpr const char* name() { return "MUMPS"; }

 private:
  void call(int job, const char* what) const {
    id_->job = job;
    dmumps_c(id_.get());
    if (id_->infog[0] < 0) throw_error(what, id_->infog[0]);
  }
  [[noreturn]] void throw_error(const char* what, int info) const {
    const char* why = info == -10 || info == -6 ? "the system is singular, e.g. a rigid-body mode is not "
                                                  "constrained or a constraint is given twice"
                      : info == -13 || info == -5 ? "out of memory (the LU factors do not fit; fewer nodes or a "
                                                    "larger tol0)"
                                                  : "MUMPS error (see the MUMPS users' guide, INFOG(1))";
    throw Error(detail::cat("MUMPS ", what, " failed (INFOG(1) = ", info, ", INFOG(2) = ", id_->infog[1], "): ",
                            why, "; ", id_->n, " unknowns, ", a_.size(), " nonzeros"),
                "MumpsSolver");
  }
  void end() noexcept {
    if (!id_) return;
    id_->job = -2;
    dmumps_c(id_.get());
    id_.reset();
  }

  // MUMPS writes to its structure in every call, solves included.
  std::unique_ptr<DMUMPS_STRUC_C> id_;
  std::vector<MUMPS_INT> irn_, jcn_;  // 1-based coordinates of A's pattern
  std::vector<double> a_;
  bool factorized_ = false;
};

static_assert(LinearSolver<MumpsSolver>);

/// The direct LU the Krylov policy keeps (GmresSolver's kept LU and fallback).
using DirectSolver = MumpsSolver;

}  // namespace maxentflow

#else

namespace maxentflow {
/// The direct LU the Krylov policy keeps (built without MUMPS: UMFPACK).
using DirectSolver = UmfpackSolver;
}  // namespace maxentflow

#endif

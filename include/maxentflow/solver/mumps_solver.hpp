// maxentflow: MUMPS (sequential, Debian libmumps-seq-dev) sparse LU as a
// LinearSolver policy, and DirectSolver: MUMPS where the build has it
// (MAXENTFLOW_HAVE_MUMPS, set by CMake), UMFPACK otherwise.
#pragma once

#include <maxentflow/solver/linear_solver.hpp>

#ifdef MAXENTFLOW_HAVE_MUMPS

#include <cstdint>
#include <memory>
#include <type_traits>
#include <vector>

#include <dmumps_c.h>
#include <smumps_c.h>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

namespace detail {
template <class Scalar>
struct Mumps;
template <>
struct Mumps<double> {
  using Struc = DMUMPS_STRUC_C;
  static void call(Struc* id) { dmumps_c(id); }
};
template <>
struct Mumps<float> {
  using Struc = SMUMPS_STRUC_C;
  static void call(Struc* id) { smumps_c(id); }
};
}  // namespace detail

/// MUMPS multifrontal LU (unsymmetric, centralized input) with factors in
/// `Scalar` (double: dmumps, float: smumps); A, b and x stay double. Why next
/// to UMFPACK: the kept LU of Newton's max-ent tangent (~85 nodes per row) is
/// dense-ish (fronts of 500-1700 rows), where MUMPS's dense kernels run
/// 2-2.7x faster than UMFPACK's (E2 tangent, 1k and 4k nodes: 0.13 / 0.95 s
/// against 0.35 / 2.0 s; docs/method.md section 8). Single-precision factors
/// halve the memory traffic of the factorization and of each solve (another
/// 1.8-2x); they are a preconditioner, not a direct solver: x solves A x = b
/// only to about cond(A) * 6e-8 (GmresSolver refines them).
template <class Scalar = double>
class BasicMumpsSolver {
  static_assert(std::is_same_v<Scalar, double> || std::is_same_v<Scalar, float>,
                "MUMPS factors in double or float");
  using Api = detail::Mumps<Scalar>;

 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  /// True when solve() is exact to round-off in double precision.
  static constexpr bool exact = std::is_same_v<Scalar, double>;

  BasicMumpsSolver() { init(); }
  BasicMumpsSolver(BasicMumpsSolver&&) noexcept = default;
  BasicMumpsSolver& operator=(BasicMumpsSolver&& o) noexcept {
    end();
    id_ = std::move(o.id_);
    irn_ = std::move(o.irn_), jcn_ = std::move(o.jcn_), a_ = std::move(o.a_);
    take_ = std::move(o.take_);
    rhs_ = std::move(o.rhs_);
    full_nnz_ = o.full_nnz_;
    symmetric_ = o.symmetric_;
    factorized_ = o.factorized_;
    return *this;
  }

  /// From the next analyze() on: A is symmetric (to round-off), and is
  /// factorized as L D L^T (MUMPS SYM = 2, symmetric indefinite: 2 x 2
  /// pivots for the saddle system's zero diagonal) from its lower triangle,
  /// in about half the flops and factor memory of an LU (a Picard matrix:
  /// docs/method.md section 8).
  void set_symmetric(bool symmetric) {
    if (symmetric == symmetric_) return;
    symmetric_ = symmetric;
    end();
    init();
  }
  bool symmetric() const { return symmetric_; }
  BasicMumpsSolver(const BasicMumpsSolver&) = delete;
  BasicMumpsSolver& operator=(const BasicMumpsSolver&) = delete;
  ~BasicMumpsSolver() { end(); }

  /// Symbolic analysis (ordering) of A's pattern.
  void analyze(const Matrix& A) {
    const char* where = "MumpsSolver::analyze";
    require(A.rows() == A.cols() && A.rows() > 0, detail::cat("A is ", A.rows(), " x ", A.cols()), where);
    require(A.isCompressed(), "A must be compressed", where);
    // The entries MUMPS reads: all, or the lower triangle (it would sum a
    // symmetric matrix's (i, j) and (j, i)).
    irn_.clear();
    jcn_.clear();
    take_.clear();
    for (int j = 0; j < A.outerSize(); ++j)
      for (int k = A.outerIndexPtr()[j]; k < A.outerIndexPtr()[j + 1]; ++k)
        if (!symmetric_ || A.innerIndexPtr()[k] >= j) {
          irn_.push_back(A.innerIndexPtr()[k] + 1);
          jcn_.push_back(j + 1);
          take_.push_back(k);
        }
    full_nnz_ = A.nonZeros();
    // ICNTL(7): AMD up to amd_max_unknowns, MUMPS's own choice above. On
    // max-ent systems of 4k-5k nodes (12k-15k unknowns) AMD gives the same
    // fill and factorization time as the nested dissection MUMPS picks
    // there, in half the analysis time (0.15 s against 0.26-0.34 s; the
    // analysis is a quarter to a third of each kept LU's cost).
    id_->icntl[6] = A.rows() <= amd_max_unknowns ? 0 : 7;
    id_->n = static_cast<MUMPS_INT>(A.rows());
    id_->nnz = static_cast<MUMPS_INT8>(take_.size());
    id_->irn = irn_.data();
    id_->jcn = jcn_.data();
    a_.resize(take_.size());
    gather_values(A);  // the analysis may scale by the values
    id_->a = a_.data();
    factorized_ = false;
    call(1, "analysis");
  }
  /// Numerical LU of A (the pattern analyze() saw).
  void factorize(const Matrix& A) {
    if (const int info = try_factorize(A); info < 0) throw_error("factorization", info);
  }
  /// factorize(), but a numerically singular matrix (INFOG(1) = -10 or -6,
  /// e.g. single-precision pivots too small) returns that code instead of
  /// throwing; other failures throw. 0 on success.
  int try_factorize(const Matrix& A) {
    const char* where = "MumpsSolver::factorize";
    require(A.isCompressed() && same_pattern(A),
            detail::cat("A (", A.rows(), " unknowns, ", A.nonZeros(), " nonzeros) has not the analysed pattern (",
                        id_->n, " unknowns, ", full_nnz_, " nonzeros)"),
            where);
    gather_values(A);
    id_->a = a_.data();
    factorized_ = false;
    // The workspace MUMPS estimates in the analysis can fall short when
    // pivoting delays eliminations (the saddle system's multiplier rows):
    // more room, a few times, before giving up.
    for (int relax = 20;; relax *= 2) {
      id_->icntl[13] = relax;  // ICNTL(14): workspace relaxation, per cent
      id_->job = 2;
      Api::call(id_.get());
      const int info = id_->infog[0];
      if (info >= 0) break;
      if (info == -10 || info == -6) return info;
      const bool room = info == -8 || info == -9 || info == -14 || info == -15 || info == -17 || info == -20;
      if (!room || relax >= 640) throw_error("factorization", info);
    }
    factorized_ = true;
    return 0;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const {
    require(factorized_ && b.size() == id_->n, "no factorization of this size", "MumpsSolver::solve");
    rhs_ = b.template cast<Scalar>();
    id_->rhs = rhs_.data();
    id_->nrhs = 1;
    id_->lrhs = id_->n;
    call(3, "solve");
    return rhs_.template cast<double>();
  }
  static constexpr const char* name() { return exact ? "MUMPS" : "MUMPS (single-precision factors)"; }
  /// Systems up to this size are ordered by AMD (see analyze()).
  static constexpr Eigen::Index amd_max_unknowns = 30000;

 private:
  void init() {
    id_ = std::make_unique<typename Api::Struc>();
    id_->comm_fortran = -987654;  // MUMPS's "no MPI communicator" (sequential library)
    id_->par = 1;
    id_->sym = symmetric_ ? 2 : 0;
    call(-1, "initialization");
    id_->icntl[0] = id_->icntl[1] = id_->icntl[2] = -1;  // no output
    id_->icntl[3] = 0;
    factorized_ = false;
  }
  void gather_values(const Matrix& A) {
    for (std::size_t i = 0; i < take_.size(); ++i) a_[i] = static_cast<Scalar>(A.valuePtr()[take_[i]]);
  }
  // A's pattern is the analysed one (same size, nonzeros, row indices per column).
  bool same_pattern(const Matrix& A) const {
    if (A.rows() != id_->n || A.cols() != id_->n || A.nonZeros() != full_nnz_) return false;
    std::size_t i = 0;
    for (int j = 0; j < A.outerSize(); ++j)
      for (int k = A.outerIndexPtr()[j]; k < A.outerIndexPtr()[j + 1]; ++k) {
        if (symmetric_ && A.innerIndexPtr()[k] < j) continue;
        if (i >= take_.size() || take_[i] != k || jcn_[i] != j + 1 || irn_[i] != A.innerIndexPtr()[k] + 1)
          return false;
        ++i;
      }
    return i == take_.size();
  }
  void call(int job, const char* what) const {
    id_->job = job;
    Api::call(id_.get());
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
    Api::call(id_.get());
    id_.reset();
  }

  // MUMPS writes to its structure in every call, solves included.
  std::unique_ptr<typename Api::Struc> id_;
  std::vector<MUMPS_INT> irn_, jcn_;  // 1-based coordinates of the entries MUMPS reads
  std::vector<Scalar> a_;
  std::vector<int> take_;  // their positions in A's values
  Eigen::Index full_nnz_ = 0;
  mutable Vector rhs_;
  bool symmetric_ = false, factorized_ = false;
};

using MumpsSolver = BasicMumpsSolver<double>;
static_assert(LinearSolver<MumpsSolver>);
static_assert(LinearSolver<BasicMumpsSolver<float>>);

/// An LU for a preconditioner: single-precision factors, or double ones
/// after set_exact(true). GmresSolver asks for double only where a fresh
/// single-precision LU of the very matrix it solves did not bring GMRES to
/// its tolerance (precision, not age, was short): on E2 the float factors
/// serve every solve with the same GMRES iterations, though a raw solve
/// with them leaves backward errors up to ~1 where the matrix is
/// ill-conditioned (GMRES absorbs those few directions).
class MixedMumpsSolver {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  void analyze(const Matrix& A) {
    single_.analyze(A);
    double_analyzed_ = false;
  }
  void factorize(const Matrix& A) {
    use_double_ = false;
    // Single-precision pivots can vanish where the double ones do not (a
    // matrix whose entries span more than float's range of precision, e.g.
    // sticking contact next to a dead zone at the viscosity's cap): double
    // then, for this matrix.
    if (!exact_ && single_.try_factorize(A) == 0) return;
    if (!exact_) ++singular_single_;
    if (!double_analyzed_) double_.analyze(A);
    double_analyzed_ = true;
    double_.factorize(A);
    use_double_ = true;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const { return use_double_ ? double_.solve(b) : single_.solve(b); }
  /// Double-precision factors from the next factorize() on (until set_exact(false)).
  void set_exact(bool exact) { exact_ = exact; }
  /// L D L^T from the next analyze() on (BasicMumpsSolver::set_symmetric).
  void set_symmetric(bool symmetric) {
    single_.set_symmetric(symmetric);
    double_.set_symmetric(symmetric);
    double_analyzed_ = false;
  }
  /// The factors in use are double precision.
  bool exact() const { return use_double_; }
  /// Factorizations made in double precision because the single-precision
  /// one found the matrix numerically singular.
  int singular_single() const { return singular_single_; }
  static constexpr const char* name() { return "MUMPS (single-precision factors, double on request)"; }

 private:
  BasicMumpsSolver<float> single_;
  BasicMumpsSolver<double> double_;
  bool exact_ = false, double_analyzed_ = false, use_double_ = false;
  int singular_single_ = 0;
};

static_assert(LinearSolver<MixedMumpsSolver>);

/// The direct LU (exact to round-off).
using DirectSolver = MumpsSolver;
/// The LU GmresSolver keeps as Newton's preconditioner and for its direct
/// fallback (which GMRES refines to the solve's tolerance).
using KeptLuSolver = MixedMumpsSolver;
/// The LU of GmresSolver's linear-triangle companion (L D L^T, the
/// companion being a Picard matrix): single-precision
/// factors, as the companion is itself only an approximation of the max-ent
/// system (bench_flow 1k-16k: the same GMRES iterations as double factors;
/// at 16k factorization 2.1 -> 1.1 s, peak 630 -> 582 MB). Measured: at
/// ~50k unknowns MUMPS's single-precision factorization is not bitwise the
/// same from run to run, also with OpenBLAS and MUMPS on one thread
/// (bench_flow 16k: 902-916 GMRES iterations, final residuals 3e-10..2e-9,
/// forces equal to 6 digits); its double-precision one is (at 4k nodes both
/// are). GmresSolver<DirectSolver> keeps such runs bitwise reproducible.
using CompanionLuSolver = BasicMumpsSolver<float>;

}  // namespace maxentflow

#else

namespace maxentflow {
/// The direct LU and the LUs the Krylov policy keeps (built without MUMPS: UMFPACK).
using DirectSolver = UmfpackSolver;
using KeptLuSolver = UmfpackSolver;
using CompanionLuSolver = UmfpackSolver;
}  // namespace maxentflow

#endif

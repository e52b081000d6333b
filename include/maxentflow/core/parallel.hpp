// maxentflow: thread control for the OpenMP loops (serial without OpenMP),
// and the parallel sparse product the Krylov solves use.
#pragma once

#include <algorithm>
#include <array>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#if defined(_OPENMP)
#include <omp.h>
#endif
#if __has_include(<dlfcn.h>)
#include <dlfcn.h>
#endif

namespace maxentflow {

/// Threads the parallel loops use (1 without OpenMP).
inline int max_threads() {
#if defined(_OPENMP)
  return omp_get_max_threads();
#else
  return 1;
#endif
}

/// Sets the thread count of later parallel loops (ignored without OpenMP).
inline void set_threads(int n) {
#if defined(_OPENMP)
  omp_set_num_threads(n > 0 ? n : 1);
#else
  (void)n;
#endif
}

/// Sets the thread count of the BLAS under the sparse LUs where that BLAS is
/// OpenBLAS (looked up at run time: no link dependency); false where there
/// is none to set. A forming run wants 1: its LUs are of a few thousand
/// nodes, whose fronts gain nothing from BLAS threads (E3, 70 steps: 26 s of
/// factorization on 2 threads, 31 s on 1), while the threads of OpenBLAS's
/// pthread build spin after each call and take the cores from the OpenMP
/// loops around it (E3: 111 s with 67 s of system time, against 90 s and 3 s
/// on one BLAS thread; docs/method.md section 8).
inline bool set_blas_threads(int n) {
#if __has_include(<dlfcn.h>)
  using Setter = void (*)(int);
  if (void* f = dlsym(RTLD_DEFAULT, "openblas_set_num_threads")) {
    reinterpret_cast<Setter>(f)(n > 0 ? n : 1);
    return true;
  }
#endif
  (void)n;
  return false;
}

/// This thread's number inside a parallel region (0 outside or without OpenMP).
inline int thread_id() {
#if defined(_OPENMP)
  return omp_get_thread_num();
#else
  return 0;
#endif
}

/// Threads in the current parallel region (1 outside or without OpenMP).
inline int team_size() {
#if defined(_OPENMP)
  return omp_get_num_threads();
#else
  return 1;
#endif
}

/// y = A v for a column-major sparse A, in parallel, with the same result for
/// any thread count: the columns are cut into `column_product_chunks` ranges
/// of about equal nonzeros, each range's product goes to its own column of
/// `part` (n x chunks, reused storage), and the columns are added in order.
/// Eigen runs only row-major products in parallel, and a row-major copy of
/// a wide max-ent matrix would hold as much memory as the matrix itself.
inline constexpr int column_product_chunks = 4;
template <class Scalar, class StorageIndex>
void column_product(const Eigen::SparseMatrix<Scalar, Eigen::ColMajor, StorageIndex>& A,
                    const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v, Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& y,
                    Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>& part) {
  using Index = Eigen::Index;
  constexpr int K = column_product_chunks;
  const Index n = A.rows(), m = A.cols();
  std::array<Index, K + 1> first{};
  first[K] = m;
  for (int k = 1; k < K; ++k) {
    if (A.isCompressed()) {
      const StorageIndex* outer = A.outerIndexPtr();
      const auto target = static_cast<StorageIndex>(static_cast<double>(A.nonZeros()) * k / K);
      first[static_cast<std::size_t>(k)] = std::lower_bound(outer, outer + m + 1, target) - outer;
    } else {
      first[static_cast<std::size_t>(k)] = m * k / K;
    }
    first[static_cast<std::size_t>(k)] =
        std::clamp(first[static_cast<std::size_t>(k)], first[static_cast<std::size_t>(k) - 1], m);
  }
  part.resize(n, K);
#pragma omp parallel for schedule(static)
  for (int k = 0; k < K; ++k) {
    auto out = part.col(k);
    out.setZero();
    for (Index j = first[static_cast<std::size_t>(k)]; j < first[static_cast<std::size_t>(k) + 1]; ++j) {
      const Scalar vj = v[j];
      for (typename Eigen::SparseMatrix<Scalar, Eigen::ColMajor, StorageIndex>::InnerIterator it(A, j); it; ++it)
        out[it.row()] += it.value() * vj;
    }
  }
  y.resize(n);
#pragma omp parallel for schedule(static)
  for (Index i = 0; i < n; ++i) {
    Scalar s = part(i, 0);
    for (int k = 1; k < K; ++k) s += part(i, k);
    y[i] = s;
  }
}

}  // namespace maxentflow

// maxentflow: one-column matrix products (xGEMM with N = 1) handed to the
// BLAS's matrix-vector product (xGEMV), and one-column triangular solves
// (xTRSM) to xTRSV, for the sparse LUs' solves.
//
// Include this header in exactly one translation unit of a program (its
// main.cpp, as the examples and benchmarks do); maxentflow.hpp does not
// include it. It defines sgemm_, dgemm_, strsm_ and dtrsm_, which take the
// place of the BLAS's own for the whole program (the dynamic linker binds
// the sparse solvers' calls to the program's definition first) and pass
// every other call on to the BLAS's.
//
// Why: MUMPS, as Debian builds it (without MUMPS_USE_BLAS2), solves with one
// right-hand side through xGEMM and xTRSM with N = 1, and OpenBLAS before
// 0.3.27 packs each panel of the factors into a buffer before its kernel
// reads it: 2.5 times the kernel's own time. A GMRES iteration on E3 (5k
// nodes, ~11.5M single-precision factor entries) costs 7.1 ms with this
// header against 11.1 ms without; a solve with the linear-triangle
// companion's factors at 16k nodes 9.7 ms against 10.5 ms with the GEMM
// forwarding alone (docs/method.md, section 8). Results are those of GEMV
// and TRSV, equal to GEMM's and TRSM's up to the order of the sums.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdio>
#include <cstdlib>

#if !__has_include(<dlfcn.h>)
#error "blas_gemv_forward.hpp needs <dlfcn.h> (dlsym) to find the BLAS's own GEMM"
#endif
#include <dlfcn.h>

namespace maxentflow {
namespace detail {

template <class T>
using Gemm = void (*)(const char*, const char*, const int*, const int*, const int*, const T*,
                      const T*, const int*, const T*, const int*, const T*, T*, const int*,
                      std::size_t, std::size_t);
template <class T>
using Gemv = void (*)(const char*, const int*, const int*, const T*, const T*, const int*, const T*,
                      const int*, const T*, T*, const int*, std::size_t);

inline std::atomic<long long>& gemv_forwards() {
  static std::atomic<long long> count{0};
  return count;
}

// The BLAS's own routine `name`: the next definition after this program's
// (RTLD_NEXT) for GEMM, any for GEMV. Without one no product can be made:
// the program stops with the loader's reason (a BLAS routine has no way to
// report an error to its Fortran caller).
inline void* blas_routine(void* handle, const char* name) {
  void* f = dlsym(handle, name);
  if (f == nullptr) {
    std::fprintf(stderr, "maxentflow (blas_gemv_forward.hpp): no BLAS %s in this program: %s\n",
                 name, dlerror());
    std::abort();
  }
  return f;
}

// C = alpha op(A) B + beta C with B and C one column: C = alpha op(A) b +
// beta C by GEMV (op(A) m x k; b B's column, or B's row where B is given
// transposed). Other shapes go to the BLAS's GEMM.
template <class T>
void gemm_or_gemv(Gemm<T> gemm, Gemv<T> gemv, const char* ta, const char* tb, const int* m,
                  const int* n, const int* k, const T* alpha, const T* a, const int* lda,
                  const T* b, const int* ldb, const T* beta, T* c, const int* ldc, std::size_t lta,
                  std::size_t ltb) {
  if (*n != 1 || *m <= 0 || *k <= 0) {
    gemm(ta, tb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc, lta, ltb);
    return;
  }
  if (*beta == T(0))  // GEMM does not read C then; GEMV's scaling by 0 would keep a NaN
    for (int i = 0; i < *m; ++i) c[i] = T(0);
  const bool plain = *ta == 'N' || *ta == 'n';
  const int one = 1, incb = (*tb == 'N' || *tb == 'n') ? 1 : *ldb;
  gemv(plain ? "N" : "T", plain ? m : k, plain ? k : m, alpha, a, lda, b, &incb, beta, c, &one, 1);
  gemv_forwards().fetch_add(1, std::memory_order_relaxed);
}

template <class T>
using Trsm = void (*)(const char*, const char*, const char*, const char*, const int*, const int*,
                      const T*, const T*, const int*, T*, const int*, std::size_t, std::size_t,
                      std::size_t, std::size_t);
template <class T>
using Trsv = void (*)(const char*, const char*, const char*, const int*, const T*, const int*, T*,
                      const int*, std::size_t, std::size_t, std::size_t);

// B = alpha op(A)^-1 B (side L) or alpha B op(A)^-1 (side R) with B one
// column (L) or one row (R): alpha B, then xTRSV, op transposed for a row
// (B op(A)^-1 = (op(A)^-T B^T)^T). Other shapes go to the BLAS's TRSM.
template <class T>
void trsm_or_trsv(Trsm<T> trsm, Trsv<T> trsv, const char* side, const char* uplo, const char* ta,
                  const char* diag, const int* m, const int* n, const T* alpha, const T* a,
                  const int* lda, T* b, const int* ldb, std::size_t ls, std::size_t lu,
                  std::size_t lt, std::size_t ld) {
  const bool left = *side == 'L' || *side == 'l';
  if ((left ? *n : *m) != 1 || *m <= 0 || *n <= 0) {
    trsm(side, uplo, ta, diag, m, n, alpha, a, lda, b, ldb, ls, lu, lt, ld);
    return;
  }
  const int len = left ? *m : *n, inc = left ? 1 : *ldb;
  const auto step = static_cast<std::size_t>(inc);
  if (*alpha != T(1))  // alpha 0: B = 0, A not read (TRSM's own rule)
    for (std::size_t i = 0; i < static_cast<std::size_t>(len); ++i)
      b[i * step] = *alpha == T(0) ? T(0) : *alpha * b[i * step];
  if (*alpha == T(0)) return;
  const bool plain = *ta == 'N' || *ta == 'n';
  trsv(uplo, plain == left ? "N" : "T", diag, &len, a, lda, b, &inc, 1, 1, 1);
  gemv_forwards().fetch_add(1, std::memory_order_relaxed);
}

}  // namespace detail

/// xGEMM and xTRSM calls with one column this program handed to xGEMV and
/// xTRSV so far.
inline long long blas_gemv_forwards() {
  return detail::gemv_forwards().load(std::memory_order_relaxed);
}

}  // namespace maxentflow

// Exported even where the program is built with -fvisibility=hidden: the
// shared libraries can only bind to a name in the dynamic symbol table.
#if defined(__GNUC__)
#define MAXENTFLOW_BLAS_ENTRY __attribute__((visibility("default")))
#else
#define MAXENTFLOW_BLAS_ENTRY
#endif

extern "C" {
// Fortran BLAS interfaces (gfortran: the CHARACTER arguments' lengths last).
MAXENTFLOW_BLAS_ENTRY void sgemm_(const char* ta, const char* tb, const int* m, const int* n,
                                  const int* k, const float* alpha, const float* a, const int* lda,
                                  const float* b, const int* ldb, const float* beta, float* c,
                                  const int* ldc, std::size_t lta, std::size_t ltb) {
  using namespace maxentflow::detail;
  static const auto gemm = reinterpret_cast<Gemm<float>>(blas_routine(RTLD_NEXT, "sgemm_"));
  static const auto gemv = reinterpret_cast<Gemv<float>>(blas_routine(RTLD_DEFAULT, "sgemv_"));
  gemm_or_gemv<float>(gemm, gemv, ta, tb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc, lta, ltb);
}
MAXENTFLOW_BLAS_ENTRY void dgemm_(const char* ta, const char* tb, const int* m, const int* n,
                                  const int* k, const double* alpha, const double* a,
                                  const int* lda, const double* b, const int* ldb,
                                  const double* beta, double* c, const int* ldc, std::size_t lta,
                                  std::size_t ltb) {
  using namespace maxentflow::detail;
  static const auto gemm = reinterpret_cast<Gemm<double>>(blas_routine(RTLD_NEXT, "dgemm_"));
  static const auto gemv = reinterpret_cast<Gemv<double>>(blas_routine(RTLD_DEFAULT, "dgemv_"));
  gemm_or_gemv<double>(gemm, gemv, ta, tb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc, lta, ltb);
}
MAXENTFLOW_BLAS_ENTRY void strsm_(const char* side, const char* uplo, const char* ta,
                                  const char* diag, const int* m, const int* n, const float* alpha,
                                  const float* a, const int* lda, float* b, const int* ldb,
                                  std::size_t ls, std::size_t lu, std::size_t lt, std::size_t ld) {
  using namespace maxentflow::detail;
  static const auto trsm = reinterpret_cast<Trsm<float>>(blas_routine(RTLD_NEXT, "strsm_"));
  static const auto trsv = reinterpret_cast<Trsv<float>>(blas_routine(RTLD_DEFAULT, "strsv_"));
  trsm_or_trsv<float>(trsm, trsv, side, uplo, ta, diag, m, n, alpha, a, lda, b, ldb, ls, lu, lt,
                      ld);
}
MAXENTFLOW_BLAS_ENTRY void dtrsm_(const char* side, const char* uplo, const char* ta,
                                  const char* diag, const int* m, const int* n, const double* alpha,
                                  const double* a, const int* lda, double* b, const int* ldb,
                                  std::size_t ls, std::size_t lu, std::size_t lt, std::size_t ld) {
  using namespace maxentflow::detail;
  static const auto trsm = reinterpret_cast<Trsm<double>>(blas_routine(RTLD_NEXT, "dtrsm_"));
  static const auto trsv = reinterpret_cast<Trsv<double>>(blas_routine(RTLD_DEFAULT, "dtrsv_"));
  trsm_or_trsv<double>(trsm, trsv, side, uplo, ta, diag, m, n, alpha, a, lda, b, ldb, ls, lu, lt,
                       ld);
}
}

#undef MAXENTFLOW_BLAS_ENTRY

// maxentflow: thread control for the OpenMP loops (serial without OpenMP).
#pragma once

#if defined(_OPENMP)
#include <omp.h>
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

}  // namespace maxentflow

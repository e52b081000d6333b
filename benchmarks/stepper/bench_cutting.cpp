// Benchmark: E3 orthogonal cutting (docs/cases.md), the whole run with its
// time split into mesh, basis, assembly, factorization, linear solves and
// post-processing, and the node count over the run (rezoning). Never fails on
// time; the spec's target is 120 s for the full run on a 2-core machine.
//   bench_cutting [nx = 122] [ny = 41] [steps = 350] [dt = 2e-5]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>

#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV

#include "cutting/cutting_case.hpp"
#include "stepper/step_totals.hpp"

using namespace maxentflow;

int main(int argc, char** argv) {
  set_blas_threads(1);  // as the examples: the cores go to the OpenMP loops
  examples::CuttingSetup s;
  if (argc > 1) s.nx = std::atoi(argv[1]);
  if (argc > 2) s.ny = std::atoi(argv[2]);
  const int steps = argc > 3 ? std::atoi(argv[3]) : 350;
  if (argc > 4) s.dt = std::atof(argv[4]);
  Stepper<NortonHoff> sim = examples::make_cutting(s);
  const auto t0 = std::chrono::steady_clock::now();
  int done = 0;
  try {
    for (; done < steps; ++done) sim.step();
  } catch (const Error& e) {
    std::fprintf(stderr, "bench_cutting: stopped after %d steps: %s\n", done, e.what());
  }
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bench::StepTotals T(sim.history());
  std::printf(
      "BENCH cutting nodes_start=%d nodes_end=%ld nodes_max=%d nodes_added=%d nodes_removed=%d steps=%d completed=%d "
      "threads=%d total_s=%.3f per_step_s=%.4f mesh_s=%.3f basis_s=%.3f solve_s=%.3f assembly_s=%.3f "
      "factorization_s=%.3f linear_s=%.3f post_s=%.3f picard=%d newton=%d krylov=%d max_krylov_per_solve=%d "
      "direct_fallbacks=%d retried_steps=%d gemv_forwards=%lld target_s=120\n",
      s.nx * s.ny, static_cast<long>(sim.nodes().cols()), T.nodes_max, T.added, T.removed, steps, done,
      max_threads(), total, total / std::max(1, done), T.mesh, T.basis, T.solve, T.assembly, T.factorization,
      T.linear, T.post, T.picard, T.newton, T.krylov, T.max_krylov, T.fallbacks, T.retried, blas_gemv_forwards());
  return done == steps ? 0 : 1;
}

// Benchmark: E3 orthogonal cutting (docs/cases.md), the whole run with its
// time split into mesh, basis, assembly, factorization, linear solves and
// post-processing, and the node count over the run (rezoning). Never fails on
// time; the spec's target is 120 s for the full run on a 2-core machine.
//   bench_cutting [nx = 122] [ny = 41] [steps = 350] [dt = 2e-5]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>

#include "cutting/cutting_case.hpp"

using namespace maxentflow;

int main(int argc, char** argv) {
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
  double mesh = 0, basis = 0, solve = 0, post = 0, assembly = 0, factorization = 0, linear = 0;
  int picard = 0, newton = 0, krylov = 0, fallbacks = 0, max_krylov = 0, retried = 0, added = 0, removed = 0;
  int nodes_max = 0;
  for (const auto& r : sim.history()) {
    mesh += r.mesh_seconds;
    basis += r.basis_seconds;
    solve += r.solve_seconds;
    post += r.post_seconds;
    assembly += r.assembly_seconds;
    factorization += r.factorization_seconds;
    linear += r.linear_seconds;
    picard += r.picard;
    newton += r.newton;
    krylov += r.linear_iterations;
    max_krylov = std::max(max_krylov, r.max_linear_iterations);
    fallbacks += r.direct_fallbacks;
    retried += r.substeps > 1;
    added += r.nodes_added;
    removed += r.nodes_removed;
    nodes_max = std::max(nodes_max, r.nodes);
  }
  std::printf(
      "BENCH cutting nodes_start=%d nodes_end=%ld nodes_max=%d nodes_added=%d nodes_removed=%d steps=%d completed=%d "
      "threads=%d total_s=%.3f per_step_s=%.4f mesh_s=%.3f basis_s=%.3f solve_s=%.3f assembly_s=%.3f "
      "factorization_s=%.3f linear_s=%.3f post_s=%.3f picard=%d newton=%d krylov=%d max_krylov_per_solve=%d "
      "direct_fallbacks=%d retried_steps=%d target_s=120\n",
      s.nx * s.ny, static_cast<long>(sim.nodes().cols()), nodes_max, added, removed, steps, done, max_threads(),
      total, total / std::max(1, done), mesh, basis, solve, assembly, factorization, linear, post, picard, newton,
      krylov, max_krylov, fallbacks, retried);
  return done == steps ? 0 : 1;
}

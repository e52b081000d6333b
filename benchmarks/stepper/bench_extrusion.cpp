// Benchmark: E2 extrusion (docs/cases.md), the whole run with its time split
// into mesh, basis, assembly, factorization (preconditioner), linear solves,
// post-processing and VTU/CSV output. Never fails on time.
//   bench_extrusion [nodes_per_side = 32] [steps = 100] [dt = 0.3] [--no-peer]
// (`bench_extrusion 64` is the 64 x 64 run.) Where FreeFem++ is installed it
// also times the FEM peer's step-1 solve at the same nodes per side (wall
// clock, same run) and prints the ratio; --no-peer skips it.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <filesystem>

#include <cstring>

#include "extrusion/extrusion_case.hpp"
#include "peer/peer.hpp"

using namespace maxentflow;

int main(int argc, char** argv) {
  examples::Setup s;
  s.nx = s.ny = argc > 1 ? std::atoi(argv[1]) : 32;
  const int steps = argc > 2 ? std::atoi(argv[2]) : 100;
  if (argc > 3) s.dt = std::atof(argv[3]);
  Stepper<NortonHoff> sim = examples::make_simulation(s);
  const auto dir = std::filesystem::temp_directory_path() / "maxentflow_bench_extrusion";
  std::filesystem::remove_all(dir);
  ResultsWriter out(dir);
  double output = 0;
  const auto t0 = std::chrono::steady_clock::now();
  int done = 0;
  try {
    for (int k = 1; k <= steps; ++k, ++done) {
      sim.step();
      const auto t = std::chrono::steady_clock::now();
      out.record(sim, k % 10 == 0 || k == 1);
      output += std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "bench_extrusion: stopped after %d steps: %s\n", done, e.what());
  }
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double mesh = 0, basis = 0, solve = 0, post = 0, assembly = 0, factorization = 0, linear = 0;
  int picard = 0, newton = 0, krylov = 0, retried = 0, pc_updates = 0, fallbacks = 0, max_krylov = 0;
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
    pc_updates += r.preconditioner_updates;
    fallbacks += r.direct_fallbacks;
    retried += r.substeps > 1;
  }
  std::printf(
      "BENCH extrusion nodes=%d steps=%d completed=%d threads=%d total_s=%.3f per_step_s=%.4f "
      "mesh_s=%.3f basis_s=%.3f solve_s=%.3f assembly_s=%.3f factorization_s=%.3f linear_s=%.3f "
      "post_s=%.3f output_s=%.3f picard=%d newton=%d krylov=%d preconditioner_updates=%d direct_fallbacks=%d max_krylov_per_solve=%d retried_steps=%d\n",
      s.nx * s.ny, steps, done, max_threads(), total, total / std::max(1, done), mesh, basis, solve,
      assembly, factorization, linear, post, output, picard, newton, krylov, pc_updates, fallbacks, max_krylov, retried);
  const bool peer = !(argc > 4 && std::strcmp(argv[4], "--no-peer") == 0);
  const double ps = peer ? bench::peer_step1_seconds(s.nx) : -1.0;
  if (ps > 0)
    std::printf("BENCH extrusion_vs_peer run_over_peer_step1=%.2f target=10 step1_s=%.3f\n", total / ps,
                sim.history().empty() ? 0.0 : sim.history().front().seconds);
  std::filesystem::remove_all(dir);
  return done == steps ? 0 : 1;
}

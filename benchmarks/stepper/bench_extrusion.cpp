// Benchmark: E2 extrusion (docs/cases.md), the whole run with its time split
// into mesh, basis, assembly, factorization (preconditioner), linear solves,
// post-processing and VTU/CSV output. Never fails on time.
//   bench_extrusion [nodes_per_side = 32] [steps = 100] [dt = 0.3] [--no-peer] [--no-zone]
// (`bench_extrusion 64` is the 64 x 64 run.) Where FreeFem++ is installed it
// also times the FEM peer's step-1 solve at the same nodes per side (wall
// clock, same run) and prints the ratio; --no-peer skips it.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <cstring>

#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV

#include "extrusion/extrusion_case.hpp"
#include "peer/peer.hpp"
#include "stepper/step_totals.hpp"

using namespace maxentflow;

int main(int argc, char** argv) {
  set_blas_threads(1);  // as the examples: the cores go to the OpenMP loops
  // Numbers first, then the flags in any order.
  std::vector<std::string> num, flags;
  for (int i = 1; i < argc; ++i) (std::strncmp(argv[i], "--", 2) == 0 ? flags : num).emplace_back(argv[i]);
  const auto flag = [&](const char* f) { return std::find(flags.begin(), flags.end(), f) != flags.end(); };
  examples::Setup s;
  s.nx = s.ny = num.size() > 0 ? std::atoi(num[0].c_str()) : 32;
  const int steps = num.size() > 1 ? std::atoi(num[1].c_str()) : 100;
  if (num.size() > 2) s.dt = std::atof(num[2].c_str());
  // The Eulerian zone as the example sets it by default (--no-zone: none).
  if (!flag("--no-zone") && examples::zone_by_default(s)) s.zone_from = examples::default_zone_from(s, steps);
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
  const bench::StepTotals T(sim.history());
  std::printf(
      "BENCH extrusion nodes=%d steps=%d completed=%d threads=%d total_s=%.3f per_step_s=%.4f "
      "mesh_s=%.3f basis_s=%.3f solve_s=%.3f assembly_s=%.3f factorization_s=%.3f linear_s=%.3f "
      "post_s=%.3f output_s=%.3f picard=%d newton=%d krylov=%d preconditioner_updates=%d direct_fallbacks=%d max_krylov_per_solve=%d retried_steps=%d eulerian_zone=%d gemv_forwards=%lld\n",
      s.nx * s.ny, steps, done, max_threads(), total, total / std::max(1, done), T.mesh, T.basis, T.solve,
      T.assembly, T.factorization, T.linear, T.post, output, T.picard, T.newton, T.krylov, T.preconditioner_updates,
      T.fallbacks, T.max_krylov, T.retried, sim.eulerian_zone() ? 1 : 0, blas_gemv_forwards());
  const bool peer = !flag("--no-peer");
  const double ps = peer ? bench::peer_step1_seconds(s.nx) : -1.0;
  if (ps > 0)
    std::printf("BENCH extrusion_vs_peer run_over_peer_step1=%.2f target=10 step1_s=%.3f\n", total / ps,
                sim.history().empty() ? 0.0 : sim.history().front().seconds);
  std::filesystem::remove_all(dir);
  return done == steps ? 0 : 1;
}

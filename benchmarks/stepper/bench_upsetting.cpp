// Benchmark: E1 upsetting (21 x 25 nodes, 100 steps, axisymmetric), the whole
// run with its time per step split into mesh, basis, solve (assembly + LU,
// active set), and post-processing + VTU/CSV output. Never fails on time.
//   bench_upsetting [steps] [gmres|direct] [--no-peer]
// Where FreeFem++ is installed it also times the FEM peer's E2 step-1 solve
// (32 per side; spec target: the whole E1 run within that time) and prints the ratio.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include <maxentflow/maxentflow.hpp>
#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV

#include "peer/peer.hpp"
#include "stepper/step_totals.hpp"

using namespace maxentflow;

template <class Linear>
int run(int steps, const char* solver, bool peer) {
  const int nx = 21, ny = 25;
  const double R = 10, H = 12, V = 0.06;
  Eigen::Matrix2Xd x(2, nx * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) x.col(j * nx + i) << R * i / (nx - 1), H * j / (ny - 1);
  StepperParams prm;
  prm.geometry = Geometry::axisymmetric;
  prm.dt = 1.0;
  if (std::getenv("BENCH_LOG")) prm.solver.log = &std::cerr;

  Stepper<NortonHoff, Linear> sim(x, NortonHoff(150.0, 0.2, 1e-6 * V / H), prm);
  sim.add_tool(flat_plate("bottom plate", {0, 0}, {0, 1}, 1000));
  RigidTool top = flat_plate("top plate", {0, H}, {0, -1}, 1000);
  top.set_velocity({0, -V});
  sim.add_tool(top);
  sim.add_velocity_condition({"axis", on_line({0, 0}, {1, 0}, 1e-9 * R), {1, 0}, 0.0});
  const auto dir = std::filesystem::temp_directory_path() / "maxentflow_bench_upsetting";
  ResultsWriter out(dir);
  double output = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 1; k <= steps; ++k) {
    sim.step();
    const auto t = std::chrono::steady_clock::now();
    out.record(sim, k % 10 == 0 || k == 1);
    output += std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  }
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bench::StepTotals T(sim.history());
  std::printf(
      "BENCH upsetting nodes=%d steps=%d threads=%d total_s=%.3f per_step_s=%.4f mesh_s=%.3f "
      "basis_s=%.3f solve_s=%.3f (assembly_s=%.3f factorization_s=%.3f linear_s=%.3f) post_s=%.3f output_s=%.3f picard=%d newton=%d krylov=%d max_krylov_per_solve=%d direct_fallbacks=%d solver=%s gemv_forwards=%lld\n",
      nx * ny, steps, max_threads(), total, total / steps, T.mesh, T.basis, T.solve, T.assembly, T.factorization,
      T.linear, T.post, output, T.picard, T.newton, T.krylov, T.max_krylov, T.fallbacks, solver, blas_gemv_forwards());
  const double ps = peer ? bench::peer_step1_seconds(32) : -1.0;
  if (ps > 0) std::printf("BENCH upsetting_vs_peer run_over_peer_step1=%.2f target=1\n", total / ps);
  std::filesystem::remove_all(dir);
  return 0;
}

int main(int argc, char** argv) {
  set_blas_threads(1);  // as the examples: the cores go to the OpenMP loops
  const int steps = argc > 1 ? std::atoi(argv[1]) : 100;
  const std::string solver = argc > 2 ? argv[2] : "gmres";
  const bool peer = !(argc > 3 && std::string(argv[3]) == "--no-peer");
  if (solver == "direct") return run<UmfpackSolver>(steps, "direct", peer);
  return run<GmresSolver<>>(steps, "gmres", peer);
}

// Benchmark: one full nonlinear solve (Picard then Newton; GMRES preconditioned by
// the linear-triangle LU, or UMFPACK on the whole system with
// MAXENTFLOW_BENCH_SOLVER=direct) of a
// Norton-Hoff plane-strain compression, at N = 1k, 4k, 16k, 64k nodes (spec
// section 4: time should grow no faster than N^1.2; peak memory at 64k <= 2 GB).
//
// Problem: block [0, 10] x [0, 10], nodes on a sqrt(N) x sqrt(N) grid with
// interior nodes moved at random by up to 0.2 h each way; mu0 = 150, n = 0.2,
// d_min = 1e-6 V/H; symmetry v_x = 0 on x = 0; bottom plate sticking
// (v_x = v_y = 0 on y = 0, so the flow is not homogeneous); top plate v_y = -V,
// V = 1 (frictionless); the right side x = 10 is free.
//
// Per size it prints one line
//   BENCH flow N=... unknowns=... nnz=... mesh=... basis=... pattern=... constraints=...
//         assembly=... factorization=... solve=... nonlinear_other=... total=... picard=...
//         newton=... krylov=... direct_fallbacks=... peak_rss_mb=... ...
// (seconds; `basis` is the MaxEntBasis construction plus the FlowDiscretization
// build, which evaluates the basis at all Gauss and edge points; `pattern` the
// FlowSystem construction plus the first size(); assembly/factorization/solve
// are the SolveReport's; total is wall time from the mesh to the solution;
// peak_rss_mb is getrusage's ru_maxrss, the process peak so far, i.e. that of
// the largest size run yet), then the least-squares growth exponent of total
// (and of each part) against N. Never fails on time; exits 1 only if a solve fails.
//
// Progress (each part as it ends) goes to stderr, and with MAXENTFLOW_BENCH_LOG=1
// also the nonlinear solver's per-iteration log, so that a run stopped early
// still shows where the time went.
//
// Usage: bench_flow [max_N [min_N]]   (sizes 1024, 4096, 16384, 65536 within
// [min_N, max_N]; default max_N 65536; the ctest runs 16384)
#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/core/parallel.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/flow/flow_system.hpp>
#include <maxentflow/material/norton_hoff.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>
#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV
#include <maxentflow/solver/nonlinear_solver.hpp>
#include <maxentflow/stepper/stepper.hpp>

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <random>
#include <string>
#include <vector>

using namespace maxentflow;

namespace {

bool direct_solver() {
  const char* e = std::getenv("MAXENTFLOW_BENCH_SOLVER");
  return e && std::string(e) == "direct";
}
const char* solver_name() { return direct_solver() ? "umfpack" : "gmres"; }

using clock_type = std::chrono::steady_clock;

double since(clock_type::time_point t0) {
  return std::chrono::duration<double>(clock_type::now() - t0).count();
}

double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

// side x side nodes on [0, L]^2; interior nodes perturbed by up to delta * h.
Eigen::Matrix2Xd block(int side, double L, double delta, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-delta, delta);
  const double h = L / (side - 1);
  Eigen::Matrix2Xd x(2, side * side);
  for (int j = 0; j < side; ++j)
    for (int i = 0; i < side; ++i) {
      const bool inner = i > 0 && j > 0 && i + 1 < side && j + 1 < side;
      const double dx = u(rng), dy = u(rng);
      x.col(j * side + i) << h * (i + (inner ? dx : 0.0)), h * (j + (inner ? dy : 0.0));
    }
  return x;
}

struct Figures {
  std::map<std::string, double> t;  // seconds per part
  int picard = 0, newton = 0, fallbacks = 0;
};

void progress(int side, const char* part, double seconds) {
  std::fprintf(stderr, "bench_flow: N=%d %s %.3f s (peak rss %.0f MB)\n", side * side, part, seconds,
               peak_rss_mb());
}

template <class Linear>
Figures run(int side) {
  const double L = 10.0, V = 1.0, H = L;
  Figures f;
  const auto start = clock_type::now();

  // 1. Integration mesh.
  auto t0 = clock_type::now();
  const Eigen::Matrix2Xd x = block(side, L, 0.2, 7);
  const IntegrationMesh<> mesh(x);
  f.t["mesh"] = since(t0);
  progress(side, "mesh", f.t["mesh"]);

  // 2. Basis (h_a from the mesh) and the discretization (basis at all points).
  t0 = clock_type::now();
  MaxEntBasis<2>::params bp;
  bp.gamma = 1.6;
  bp.tol0 = StepperParams{}.tol0;  // the forming runs' support cut-off
  const MaxEntBasis<2> basis(x, mesh.h(), bp);
  const FlowDiscretization disc(mesh, basis, Geometry::plane_strain);
  f.t["basis"] = since(t0);
  progress(side, "basis", f.t["basis"]);

  // 3. System (node adjacency), constraints, matrix structure.
  t0 = clock_type::now();
  FlowSystem<NortonHoff> system(mesh, disc, NortonHoff(150.0, 0.2, 1e-6 * V / H));
  f.t["pattern"] = since(t0);
  t0 = clock_type::now();
  const double tol = 1e-9 * L;
  auto value = [](double v) { return [v](const Eigen::Vector2d&) { return v; }; };
  auto& cs = system.constraints();
  cs.add_velocity(mesh, disc, on_line({0, 0}, {1, 0}, tol), {1, 0}, value(0.0), "symmetry");
  cs.add_velocity(mesh, disc, on_line({0, 0}, {0, 1}, tol), {0, 1}, value(0.0), "bottom");
  cs.add_velocity(mesh, disc, on_line({0, 0}, {0, 1}, tol), {1, 0}, value(0.0), "bottom");
  cs.add_velocity(mesh, disc, on_line({0, H}, {0, 1}, tol), {0, 1}, value(-V), "top");
  f.t["constraints"] = since(t0);
  t0 = clock_type::now();
  const int unknowns = system.size();
  f.t["pattern"] += since(t0);
  progress(side, "pattern+constraints", f.t["pattern"] + f.t["constraints"]);
  const long nnz = static_cast<long>(system.pattern().nonzeros());

  // 4. One nonlinear solve from rest.
  t0 = clock_type::now();
  NonlinearSolverParams np;
  if (const char* e = std::getenv("MAXENTFLOW_BENCH_LOG"); e && *e && *e != '0') np.log = &std::cerr;
  NonlinearSolver<Linear> solver(np);
  Eigen::VectorXd X;
  const SolveReport rep = solver.solve(system, X);
  const double nonlinear = since(t0);
  f.t["assembly"] = rep.assembly_seconds;
  f.t["factorization"] = rep.factorization_seconds;
  f.t["solve"] = rep.solve_seconds;
  f.t["nonlinear_other"] = nonlinear - rep.assembly_seconds - rep.factorization_seconds - rep.solve_seconds;
  f.t["total"] = since(start);
  f.picard = rep.picard;
  f.newton = rep.newton;
  f.fallbacks = rep.direct_fallbacks;

  const Eigen::Vector2d top = system.reaction("top", X);
  std::printf(
      "BENCH flow N=%ld threads=%d unknowns=%d nnz=%ld triangles=%ld mean_nodes_per_cell=%.1f "
      "mean_adjacency=%.1f mesh=%.4f basis=%.4f pattern=%.4f constraints=%.4f assembly=%.4f "
      "factorization=%.4f solve=%.4f nonlinear_other=%.4f total=%.4f picard=%d newton=%d "
      "krylov=%d direct_fallbacks=%d residual=%.3e top_force_y=%.6g peak_rss_mb=%.1f solver=%s\n",
      static_cast<long>(x.cols()), max_threads(), unknowns, nnz,
      static_cast<long>(mesh.number_of_triangles()), disc.mean_nodes_per_cell(),
      system.pattern().mean_adjacency(), f.t["mesh"], f.t["basis"], f.t["pattern"],
      f.t["constraints"], f.t["assembly"], f.t["factorization"], f.t["solve"],
      f.t["nonlinear_other"], f.t["total"], f.picard, f.newton, rep.linear_iterations, f.fallbacks, rep.residual,
      top.y(), peak_rss_mb(), solver_name());
  std::fflush(stdout);
  return f;
}

// Least-squares slope of log y against log x.
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double lx = std::log(x[i]), ly = std::log(std::max(y[i], 1e-9));
    sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

}  // namespace

int main(int argc, char** argv) {
  set_blas_threads(1);  // as the examples: the cores go to the OpenMP loops
  const long max_n = argc > 1 ? std::atol(argv[1]) : 65536;
  const long min_n = argc > 2 ? std::atol(argv[2]) : 0;
  std::vector<double> ns;
  std::map<std::string, std::vector<double>> times;
  try {
    for (int side : {32, 64, 128, 256}) {
      if (static_cast<long>(side) * side > max_n) break;
      if (static_cast<long>(side) * side < min_n) continue;
      const Figures f = direct_solver() ? run<UmfpackSolver>(side) : run<GmresSolver<>>(side);
      ns.push_back(static_cast<double>(side) * side);
      for (const auto& [k, v] : f.t) times[k].push_back(v);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_flow: %s\n", e.what());
    return 1;
  }
  if (ns.size() >= 2) {
    std::printf("BENCH flow_growth sizes=%zu N_min=%.0f N_max=%.0f", ns.size(), ns.front(), ns.back());
    for (const char* k : {"total", "mesh", "basis", "pattern", "assembly", "factorization", "solve"})
      std::printf(" %s_exponent=%.3f", k, slope(ns, times[k]));
    // The fit hides a steepening curve: also the exponent of the two largest sizes.
    const auto& tt = times["total"];
    const std::size_t k = ns.size() - 1;
    std::printf(" total_exponent_last_pair=%.3f target_total_exponent=1.2\n",
                std::log(tt[k] / tt[k - 1]) / std::log(ns[k] / ns[k - 1]));
  }
  return 0;
}

// maxentflow example: channel_flow — power-law (Norton-Hoff) flow in a plane
// channel driven by a body force, against its exact solution (spec case V3).
//
// Compile with:  cmake --preset release && cmake --build --preset release --target channel_flow
//
// Sample runs:
//   channel_flow                                   (n = 0.5, 17 nodes across, into results/channel_flow/)
//   channel_flow --n 1 --ny 33 --convergence       (Newtonian, plus the refinement study)
//   channel_flow --no-plots --check 0.02           (CSV/VTU only; exit 1 if the profile is off by > 2 %)
//
// Description:
//   Channel x in [0, l], y in [-b, b]; no-slip walls (v = 0 on y = +-b); the ends
//   x = 0 and x = l have v_y = 0 and no x-traction; body force (G, 0). The
//   material is Norton-Hoff, mu = mu0 (sqrt(3) d)^(n-1). The flow is fully
//   developed: v = (u(y), 0), p = 0, with sqrt(3) d = |u'| and
//     u(y) = n/(n+1) (G/mu0)^(1/n) (b^((n+1)/n) - |y|^((n+1)/n)),
//   a parabola for n = 1 and a blunter, plug-like profile for n < 1.
//   The nodes form a regular grid (ny across the channel, the same spacing along
//   it); the velocity and pressure are max-ent interpolants of nodal
//   coefficients, the walls and ends are imposed by Lagrange multipliers, and the
//   nonlinear system is solved by Picard then Newton iterations.
//   Outputs (in --out-dir):
//     profile.csv       y,u,u_exact: the discrete u_h(l/2, y) = sum_a p_a(x) V_a and the exact u
//     channel_flow.vtu  nodes and integration triangles with the nodal velocity and
//                       pressure coefficients and the exact velocity (ParaView)
//     convergence.csv   h,l2_error for ny = 5, 9, 17, 33 (with --convergence)
//     profile.png, convergence.png  drawn by plot_channel_flow.py (unless --no-plots)
#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/flow/flow_system.hpp>
#include <maxentflow/io/csv.hpp>
#include <maxentflow/io/vtk.hpp>
#include <maxentflow/material/norton_hoff.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>
#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV
#include <maxentflow/solver/nonlinear_solver.hpp>

#include "common/plotting.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace maxentflow;

namespace {

struct Channel {
  double n = 0.5;       // Norton-Hoff exponent
  double mu0 = 2.0;     // consistency
  double G = 3.0;       // body force along x
  double b = 1.0;       // half width
  double length = 2.0;  // l
  double gamma = 1.6;   // max-ent locality
  double Cs = 0.5;      // stabilization, Eq. (14)
  double d_min_rel = 1e-7;  // regularization floor, relative to u_max / b

  double u_max() const { return n / (n + 1) * std::pow(G / mu0, 1 / n) * std::pow(b, (n + 1) / n); }
  double exact(double y) const {
    const double k = (n + 1) / n;
    return n / (n + 1) * std::pow(G / mu0, 1 / n) * (std::pow(b, k) - std::pow(std::abs(y), k));
  }
};

struct Result {
  double h = 0;         // node spacing across the channel
  double l2_error = 0;  // relative L2 error of u at the Gauss points
  double profile_error = 0;  // max |u_h - u| / max u on the x = l/2 profile
  int nodes = 0, picard = 0, newton = 0;
};

// Solves the channel on a grid with ny nodes across; fills the profile and the
// VTU if asked (profile and vtu may be null, e.g. for the refinement study).
Result solve(const Channel& c, int ny, int samples, std::ostream* log, CsvTable* profile,
             const fs::path* vtu) {
  // 1. Nodes: a regular grid, ny across, the same spacing (as near as fits) along.
  const int nx = std::max(2, static_cast<int>(std::lround(c.length / (2 * c.b) * (ny - 1)))) + 1;
  Eigen::Matrix2Xd x(2, nx * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      x.col(j * nx + i) << c.length * i / (nx - 1), -c.b + 2 * c.b * j / (ny - 1);

  // 2. Integration mesh (Delaunay + alpha shape), basis with the mesh's h_a,
  //    basis at the Gauss points, and the saddle system for Norton-Hoff.
  const IntegrationMesh<> mesh(x);
  MaxEntBasis<2>::params bp;
  bp.gamma = c.gamma;
  const MaxEntBasis<2> basis(x, mesh.h(), bp);
  const FlowDiscretization disc(mesh, basis, Geometry::plane_strain);
  const NortonHoff material(c.mu0, c.n, c.d_min_rel * c.u_max() / c.b);
  StabilizationParams sp;
  sp.Cs = c.Cs;
  FlowSystem<NortonHoff> system(mesh, disc, material, sp);
  system.assembler().set_body_force(Eigen::Vector2d(c.G, 0.0));

  // 3. Essential conditions by Lagrange multipliers: no slip on the walls,
  //    v_y = 0 on the ends (their x-traction is zero: nothing to add).
  const double tol = 1e-9 * c.b;
  auto zero = [](const Eigen::Vector2d&) { return 0.0; };
  auto& cs = system.constraints();
  for (double yw : {-c.b, c.b}) {
    cs.add_velocity(mesh, disc, on_line({0, yw}, {0, 1}, tol), {1, 0}, zero, "wall");
    cs.add_velocity(mesh, disc, on_line({0, yw}, {0, 1}, tol), {0, 1}, zero, "wall");
  }
  for (double xe : {0.0, c.length})
    cs.add_velocity(mesh, disc, on_line({xe, 0}, {1, 0}, tol), {0, 1}, zero, "ends");

  // 4. Picard, then Newton (from zero: the first iterate is a Newtonian flow).
  NonlinearSolverParams np;
  np.log = log;
  NonlinearSolver<> solver(np);
  Eigen::VectorXd X;
  const SolveReport rep = solver.solve(system, X);

  Result r;
  r.h = 2 * c.b / (ny - 1);
  r.nodes = static_cast<int>(x.cols());
  r.picard = rep.picard;
  r.newton = rep.newton;

  // 5. Relative L2 error of u over the channel, at the Gauss points:
  //    u_h(x_g) = sum_{a in U_T} p_a(x_g) V_a.
  double e2 = 0, u2 = 0;
  for (int t = 0; t < disc.cells(); ++t) {
    const auto u = disc.nodes(t);
    for (int q = 0; q < disc.points_per_cell(); ++q) {
      const int g = t * disc.points_per_cell() + q;
      const double* p = disc.values(t, q);
      double uh = 0;
      for (std::size_t i = 0; i < u.size(); ++i) uh += p[i] * X[velocity_dof(u[i], 0)];
      const double ue = c.exact(disc.points()(1, g));
      e2 += disc.weight(g) * (uh - ue) * (uh - ue);
      u2 += disc.weight(g) * ue * ue;
    }
  }
  r.l2_error = std::sqrt(e2 / u2);

  // 6. The profile across the channel at x = l/2, by evaluating the basis there.
  double worst = 0;
  for (int k = 0; k < samples; ++k) {
    const double y = -c.b + 2 * c.b * k / (samples - 1);
    const auto v = basis.evaluate(Eigen::Vector2d(0.5 * c.length, y), false);
    double uh = 0;
    for (std::size_t j = 0; j < v.node.size(); ++j) uh += v.p[j] * X[velocity_dof(v.node[j], 0)];
    const double ue = c.exact(y);
    worst = std::max(worst, std::abs(uh - ue));
    if (profile) profile->row({y, uh, ue});
  }
  r.profile_error = worst / c.u_max();

  // 7. VTU: nodes, triangles, nodal coefficients (velocity, pressure), exact velocity.
  if (vtu) {
    const int N = static_cast<int>(x.cols());
    Eigen::Matrix2Xd vel(2, N), vel_exact = Eigen::Matrix2Xd::Zero(2, N);
    Eigen::VectorXd pres(N);
    for (int a = 0; a < N; ++a) {
      vel.col(a) << X[velocity_dof(a, 0)], X[velocity_dof(a, 1)];
      pres(a) = X[pressure_dof(a)];
      vel_exact(0, a) = c.exact(x(1, a));
    }
    VtuWriter()
        .points(x)
        .triangles(mesh.triangles())
        .point_vector("velocity", vel)
        .point_scalar("pressure", pres)
        .point_vector("velocity_exact", vel_exact)
        .point_scalar("h", mesh.h())
        .write(*vtu);
  }
  return r;
}

double rate(double e0, double e1, double h0, double h1) { return std::log(e0 / e1) / std::log(h0 / h1); }

}  // namespace

int main(int argc, char** argv) {
  // 1. Parse options.
  CLI::App app{"maxentflow channel_flow: power-law channel flow against its exact solution (V3)"};
  Channel c;
  int ny = 17, samples = 101;
  std::string out_dir = "results/channel_flow";
  bool no_plots = false, convergence = false;
  double check_tol = -1;
  app.add_option("--n", c.n, "Norton-Hoff exponent n (1: Newtonian)")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--nodes-per-side,--ny", ny, "Nodes across the channel (the spacing along is the same)")
      ->check(CLI::Range(3, 2000))->capture_default_str();
  app.add_option("--mu0", c.mu0, "Consistency mu0 of mu = mu0 (sqrt(3) d)^(n-1)")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--G", c.G, "Body force along the channel")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--b", c.b, "Half width b of the channel")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--length", c.length, "Length l of the channel")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--gamma", c.gamma, "Max-ent locality gamma")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--Cs", c.Cs, "Stabilization constant Cs of Eq. (14)")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--d-min", c.d_min_rel, "Strain-rate floor d_min of the Norton-Hoff law, relative to u_max / b")
      ->check(CLI::Range(1e-300, 1.0))->capture_default_str();
  app.add_option("--samples", samples, "Points of the x = l/2 profile")->check(CLI::Range(2, 100000))->capture_default_str();
  app.add_option("--out-dir", out_dir, "Folder for the CSV, VTU and PNG files")->capture_default_str();
  app.add_flag("--convergence", convergence, "Also solve with ny = 5, 9, 17, 33 and write convergence.csv");
  app.add_flag("--no-plots", no_plots, "Write CSV/VTU only (no matplotlib)");
  app.add_option("--check", check_tol, "Exit 1 if max |u_h - u| / max u on the profile exceeds TOL")
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  set_blas_threads(1);  // the cores go to the OpenMP loops (parallel.hpp)

  try {
    const fs::path out(out_dir);
    std::cout << "channel_flow: n = " << c.n << ", mu0 = " << c.mu0 << ", G = " << c.G << ", b = " << c.b
              << ", l = " << c.length << ", gamma = " << c.gamma << ", Cs = " << c.Cs << ", " << ny
              << " nodes across; exact u_max = " << c.u_max() << "\n";

    // 2. The requested resolution, with the solver's log.
    CsvTable profile({"y", "u", "u_exact"});
    const fs::path vtu = out / "channel_flow.vtu";
    const Result r = solve(c, ny, samples, &std::cout, &profile, &vtu);
    profile.write(out / "profile.csv");
    std::printf("  %d nodes, %d picard + %d newton iterations\n", r.nodes, r.picard, r.newton);
    std::printf("  relative L2 error of u: %.4e\n", r.l2_error);
    std::printf("  max |u_h - u| / max u on the profile x = l/2: %.4e\n", r.profile_error);
    std::cout << "  wrote " << (out / "profile.csv").string() << ", " << vtu.string() << "\n";

    // 3. Refinement study: relative L2 error and observed rates.
    if (convergence) {
      CsvTable conv({"h", "l2_error"});
      std::vector<Result> rs;
      for (int m : {5, 9, 17, 33}) {
        rs.push_back(solve(c, m, 2, nullptr, nullptr, nullptr));
        const Result& q = rs.back();
        conv.row({q.h, q.l2_error});
        std::printf("  convergence: ny = %2d  h = %.5g  L2 error %.4e (%d + %d iterations)", m, q.h,
                    q.l2_error, q.picard, q.newton);
        if (rs.size() > 1) {
          const Result& p = rs[rs.size() - 2];
          std::printf("  rate %.3f", rate(p.l2_error, q.l2_error, p.h, q.h));
        }
        std::printf("\n");
      }
      // Least-squares slope of log error against log h.
      double sx = 0, sy = 0, sxx = 0, sxy = 0;
      for (const auto& q : rs) {
        const double lx = std::log(q.h), ly = std::log(q.l2_error);
        sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
      }
      const double k = static_cast<double>(rs.size());
      std::printf("  observed L2 rate: %.3f (last pair), %.3f (fit over all)\n",
                  rate(rs[rs.size() - 2].l2_error, rs.back().l2_error, rs[rs.size() - 2].h, rs.back().h),
                  (k * sxy - sx * sy) / (k * sxx - sx * sx));
      conv.write(out / "convergence.csv");
      std::cout << "  wrote " << (out / "convergence.csv").string() << "\n";
    }
    std::cout.flush();

    // 4. Figures (matplotlib), then the optional check.
    if (!no_plots) {
      std::ostringstream n_text;
      n_text << c.n;
      examples::run_plot_script(fs::path(MAXENTFLOW_EXAMPLE_DIR) / "plot_channel_flow.py",
                                "\"" + out.string() + "\" " + n_text.str());
    }
    if (check_tol > 0) {
      const bool ok = std::isfinite(r.profile_error) && r.profile_error <= check_tol;
      std::printf("check: max relative profile error %.4e %s %.4g: %s\n", r.profile_error,
                  ok ? "<=" : ">", check_tol, ok ? "passed" : "FAILED");
      return ok ? 0 : 1;
    }
    return 0;
  } catch (const maxentflow::Error& e) {
    std::cerr << e.what() << "\n";
    return 1;
  }
}

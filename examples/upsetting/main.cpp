// Example E1 (docs/cases.md): upsetting of a cylindrical billet between flat,
// frictionless plates; axisymmetric by default, --plane-strain for a strip.
//
//   upsetting                                 (E1: 21 x 25 nodes, 100 steps, dt = 1)
//   upsetting --plane-strain --steps 50 --out-dir /tmp/strip
//   upsetting --no-plots --check 1e-6         (exit 1 if the plate force misses V2/V1)
//
// Frictionless upsetting is homogeneous: the billet stays a rectangle and the
// plate force is the exact V2 (V1) force on each configuration; exact.csv
// compares them step by step.
#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <maxentflow/maxentflow.hpp>
#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV

#include "common/friction.hpp"
#include "common/plotting.hpp"
#include "common/restart.hpp"

namespace fs = std::filesystem;
using namespace maxentflow;

namespace {

struct Options {
  bool plane_strain = false, no_plots = false, verbose = false;
  int nx = 21, ny = 25, steps = 100, vtu_every = 10;
  double tol0 = StepperParams{}.tol0;
  double radius = 10, height = 12, V = 0.06, dt = 1.0, gamma = 1.6, Cs = 0.5, mu0 = 150, n = 0.2;
  double alpha = 1.3, check = -1;
  std::string out = "results/upsetting", node_update = "ab2";
  examples::FrictionOptions friction;
  examples::RestartOptions restart;
};

// The largest radius of the nodes in contact with the top plate (tool 1).
double top_contact_radius(const Stepper<NortonHoff>& sim) {
  double r = 0;
  const auto& x = sim.nodes_solved();
  for (Eigen::Index a = 0; a < x.cols(); ++a)
    if (sim.contact_flags()[static_cast<std::size_t>(a)] == 2 && x(1, a) > 0.5 * x.row(1).maxCoeff())
      r = std::max(r, x(0, a));
  return r;
}

// Barrelling at the last solve: the free side's radial velocity at mid-height
// less that at the top plate's edge, over the homogeneous e R / 2 (e x in
// plane strain): 0 without friction.
double barrel_rate(const Stepper<NortonHoff>& sim, bool axi, double V) {
  const auto& x = sim.nodes_solved();
  const double R = x.row(0).maxCoeff(), H = x.row(1).maxCoeff() - x.row(1).minCoeff();
  int mid = -1, top = -1;
  for (Eigen::Index a = 0; a < x.cols(); ++a) {
    if (x(0, a) < R - 1e-6 * R) continue;
    if (mid < 0 || std::abs(x(1, a) - H / 2) < std::abs(x(1, mid) - H / 2)) mid = static_cast<int>(a);
    if (top < 0 || x(1, a) > x(1, top)) top = static_cast<int>(a);
  }
  const double homogeneous = (axi ? 0.5 : 1.0) * V / H * R;
  return (sim.velocity()(0, mid) - sim.velocity()(0, top)) / homogeneous;
}

void add_options(CLI::App& app, Options& o) {
  app.add_flag("--plane-strain", o.plane_strain, "Plane strain (a strip of half width --radius) instead of axisymmetric");
  app.add_option("--nx", o.nx, "Nodes across the radius (half width)")->check(CLI::Range(3, 2000));
  app.add_option("--ny", o.ny, "Nodes along the height")->check(CLI::Range(3, 2000));
  app.add_option("--steps", o.steps, "Time steps")->check(CLI::Range(1, 100000));
  app.add_option("--dt", o.dt, "Time step")->check(CLI::PositiveNumber);
  app.add_option("--radius", o.radius, "Billet radius (half width in plane strain)")->check(CLI::PositiveNumber);
  app.add_option("--height", o.height, "Billet height")->check(CLI::PositiveNumber);
  app.add_option("--velocity", o.V, "Top plate speed")->check(CLI::PositiveNumber);
  app.add_option("--gamma", o.gamma, "Max-ent locality gamma")->check(CLI::PositiveNumber);
  app.add_option("--tol0", o.tol0, "Max-ent support cut-off on the prior weight")->check(CLI::Range(1e-300, 0.5));
  app.add_option("--Cs", o.Cs, "Stabilization constant Cs (Eq. 14)")->check(CLI::NonNegativeNumber);
  app.add_option("--alpha", o.alpha, "Alpha-shape parameter (circumradius <= alpha h)")->check(CLI::PositiveNumber);
  app.add_option("--mu0", o.mu0, "Norton-Hoff mu0")->check(CLI::PositiveNumber);
  app.add_option("--n", o.n, "Norton-Hoff exponent n")->check(CLI::PositiveNumber);
  app.add_option("--vtu-every", o.vtu_every, "Write a VTU every this many steps (and at steps 1, mid, last)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--node-update", o.node_update,
                 "How nodes move: euler (Eq. 18) or ab2 (Adams-Bashforth 2 on each node's velocity history)")
      ->check(CLI::IsMember({"euler", "ab2"}));
  app.add_option("--out-dir", o.out, "Results folder");
  app.add_flag("--no-plots", o.no_plots, "Skip the PNG figures");
  app.add_flag("--verbose", o.verbose, "Log every nonlinear iteration");
  o.friction.add_to(app);
  o.restart.add_to(app);
  app.add_option("--check", o.check, "Fail (exit 1) if the plate force misses the exact one by more than this");
}

// The exact plate force (V2 axisymmetric, V1 plane strain) of a homogeneous
// compression at plate speed V of a billet of height H and radius R.
double exact_force(const NortonHoff& material, bool axi, double V, double H, double R) {
  const double e = V / H, d = axi ? e : 2 * e / std::sqrt(3.0);
  const double mu = material.viscosity(d).mu;
  return axi ? 3 * mu * e * M_PI * R * R : 4 * mu * e * R;
}

}  // namespace

int main(int argc, char** argv) {
  // 1. Options: every parameter of the case on the command line.
  CLI::App app{"maxentflow E1: upsetting (paper Fig. 5; frictionless unless a friction option is given)"};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  set_blas_threads(1);  // the cores go to the OpenMP loops (parallel.hpp)
  const bool axi = !o.plane_strain;
  if (o.restart.restarting()) o.out = o.restart.dir;
  if (!(o.steps * o.dt * o.V < o.height)) {
    std::cerr << "upsetting: the stroke --steps x --dt x --velocity = " << o.steps * o.dt * o.V
              << " would close the gap between the plates (--height " << o.height << ")\n";
    return 2;
  }
  const fs::path dir(o.out);
  if (o.check >= 0 && !o.friction.frictionless()) {
    std::cerr << "upsetting: --check compares with the exact frictionless solution; it does not apply with "
              << o.friction.describe() << " friction\n";
    return 2;
  }
  try {
    // 2. Nodes: a regular grid on the billet's half section (r or x, z).
    Eigen::Matrix2Xd x(2, o.nx * o.ny);
    for (int j = 0; j < o.ny; ++j)
      for (int i = 0; i < o.nx; ++i) x.col(j * o.nx + i) << o.radius * i / (o.nx - 1), o.height * j / (o.ny - 1);

    // 3. The stepper: max-ent basis (gamma), alpha-shape mesh, stabilized
    //    flow (Cs), Norton-Hoff material with d_min far below V / H.
    StepperParams prm;
    prm.geometry = axi ? Geometry::axisymmetric : Geometry::plane_strain;
    prm.dt = o.dt;
    prm.gamma = o.gamma;
    prm.tol0 = o.tol0;
    prm.mesh.alpha = o.alpha;
    prm.stabilization.Cs = o.Cs;
    prm.node_update = o.node_update == "ab2" ? NodeUpdate::adams_bashforth2 : NodeUpdate::euler;
    const NortonHoff material(o.mu0, o.n, 1e-6 * o.V / o.height);
    Stepper<NortonHoff> sim(x, material, prm);

    // 4. Tools and conditions: two plates with the chosen friction law
    //    (frictionless by default), the top one moving down at V; v_r = 0 on
    //    the axis (v_x = 0 on the symmetry line).
    const double wide = 100 * (o.radius + o.height);
    const AnyContactLaw law = o.friction.law(o.V);
    sim.add_tool(flat_plate("bottom plate", {0, 0}, {0, 1}, wide), law);
    RigidTool top = flat_plate("top plate", {0, o.height}, {0, -1}, wide);
    top.set_velocity({0, -o.V});
    sim.add_tool(top, law);
    sim.add_velocity_condition({axi ? "axis" : "symmetry", on_line({0, 0}, {1, 0}, 1e-9 * o.radius), {1, 0}, 0.0});
    sim.set_log(&std::cout);
    if (o.verbose) sim.parameters().solver.log = &std::cout;

    // 5. March: each step's results, and the plate force against the exact
    //    one on the solved configuration and on the continuum path
    //    R^2 = R0^2 H0 / H (R = R0 H0 / H), which the nodes follow to O(dt^2)
    //    with AB2, O(dt) with Eq. (18).
    ResultsWriter results(dir);
    CsvTable exact({"step", "time", "stroke", "height", "radius", "force", "force_exact", "rel_error",
                    "force_continuum"});
    double worst = 0, worst_path = 0, worst_volume = 0, ratio_first = 0, ratio_last = 0, bulge = 0, barrel = 0;
    const double volume0 = axi ? M_PI * o.radius * o.radius * o.height : o.radius * o.height;
    // What the loop accumulates travels in the checkpoint with the stepper.
    double* const running[] = {&worst, &worst_path, &worst_volume, &ratio_first, &ratio_last, &bulge, &barrel};
    const std::string signature = examples::RestartOptions::signature(app);
    if (o.restart.restarting()) {
      examples::RestartOptions::resume(dir, signature, sim, results, o.steps, "upsetting", [&](CheckpointIn& in) {
        for (double* v : running) *v = in.get_double();
        exact.load(in);
      });
    }
    for (int k = sim.steps_done() + 1; k <= o.steps; ++k) {
      const auto& r = sim.step();
      const bool vtu = k == 1 || k == o.steps || k == (o.steps + 1) / 2 || k % o.vtu_every == 0;
      results.record(sim, vtu);
      const auto& xs = sim.nodes_solved();
      const double H = xs.row(1).maxCoeff() - xs.row(1).minCoeff(), R = xs.row(0).maxCoeff();
      const double F = exact_force(material, axi, o.V, H, R);
      const double Fc = exact_force(material, axi, o.V, H, axi ? o.radius * std::sqrt(o.height / H) : o.radius * o.height / H);
      const double Fh = r.tool_force[1].y(), err = std::abs(Fh - F) / F;
      worst = std::max(worst, err);
      worst_path = std::max(worst_path, std::abs(Fh - Fc) / Fc);
      worst_volume = std::max(worst_volume, std::abs((axi ? M_PI * R * R * H : R * H) / volume0 - 1));
      ratio_last = Fh / F;
      if (k == 1) {
        ratio_first = ratio_last;
        barrel = barrel_rate(sim, axi, o.V);
      }
      bulge = R - top_contact_radius(sim);
      exact.cell(k).cell(r.time - r.dt).cell(r.tool_stroke[1]).cell(H).cell(R).cell(Fh).cell(F).cell(err).cell(Fc);
      exact.end_row();
      if (o.restart.due(k, vtu))
        write_checkpoint(dir, signature, sim, results, [&](CheckpointOut& out) {
          for (const double* v : running) out.put(*v);
          exact.save(out);
        });
    }
    exact.write(dir / "exact.csv");

    // 6. Report, figures (pressure maps, force against stroke with the exact
    //    curve) and the --check.
    double total = 0;
    for (const auto& r : sim.history()) total += r.seconds;
    std::cout << "upsetting: " << o.steps << " steps, " << x.cols() << " nodes, " << total
              << " s; plate force vs exact (V" << (axi ? 2 : 1) << "): max relative error " << worst
              << "\n  against the continuum path: force " << worst_path << ", volume " << 100 * worst_volume
              << " % (node update " << o.node_update << ")\n";
    if (!o.friction.frictionless())
      std::cout << "  " << o.friction.describe() << ": plate force / frictionless exact " << ratio_first
                << " at step 1, " << ratio_last << " at the end; barrelling at step 1 (free side's v_r, "
                << "mid-height - plate edge, / homogeneous) " << barrel << "; bulge at the end (largest radius - "
                << "top contact radius) " << bulge << "\n";
    // One row per run: refinement studies collect these (examples/upsetting/README.md).
    CsvTable summary({"nx", "ny", "nodes", "law", "steps", "force_ratio_first", "force_ratio_last",
                      "barrel_rate_first", "bulge_last"});
    summary.cell(o.nx).cell(o.ny).cell(static_cast<int>(x.cols())).cell(o.friction.describe()).cell(o.steps)
        .cell(ratio_first).cell(ratio_last).cell(barrel).cell(bulge);
    summary.end_row();
    summary.write(dir / "summary.csv");
    std::cout << "results in " << dir << " (step.pvd: open in ParaView)\n";
    if (!o.no_plots) {
      std::ostringstream args;
      const int mid = (o.steps + 1) / 2;
      args << '"' << dir.string() << "\" --maps pressure:1," << mid << ',' << o.steps << " velocity_y:" << o.steps
           << " --force-tool \"top plate\" --exact exact.csv";
      examples::run_plot_script(fs::path(MAXENTFLOW_EXAMPLE_DIR) / "../common/plot_forming.py", args.str());
    }
    if (o.check >= 0 && !(worst <= o.check)) {
      std::cerr << "check failed: plate force error " << worst << " > " << o.check << "\n";
      return 1;
    }
  } catch (const Error& e) {
    std::cerr << "upsetting failed: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

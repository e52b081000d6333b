// Example: ring compression, the test engineers use to measure friction.
// A 6:3:2 ring (outer diameter : inner diameter : height) between flat plates,
// axisymmetric, compressed to 50 % of its height once per shear factor m; the
// change of the inner diameter at mid-height against the height reduction is
// the calibration chart a measured ring is read against.
//
//   ring_compression                               (m = 0, 0.05, 0.1, 0.2, 0.3, 0.5, 1)
//   ring_compression --m 0,0.1,1 --steps 25 --no-plots --check
//
// Half the ring is solved (the mid-plane is a symmetry line, v_z = 0); the
// top plate carries Tresca friction (frictionless for m = 0). With m = 0 the
// flow is homogeneous and the inner radius follows r_i = r_i0 sqrt(H0 / H)
// (incompressible); friction holds the faces back, and from some m on the
// material flows toward the axis and the hole closes.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <maxentflow/maxentflow.hpp>
#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV

#include "common/plotting.hpp"
#include "common/restart.hpp"

namespace fs = std::filesystem;
using namespace maxentflow;

namespace {

struct Options {
  std::vector<double> m = {0, 0.05, 0.1, 0.2, 0.3, 0.5, 1};
  int nr = 21, nz = 11, steps = 50, vtu_every = 10;
  double outer = 30, inner = 15, height = 10, V = 0.1, reduction = 0.5;
  double gamma = 1.6, Cs = 0.5, alpha = 1.3, mu0 = 150, n = 0.2, v0_rel = 1e-2;
  double homogeneous_tol = 1e-3;
  bool check = false, no_plots = false;
  std::string out = "results/ring_compression";
  examples::RestartOptions restart;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("--m", o.m, "Tresca shear factors, one run each (comma separated)")
      ->delimiter(',')
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--nr", o.nr, "Nodes across the wall (radially)")->check(CLI::Range(3, 2000));
  app.add_option("--nz", o.nz, "Nodes along the half height")->check(CLI::Range(3, 2000));
  app.add_option("--steps", o.steps, "Time steps to the final reduction")->check(CLI::Range(1, 100000));
  app.add_option("--outer", o.outer, "Outer diameter")->check(CLI::PositiveNumber);
  app.add_option("--inner", o.inner, "Inner diameter")->check(CLI::PositiveNumber);
  app.add_option("--height", o.height, "Ring height")->check(CLI::PositiveNumber);
  app.add_option("--reduction", o.reduction, "Final height reduction (fraction)")->check(CLI::Range(0.01, 0.8));
  app.add_option("--velocity", o.V, "Plate speed (each plate; the half model moves one)")->check(CLI::PositiveNumber);
  app.add_option("--friction-v0", o.v0_rel,
                 "Tresca smoothing: slip velocity, relative to the plate speed, below which the friction stress "
                 "falls off linearly")
      ->check(CLI::Range(1e-6, 1.0));
  app.add_option("--gamma", o.gamma, "Max-ent locality gamma")->check(CLI::PositiveNumber);
  app.add_option("--Cs", o.Cs, "Stabilization constant Cs (Eq. 14)")->check(CLI::NonNegativeNumber);
  app.add_option("--alpha", o.alpha, "Alpha-shape parameter (circumradius <= alpha h)")->check(CLI::PositiveNumber);
  app.add_option("--mu0", o.mu0, "Norton-Hoff mu0")->check(CLI::PositiveNumber);
  app.add_option("--n", o.n, "Norton-Hoff exponent n")->check(CLI::PositiveNumber);
  app.add_option("--vtu-every", o.vtu_every, "Write a VTU every this many steps (and at steps 1 and last)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--out-dir", o.out, "Results folder (one subfolder per m)");
  app.add_flag("--no-plots", o.no_plots, "Skip the PNG chart");
  o.restart.add_to(app);
  app.add_flag("--check", o.check,
               "Exit 1 unless m = 0 follows r_i0 sqrt(H0/H) within --homogeneous-tol, the largest m closes the "
               "hole (inner diameter change < 0) and the change at the end falls as m rises");
  app.add_option("--homogeneous-tol", o.homogeneous_tol, "Relative tolerance of the m = 0 check")
      ->check(CLI::PositiveNumber);
}

// The inner radius at mid-height: the smallest r of the nodes within tol of
// the mid-plane (its row of nodes: the symmetry condition is imposed weakly,
// so a node there may leave z = 0 by round-off-sized amounts).
double inner_radius(const Eigen::Matrix2Xd& x, double tol) {
  double r = std::numeric_limits<double>::infinity();
  for (Eigen::Index a = 0; a < x.cols(); ++a)
    if (std::abs(x(1, a)) <= tol) r = std::min(r, x(0, a));
  return r;
}

struct RingRun {
  double m = 0;
  std::vector<double> reduction, id_change;  // per step, percent
  double worst_homogeneous = 0;              // max |r_i / (r_i0 sqrt(H0/H)) - 1|
  double seconds = 0;
};

// One ring compressed to o.reduction with shear factor m on the plate, in
// dir; with --restart, from dir's checkpoint if it has one (a finished run's
// last checkpoint gives its figures back without a step).
RingRun compress(const Options& o, double m, const fs::path& dir, const std::string& signature) {
  const double ri0 = 0.5 * o.inner, ro = 0.5 * o.outer, h0 = 0.5 * o.height;  // half model
  Eigen::Matrix2Xd x(2, o.nr * o.nz);
  for (int j = 0; j < o.nz; ++j)
    for (int i = 0; i < o.nr; ++i)
      x.col(j * o.nr + i) << ri0 + (ro - ri0) * i / (o.nr - 1), h0 * j / (o.nz - 1);
  StepperParams prm;
  prm.geometry = Geometry::axisymmetric;
  const double stroke = o.reduction * h0;
  prm.dt = stroke / (o.V * o.steps);
  prm.gamma = o.gamma;
  prm.mesh.alpha = o.alpha;
  prm.stabilization.Cs = o.Cs;
  const NortonHoff material(o.mu0, o.n, 1e-6 * o.V / h0);
  Stepper<NortonHoff> sim(x, material, prm);
  RigidTool top = flat_plate("top plate", {0, h0}, {0, -1}, 100 * (ro + h0));
  top.set_velocity({0, -o.V});
  const AnyContactLaw law = m == 0 ? AnyContactLaw(Frictionless{}) : AnyContactLaw(Tresca(m, o.v0_rel * o.V));
  sim.add_tool(top, law);
  sim.add_velocity_condition({"mid-plane", on_line({0, 0}, {0, 1}, 1e-9 * h0), {0, 1}, 0.0});

  RingRun run;
  run.m = m;
  ResultsWriter results(dir);
  if (o.restart.restarting() && fs::exists(checkpoint_file(dir)))
    read_checkpoint(dir, signature, sim, results, [&](CheckpointIn& in) {
      const Eigen::MatrixXd red = in.get_matrix(), id = in.get_matrix();
      run.reduction.assign(red.data(), red.data() + red.size());
      run.id_change.assign(id.data(), id.data() + id.size());
      run.worst_homogeneous = in.get_double();
      run.seconds = in.get_double();
    });
  if (sim.steps_done() > 0)
    std::cout << "m = " << m << ": restarted from " << checkpoint_file(dir) << " after step " << sim.steps_done() << "\n";
  for (int k = sim.steps_done() + 1; k <= o.steps; ++k) {
    const StepRecord& r = sim.step();
    const bool vtu = k == 1 || k == o.steps || k % o.vtu_every == 0;
    results.record(sim, vtu);
    run.seconds += r.seconds;
    // The configuration at the step's end: the nodes after their move.
    const double h = h0 - o.V * r.time;
    const double ri = inner_radius(sim.nodes(), 0.25 * h / (o.nz - 1));
    run.reduction.push_back(100 * (1 - h / h0));
    run.id_change.push_back(100 * (ri / ri0 - 1));
    if (m == 0) run.worst_homogeneous = std::max(run.worst_homogeneous, std::abs(ri / (ri0 * std::sqrt(h0 / h)) - 1));
    if (o.restart.due(k, vtu))
      write_checkpoint(dir, signature, sim, results, [&](CheckpointOut& out) {
        out.put(Eigen::Map<const Eigen::VectorXd>(run.reduction.data(), static_cast<Eigen::Index>(run.reduction.size())))
            .put(Eigen::Map<const Eigen::VectorXd>(run.id_change.data(), static_cast<Eigen::Index>(run.id_change.size())))
            .put(run.worst_homogeneous)
            .put(run.seconds);
      });
  }
  return run;
}

// The m at which the inner diameter stops growing at the final reduction
// (linear between the two runs whose changes bracket zero; NaN if none do).
double neutral_m(std::vector<RingRun> runs) {
  std::sort(runs.begin(), runs.end(), [](const RingRun& a, const RingRun& b) { return a.m < b.m; });
  for (std::size_t i = 0; i + 1 < runs.size(); ++i) {
    const double a = runs[i].id_change.back(), b = runs[i + 1].id_change.back();
    if (a >= 0 && b < 0) return runs[i].m + (runs[i + 1].m - runs[i].m) * a / (a - b);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

int failed_checks(const Options& o, const std::vector<RingRun>& runs) {
  int failed = 0;
  for (const auto& r : runs)
    if (r.m == 0 && !(r.worst_homogeneous <= o.homogeneous_tol)) {
      std::cerr << "check failed: m = 0 inner radius off the homogeneous r_i0 sqrt(H0/H) by "
                << r.worst_homogeneous << "\n";
      ++failed;
    }
  std::vector<RingRun> sorted = runs;
  std::sort(sorted.begin(), sorted.end(), [](const RingRun& a, const RingRun& b) { return a.m < b.m; });
  for (std::size_t i = 0; i + 1 < sorted.size(); ++i)
    if (!(sorted[i + 1].id_change.back() < sorted[i].id_change.back())) {
      std::cerr << "check failed: the inner diameter change does not fall from m = " << sorted[i].m << " to "
                << sorted[i + 1].m << "\n";
      ++failed;
    }
  if (!sorted.empty() && sorted.back().m >= 0.5 && !(sorted.back().id_change.back() < 0)) {
    std::cerr << "check failed: m = " << sorted.back().m << " does not close the hole\n";
    ++failed;
  }
  return failed;
}

}  // namespace

int main(int argc, char** argv) {
  // 1. Options: the ring, the list of m, the material and the method's parameters.
  CLI::App app{"maxentflow ring compression: the friction calibration chart (6:3:2 ring, Tresca m)"};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  set_blas_threads(1);  // the cores go to the OpenMP loops (parallel.hpp)
  if (!(o.inner < o.outer)) {
    std::cerr << "ring_compression: --inner " << o.inner << " must be below --outer " << o.outer << "\n";
    return 2;
  }
  if (o.restart.restarting()) o.out = o.restart.dir;
  const fs::path dir(o.out);
  try {
    // 2. One compression per m, each in its own folder; the chart's points
    //    in calibration.csv.
    std::vector<RingRun> runs;
    const std::string signature = examples::RestartOptions::signature(app);
    for (double m : o.m) {
      std::ostringstream name;
      name << "m_" << m;
      runs.push_back(compress(o, m, dir / name.str(), signature));
      const RingRun& r = runs.back();
      std::cout << "m = " << m << ": inner diameter change " << r.id_change.back() << " % at "
                << r.reduction.back() << " % reduction (" << r.seconds << " s)";
      if (m == 0) std::cout << "; off the homogeneous solution by " << r.worst_homogeneous;
      std::cout << "\n";
    }
    CsvTable table({"m", "reduction", "inner_diameter_change"});
    for (const RingRun& r : runs)
      for (std::size_t k = 0; k < r.reduction.size(); ++k) {
        table.cell(r.m).cell(r.reduction[k]).cell(r.id_change[k]);
        table.end_row();
      }
    table.write(dir / "calibration.csv");
    std::cout << "inner diameter stops growing at m = " << neutral_m(runs) << " (at " << 100 * o.reduction
              << " % reduction)\nresults in " << dir << " (calibration.csv, m_*/step.pvd)\n";

    // 3. The chart, and the --check.
    if (!o.no_plots)
      examples::run_plot_script(fs::path(MAXENTFLOW_EXAMPLE_DIR) / "plot_calibration.py", '"' + dir.string() + '"');
    if (o.check && failed_checks(o, runs) > 0) return 1;
  } catch (const Error& e) {
    std::cerr << "ring_compression failed: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

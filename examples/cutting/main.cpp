// Example E3 (docs/cases.md; the paper's Fig. 8): plane-strain orthogonal
// cutting with a rigid, frictionless tool. The chip separates by the flow
// round the tool tip and the alpha-shape alone: no separation criterion, no
// remeshing.
//
//   cutting                                  (E3: 122 x 41 nodes, 350 steps, dt = 2e-5)
//   cutting --nx 61 --ny 21 --steps 200 --dt 4e-5 --out-dir /tmp/e3
//   cutting --no-plots --check               (exit 1 if a physical check fails)
//
// Workpiece [0, L] x [0, H], bottom and left edges fixed; the tool's tip at
// height H - t0 starts just right of the workpiece and moves -x at V.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <maxentflow/maxentflow.hpp>
#include <maxentflow/solver/blas_gemv_forward.hpp>  // this program's one translation unit: MUMPS's one-column solves by GEMV

#include "common/friction.hpp"
#include "common/load_steadiness.hpp"
#include "common/plotting.hpp"
#include "common/restart.hpp"
#include "cutting/cutting_case.hpp"

namespace fs = std::filesystem;
using namespace maxentflow;

namespace {

constexpr double deg = std::numbers::pi / 180.0;

struct Options {
  examples::CuttingSetup s;
  int steps = 350, vtu_every = 35;
  double area_tol = 0.02, plateau_tol = 0.10, ratio_tol = 0.05;
  bool no_plots = false, check = false, verbose = false;
  std::string out = "results/cutting";
  examples::FrictionOptions friction;
  examples::RestartOptions restart;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("--nx", o.s.nx, "Workpiece nodes along the cut")->check(CLI::Range(8, 4000));
  app.add_option("--ny", o.s.ny, "Workpiece nodes across the height")->check(CLI::Range(4, 4000));
  app.add_option("--steps", o.steps, "Time steps")->check(CLI::Range(1, 1000000));
  app.add_option("--dt", o.s.dt, "Time step")->check(CLI::PositiveNumber);
  app.add_option("--length", o.s.length, "Workpiece length")->check(CLI::PositiveNumber);
  app.add_option("--height", o.s.height, "Workpiece height")->check(CLI::PositiveNumber);
  app.add_option("--velocity", o.s.V, "Cutting speed (the tool moves -x)")->check(CLI::PositiveNumber);
  app.add_option("--t0", o.s.t0, "Uncut chip thickness (depth of cut)")->check(CLI::PositiveNumber);
  app.add_option("--rake", o.s.rake, "Rake angle, degrees")->check(CLI::Range(-30.0, 45.0));
  app.add_option("--clearance", o.s.clearance, "Clearance angle, degrees")->check(CLI::Range(0.5, 30.0));
  app.add_option("--edge-radius", o.s.edge_radius, "Cutting edge radius (0: sharp)")->check(CLI::NonNegativeNumber);
  app.add_option("--gamma", o.s.gamma, "Max-ent locality gamma")->check(CLI::PositiveNumber);
  app.add_option("--tol0", o.s.tol0, "Max-ent support cut-off on the prior weight")->check(CLI::Range(1e-300, 0.5));
  app.add_option("--tol", o.s.tol, "Newton's tolerance on the relative velocity increment and residual")
      ->check(CLI::Range(1e-14, 1e-2));
  app.add_option("--Cs", o.s.Cs, "Stabilization constant Cs (Eq. 14)")->check(CLI::NonNegativeNumber);
  app.add_option("--alpha", o.s.alpha, "Alpha-shape parameter (circumradius <= alpha h)")->check(CLI::PositiveNumber);
  app.add_option("--mu0", o.s.mu0, "Norton-Hoff mu0")->check(CLI::PositiveNumber);
  app.add_option("--dmin", o.s.d_min, "Norton-Hoff regularization d_min, relative to V / t0")
      ->check(CLI::Range(1e-12, 0.1));
  app.add_option("--n", o.s.n, "Norton-Hoff exponent n")->check(CLI::PositiveNumber);
  app.add_flag("--no-rezone{false}", o.s.rezone, "Keep the initial nodes (no node removal or insertion)");
  app.add_flag("!--no-zone", o.s.zone, "No Eulerian zone round the tool's tip (every node Lagrangian)");
  app.add_option("--zone-front", o.s.zone_front, "Eulerian zone: extent ahead of the tip, in t0")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--zone-depth", o.s.zone_depth, "Eulerian zone: depth below the tip, in t0")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--zone-back", o.s.zone_back, "Eulerian zone: extent behind the tip, in t0")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--zone-strip", o.s.zone_strip, "Eulerian zone: the chip's strip along the rake face, width in t0")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--zone-rise", o.s.zone_rise, "Eulerian zone: the strip's height above the uncut surface, in t0")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--vtu-every", o.vtu_every, "Write a VTU every this many steps (and at steps 1 and last)")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--out-dir", o.out, "Results folder");
  app.add_flag("--no-plots", o.no_plots, "Skip the PNG figures");
  app.add_flag("--verbose", o.verbose, "Log every nonlinear iteration");
  o.friction.add_to(app);
  o.restart.add_to(app);
  app.add_flag("--check", o.check,
               "Exit 1 unless: no penetration, area change < --area-tol, Ft/Fc within --ratio-tol of "
               "-tan(rake) (frictionless) and, on a cut of at least 5 t0, the cutting force on a plateau "
               "(last 30 % of the steps within --plateau-tol of their mean)");
  app.add_option("--area-tol", o.area_tol, "Largest area change --check accepts")->check(CLI::PositiveNumber);
  app.add_option("--plateau-tol", o.plateau_tol, "Cutting force band --check accepts")->check(CLI::PositiveNumber);
  app.add_option("--ratio-tol", o.ratio_tol, "Ft/Fc distance from -tan(rake) --check accepts")
      ->check(CLI::PositiveNumber);
}

// The tool's frame: tip, rake-face direction (from the tip up the face) and
// its outward normal (toward the chip).
struct ToolFrame {
  Eigen::Vector2d tip, along, normal;
  ToolFrame(const Options& o, double travel)
      : tip(o.s.tip_start() - Eigen::Vector2d(travel, 0)),
        along(std::sin(o.s.rake * deg), std::cos(o.s.rake * deg)),
        normal(-std::cos(o.s.rake * deg), std::sin(o.s.rake * deg)) {}
};

// The tool's normal contact force on its clearance face (the first piece,
// from the flank's end to the tip) and on the whole tool, lumped: a node in
// contact carries its contact pressure times half its boundary edges.
std::pair<double, double> contact_force_split(const Stepper<NortonHoff>& sim) {
  const auto& x = sim.nodes();
  const Eigen::MatrixXd& pn = sim.nodal_field("contact_pressure");
  std::vector<double> len(static_cast<std::size_t>(x.cols()), 0.0);
  for (const auto& seg : sim.mesh().boundary_segments()) {
    const double l = 0.5 * (x.col(seg.b) - x.col(seg.a)).norm();
    len[static_cast<std::size_t>(seg.a)] += l;
    len[static_cast<std::size_t>(seg.b)] += l;
  }
  double clearance = 0, all = 0;
  for (int a : sim.mesh().boundary_nodes()) {
    const double f = std::abs(pn(0, a)) * len[static_cast<std::size_t>(a)];
    all += f;
    if (f > 0 && sim.tools()[0].closest(x.col(a)).piece == 0) clearance += f;
  }
  return {clearance, all};
}

// The chip thickness on a configuration: along the rake face's normal, from
// the face to the chip's free surface, at stations 1.5 t0 to 3 t0 up the face
// (above the uncut surface) where the chip's back still lies on the face;
// the least of them, since the chip's root below and its curl above both
// read thicker along that normal. NaN where there are none (no chip yet).
double chip_thickness(const Options& o, const Stepper<NortonHoff>& sim, const ToolFrame& f) {
  const auto& x = sim.nodes_solved();
  const double h = o.s.spacing();
  double best = std::numeric_limits<double>::infinity();
  for (double st = 1.5; st <= 3.0 + 1e-9; st += 0.25) {
    const Eigen::Vector2d p = f.tip + st * o.s.t0 * f.along;
    if (p.y() <= o.s.height) continue;
    // Crossings of the ray p + u normal (u > 0) with the boundary.
    std::vector<double> u;
    for (const auto& seg : sim.mesh().boundary_segments()) {
      const Eigen::Vector2d a = x.col(seg.a), d = x.col(seg.b) - a;
      const double det = f.normal.x() * -d.y() + f.normal.y() * d.x();
      if (std::abs(det) < 1e-14 * d.norm()) continue;
      const Eigen::Vector2d r = a - p;
      const double ui = (r.x() * -d.y() + r.y() * d.x()) / det;
      const double wi = (f.normal.x() * r.y() - f.normal.y() * r.x()) / det;
      if (wi >= 0 && wi <= 1 && ui > -0.25 * h) u.push_back(ui);
    }
    // On the face: the chip's back (within h/4 of it), then its far side.
    std::sort(u.begin(), u.end());
    if (u.size() >= 2 && u[0] <= 0.25 * h) best = std::min(best, u[1] - u[0]);
  }
  return std::isfinite(best) ? best : std::nan("");
}

// Shear angle from the chip ratio r = t0 / tc: tan(phi) = r cos(a) / (1 - r sin(a)).
double shear_angle_deg(double t0, double tc, double rake_deg) {
  const double r = t0 / tc, a = rake_deg * deg;
  return std::atan2(r * std::cos(a), 1 - r * std::sin(a)) / deg;
}

// The mean effective strain rate of the nodes within h of the shear plane
// (from the tip at angle phi to the free surface).
double shear_zone_rate(const Options& o, const Stepper<NortonHoff>& sim, const ToolFrame& f, double phi_deg) {
  const double phi = phi_deg * deg, h = o.s.spacing();
  const Eigen::Vector2d e(-std::cos(phi), std::sin(phi));
  const double len = o.s.t0 / std::sin(phi);
  const auto& x = sim.nodes_solved();
  double sum = 0;
  int count = 0;
  for (Eigen::Index a = 0; a < x.cols(); ++a) {
    const Eigen::Vector2d r = x.col(a) - f.tip;
    const double s = r.dot(e);
    if (s < 0 || s > len || std::abs(r.x() * e.y() - r.y() * e.x()) > h) continue;
    sum += sim.strain_rate()[a];
    ++count;
  }
  return count > 0 ? sum / count : std::nan("");
}

}  // namespace

int main(int argc, char** argv) {
  // 1. Options: every parameter of the case on the command line.
  CLI::App app{"maxentflow E3: orthogonal cutting (paper Fig. 8; frictionless unless a friction option is given)"};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  set_blas_threads(1);  // the cores go to the OpenMP loops (parallel.hpp)
  if (o.restart.restarting()) o.out = o.restart.dir;
  const double h = o.s.spacing();
  if (!(o.s.t0 < 0.5 * o.s.height)) {
    std::cerr << "cutting: --t0 " << o.s.t0 << " must be less than half the workpiece height (--height " << o.s.height
              << ")\n";
    return 2;
  }
  if (!(o.steps * o.s.dt * o.s.V < 0.75 * o.s.length)) {
    std::cerr << "cutting: the cut length --steps x --dt x --velocity = " << o.steps * o.s.dt * o.s.V
              << " must stay below 3/4 of the workpiece (--length " << o.s.length << ")\n";
    return 2;
  }
  if (!(o.s.edge_radius <= 0.5 * h)) {
    std::cerr << "cutting: --edge-radius " << o.s.edge_radius << " exceeds half the node spacing (" << 0.5 * h
              << "): the nodes would not resolve it\n";
    return 2;
  }
  if (o.s.zone && o.s.edge_radius > 0) {
    std::cout << "cutting: no Eulerian zone at the tip (it needs a sharp tool); every node is Lagrangian\n";
    o.s.zone = false;
  }
  const fs::path dir(o.out);
  try {
    // 2-4. The case: the workpiece grid, the stepper (rezoning on), the tool
    //      with its law and the fixed edges (cutting_case.hpp).
    o.s.law = o.friction.law(o.s.V);
    Stepper<NortonHoff> sim = examples::make_cutting(o.s);
    const NortonHoff& material = sim.material();
    const int nodes0 = o.s.nx * o.s.ny;
    sim.set_log(&std::cout);
    if (o.verbose) sim.parameters().solver.log = &std::cout;

    // 5. March: forces and the chip's thickness per step.
    ResultsWriter results(dir);
    CsvTable forces({"step", "time", "cut_length", "Fc", "Ft"});
    CsvTable chip({"step", "time", "cut_length", "chip_thickness", "shear_angle_deg"});
    const double area0 = o.s.length * o.s.height;
    double worst_area = 0, min_gap = 0, clearance_force = 0, contact_force = 0;
    double* const running[] = {&worst_area, &min_gap, &clearance_force, &contact_force};
    const int window_from = o.steps - std::max(1, static_cast<int>(0.3 * o.steps));  // the report's window
    const std::string signature = examples::RestartOptions::signature(app);
    if (o.restart.restarting())
      examples::RestartOptions::resume(dir, signature, sim, results, o.steps, "cutting", [&](CheckpointIn& in) {
        for (double* v : running) *v = in.get_double();
        forces.load(in);
        chip.load(in);
      });
    const double gap0 = o.s.tip_start().x() - o.s.length;
    // The pressure maps at a third and two thirds of the run need their VTUs.
    const int map_steps[2] = {std::max(1, o.steps / 3), std::max(1, 2 * o.steps / 3)};
    for (int k = sim.steps_done() + 1; k <= o.steps; ++k) {
      const auto& r = sim.step();
      const bool vtu = k == 1 || k == o.steps || k % o.vtu_every == 0 || k == map_steps[0] || k == map_steps[1];
      results.record(sim, vtu);
      const double travel = r.tool_stroke[0], cut = std::max(0.0, travel - gap0);
      const double t_start = r.time - r.dt;
      forces.cell(k).cell(t_start).cell(cut).cell(r.tool_force[0].x()).cell(r.tool_force[0].y());
      forces.end_row();
      const ToolFrame f(o, travel);
      const double tc = chip_thickness(o, sim, f);
      if (std::isfinite(tc)) {
        chip.cell(k).cell(t_start).cell(cut).cell(tc).cell(shear_angle_deg(o.s.t0, tc, o.s.rake));
        chip.end_row();
      }
      if (k > window_from) {
        const auto [clearance, all] = contact_force_split(sim);
        clearance_force += clearance;
        contact_force += all;
      }
      worst_area = std::max(worst_area, std::abs(sim.mesh().total_area() / area0 - 1));
      for (int a : sim.mesh().boundary_nodes())
        min_gap = std::min(min_gap, sim.tools()[0].gap(sim.nodes().col(a)) / h);
      if (o.restart.due(k, vtu))
        write_checkpoint(dir, signature, sim, results, [&](CheckpointOut& out) {
          for (const double* v : running) out.put(*v);
          forces.save(out);
          chip.save(out);
        });
    }
    forces.write(dir / "cutting_forces.csv");
    chip.write(dir / "chip.csv");

    // 6. Report against Merchant's frictionless estimate and --check.
    const auto& hist = sim.history();
    const int n_steps = static_cast<int>(hist.size());
    const int from = n_steps - std::max(1, static_cast<int>(0.3 * n_steps));
    std::vector<double> fc_last;
    std::vector<const StepRecord*> window;
    double ft_mean = 0;
    for (int k = from; k < n_steps; ++k) {
      window.push_back(&hist[static_cast<std::size_t>(k)]);
      fc_last.push_back(hist[static_cast<std::size_t>(k)].tool_force[0].x());
      ft_mean += hist[static_cast<std::size_t>(k)].tool_force[0].y();
    }
    ft_mean /= n_steps - from;
    const examples::LoadSteadiness fc_steady = examples::load_steadiness(fc_last);
    const double fc_mean = fc_steady.mean, band = fc_steady.band();
    const double ratio = ft_mean / fc_mean, ratio_exact = -std::tan(o.s.rake * deg);
    const ToolFrame last(o, hist.back().tool_stroke[0]);
    const double tc = chip_thickness(o, sim, last);
    const double phi_merchant = 45 + 0.5 * o.s.rake;
    const double phi = std::isfinite(tc) ? shear_angle_deg(o.s.t0, tc, o.s.rake) : phi_merchant;
    const double d_shear = shear_zone_rate(o, sim, last, phi);
    const double k_shear = std::sqrt(3.0) * material.viscosity(d_shear).mu * d_shear;  // sigma_eq / sqrt(3)
    const double pm = phi_merchant * deg, a = o.s.rake * deg;
    const double fc_merchant = k_shear * o.s.t0 * (1 / std::tan(pm) + std::tan(pm - a));
    int added = 0, removed = 0;
    double total = 0;
    for (const auto& r : hist) {
      added += r.nodes_added;
      removed += r.nodes_removed;
      total += r.seconds;
    }
    std::cout << "cutting: " << n_steps << " steps, " << sim.nodes().cols() << " nodes (" << nodes0 << " at the "
              << "start, +" << added << " -" << removed << " by rezoning), " << total << " s\n"
              << "  max area change " << 100 * worst_area << " %, min gap " << min_gap << " h\n"
              << "  cutting force Fc over the last 30 % of the steps: " << fc_steady << "; Ft/Fc " << ratio
              << " (frictionless rake: -tan(rake) = " << ratio_exact << "); the clearance face carries "
              << 100 * clearance_force / std::max(contact_force, 1e-300)
              << " % of the normal contact force (lumped from the nodal pressures)\n"
              << "  chip thickness "
              << (std::isfinite(tc) ? detail::cat(tc, " (t0 ", o.s.t0, "), shear angle ", phi, " deg")
                                    : std::string("not measured (no chip above the uncut surface yet)"))
              << " (Merchant: t0, " << phi_merchant << " deg); Fc / Merchant's k t0 (cot phi + tan(phi - rake)) "
              << fc_mean / fc_merchant << " (k " << k_shear << " at the shear zone's mean strain rate "
              << d_shear << ")\n";
    if (window.size() > 1)
      std::cout << "  tool power (Fc x V) over the same steps: " << examples::power_shares(window, o.s.V) << "\n";
    std::cout << "results in " << dir << " (step.pvd: open in ParaView)\n";
    if (!o.no_plots) {
      std::ostringstream args;
      const int s1 = map_steps[0], s2 = map_steps[1];
      args << '"' << dir.string() << "\" --maps pressure:" << s1 << ',' << s2 << ',' << o.steps << " velocity_y:"
           << o.steps << " --mesh " << o.steps << " --cutting";
      examples::run_plot_script(fs::path(MAXENTFLOW_EXAMPLE_DIR) / "../common/plot_forming.py", args.str());
    }
    if (o.check) {
      int failed = 0;
      auto check = [&](bool ok, const std::string& what) {
        if (!ok) {
          std::cerr << "check failed: " << what << "\n";
          ++failed;
        }
      };
      check(min_gap >= -sim.parameters().penetration_tol, "a node inside the tool");
      check(worst_area < o.area_tol, "area changes by more than --area-tol");
      // A plateau needs the chip formed: the spec's run cuts 7 t0 and judges
      // its last 30 % (from 4.9 t0 on).
      if (hist.back().tool_stroke[0] - gap0 >= 5 * o.s.t0)
        check(band <= o.plateau_tol, "the cutting force is not on a plateau over the last 30 % of the steps");
      else
        std::cout << "  plateau not checked: the cut is shorter than 5 t0\n";
      if (o.friction.frictionless())
        check(std::abs(ratio - ratio_exact) <= o.ratio_tol, "Ft/Fc off -tan(rake) by more than --ratio-tol");
      if (failed > 0) return 1;
    }
  } catch (const Error& e) {
    std::cerr << "cutting failed: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

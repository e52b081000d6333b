// Example E2 (docs/cases.md; the paper's Figs. 6 and 7): plane-strain forward
// extrusion through a square die, half model, frictionless rigid tools.
//
//   extrusion                                 (E2: 32 x 32 nodes, 100 steps, dt = 0.3)
//   extrusion --nx 16 --ny 16 --steps 20 --out-dir /tmp/e2
//   extrusion --no-plots --check              (exit 1 if a physical check fails)
//   extrusion --convergence 16,32,64          (step-1 axis pressure on refined billets)
//
// Tools: the ram on x = 0 moving +x; the die (container wall y = H, die face
// x = L for y in [opening, H], die land y = opening for x in [L, L + land]);
// symmetry v_y = 0 on the axis y = 0. The product's free surface beyond the
// land comes from the alpha-shape alone.
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

#include "common/friction.hpp"
#include "common/load_steadiness.hpp"
#include "common/plotting.hpp"
#include "common/restart.hpp"
#include "extrusion/extrusion_case.hpp"

namespace fs = std::filesystem;
using namespace maxentflow;

namespace {

using examples::Setup;
using examples::to_model;
using examples::make_simulation;

// (along, across) of a model point: (x, y) in plane strain, (L - z, r) axisymmetric.
Eigen::Vector2d frame(const Setup& s, const Eigen::Vector2d& p) {
  return s.axisymmetric ? Eigen::Vector2d(s.length - p.y(), p.x()) : p;
}
Eigen::Matrix2Xd from_frame(const Setup& s, Eigen::Matrix2Xd q) {
  for (Eigen::Index a = 0; a < q.cols(); ++a) q.col(a) = to_model(s, q.col(a));
  return q;
}

// Material area (plane strain) or volume (axisymmetric, int 2 pi r) inside the alpha shape.
double material_measure(const Setup& s, const IntegrationMesh<>& mesh) {
  if (!s.axisymmetric) return mesh.total_area();
  double v = 0;
  for (std::size_t t = 0; t < mesh.triangles().size(); ++t) {
    double r = 0;
    for (int a : mesh.triangles()[t]) r += mesh.nodes()(0, a) / 3.0;
    v += 2 * M_PI * r * mesh.area(static_cast<int>(t));
  }
  return v;
}

// Step-1 pressure along the axis (x from 0 to L) and the die face (y from 0 to H on x = L).
struct Profiles {
  Eigen::VectorXd xs, p_axis, ys, p_die;
};
Profiles profiles(const Setup& s, const Stepper<NortonHoff>& sim, int points) {
  Profiles pr;
  pr.xs = Eigen::VectorXd::LinSpaced(points, 0.0, s.length);
  pr.ys = Eigen::VectorXd::LinSpaced(points, 0.0, s.height);
  Eigen::Matrix2Xd a(2, points), d(2, points);
  for (int i = 0; i < points; ++i) {
    a.col(i) << pr.xs[i], 0.0;
    d.col(i) << s.length, pr.ys[i];
  }
  pr.p_axis = sim.fields_at(from_frame(s, a)).row(2).transpose();
  pr.p_die = sim.fields_at(from_frame(s, d)).row(2).transpose();
  return pr;
}

void write_profiles(const fs::path& dir, const Profiles& pr) {
  CsvTable axis({"x", "p"}), die({"y", "p"});
  for (Eigen::Index i = 0; i < pr.xs.size(); ++i) {
    axis.cell(pr.xs[i]).cell(pr.p_axis[i]);
    axis.end_row();
    die.cell(pr.ys[i]).cell(pr.p_die[i]);
    die.end_row();
  }
  axis.write(dir / "profile_axis_step1.csv");
  die.write(dir / "profile_die_step1.csv");
}

// Step-1 pressure on refined billets against the finest (the reference, on
// the grid --grade asks for): rms and largest difference along the axis and
// the die-face line x = L, over the reference's largest |p| on that line, and
// the observed orders between successive sizes. With --grade g > 1 every
// coarser size runs on the uniform grid and on the graded one (same node
// count), and --check also requires the graded one closer on both lines.
int convergence(Setup s, std::vector<int> sides, const fs::path& dir, bool check) {
  fs::create_directories(dir);
  std::sort(sides.begin(), sides.end());
  sides.erase(std::unique(sides.begin(), sides.end()), sides.end());
  const double grade = s.grade;
  struct Run {
    int side;
    double grade;
    Profiles pr;
  };
  auto solve = [&](int side, double g) {
    s.nx = s.ny = side;
    s.grade = g;
    Stepper<NortonHoff> sim = make_simulation(s);
    sim.step();
    std::cout << "convergence: " << side << " x " << side << " nodes, grade " << g << ", step 1 in "
              << sim.history().back().seconds << " s, ram force " << sim.history().back().tool_force[0].x() << "\n";
    return Run{side, g, profiles(s, sim, 301)};
  };
  const Run fine = solve(sides.back(), grade);
  std::vector<Run> runs;
  for (std::size_t k = 0; k + 1 < sides.size(); ++k) {
    runs.push_back(solve(sides[k], 1.0));
    if (grade > 1.0) runs.push_back(solve(sides[k], grade));
  }
  struct Error {
    double axis_rms, axis_max, die_rms, die_max;
  };
  auto error = [&](const Profiles& p) {
    const Eigen::VectorXd da = p.p_axis - fine.pr.p_axis, dd = p.p_die - fine.pr.p_die;
    const double sa = fine.pr.p_axis.cwiseAbs().maxCoeff(), sd = fine.pr.p_die.cwiseAbs().maxCoeff();
    const auto rms = [](const Eigen::VectorXd& d) { return std::sqrt(d.squaredNorm() / static_cast<double>(d.size())); };
    return Error{rms(da) / sa, da.cwiseAbs().maxCoeff() / sa, rms(dd) / sd, dd.cwiseAbs().maxCoeff() / sd};
  };
  CsvTable t({"nodes_per_side", "grade", "axis_rms", "axis_max", "die_rms", "die_max", "axis_order", "die_order",
              "p_at_ram", "p_at_die"});
  std::cout << "  step-1 pressure against " << fine.side << " x " << fine.side << " (grade " << grade
            << "), relative to its largest |p| on each line:\n";
  bool decreasing = true, graded_closer = true;
  std::vector<const Run*> last(2, nullptr);  // the last run per grid kind (uniform, graded)
  std::vector<Error> last_error(2);
  for (const Run& r : runs) {
    const Error e = error(r.pr);
    const int kind = r.grade > 1.0 ? 1 : 0;
    double axis_order = std::nan(""), die_order = std::nan("");
    if (last[static_cast<std::size_t>(kind)]) {
      const double ratio = std::log(static_cast<double>(r.side) / last[static_cast<std::size_t>(kind)]->side);
      axis_order = std::log(last_error[static_cast<std::size_t>(kind)].axis_rms / e.axis_rms) / ratio;
      die_order = std::log(last_error[static_cast<std::size_t>(kind)].die_rms / e.die_rms) / ratio;
      decreasing = decreasing && e.axis_rms < last_error[static_cast<std::size_t>(kind)].axis_rms;
    }
    if (kind == 1) {
      const Error u = last_error[0];  // the uniform run of the same size came just before
      graded_closer = graded_closer && e.axis_rms < u.axis_rms && e.die_rms < u.die_rms;
    }
    last[static_cast<std::size_t>(kind)] = &r;
    last_error[static_cast<std::size_t>(kind)] = e;
    t.cell(r.side).cell(r.grade).cell(e.axis_rms).cell(e.axis_max).cell(e.die_rms).cell(e.die_max);
    t.cell(axis_order).cell(die_order).cell(r.pr.p_axis[0]).cell(r.pr.p_axis[r.pr.p_axis.size() - 1]);
    t.end_row();
    std::cout << "  " << r.side << " x " << r.side << ", grade " << r.grade << ": axis rms " << e.axis_rms
              << " (max " << e.axis_max << "), die face rms " << e.die_rms << " (max " << e.die_max << ")";
    if (!std::isnan(axis_order)) std::cout << ", observed orders " << axis_order << " / " << die_order;
    std::cout << "\n";
  }
  t.write(dir / "convergence_step1_pressure.csv");
  int failed = 0;
  if (check && runs.size() >= 2 && !decreasing) {
    std::cerr << "check failed: the step-1 axis pressure does not approach the finest billet's\n";
    failed = 1;
  }
  if (check && grade > 1.0 && !graded_closer) {
    std::cerr << "check failed: the graded billet is not closer to the finest than the uniform one on both lines\n";
    failed = 1;
  }
  return failed;
}

struct Options {
  bool no_plots = false, check = false, verbose = false;
  double area_tol = 0.03;
  double surface_tol = 0.25;  // in h, the uniform grid's spacing
  bool zone = false, no_zone = false;
  double load_rms_tol = std::numeric_limits<double>::infinity();  // not checked unless given
  double load_band_tol = std::numeric_limits<double>::infinity();  // not checked unless given
  double zone_from = std::numeric_limits<double>::quiet_NaN();
  int steps = 100, vtu_every = 10;
  std::string out = "results/extrusion", node_update = "ab2";
  std::vector<int> convergence;
  std::vector<double> load_window = {30, 130};
  examples::FrictionOptions friction;
  examples::RestartOptions restart;
};

void add_options(CLI::App& app, Setup& s, Options& o) {
  app.add_option("--nx", s.nx, "Billet nodes along the extrusion direction")->check(CLI::Range(4, 2000));
  app.add_option("--ny", s.ny, "Billet nodes across the half height")->check(CLI::Range(4, 2000));
  app.add_option("--steps", o.steps, "Time steps")->check(CLI::Range(1, 100000));
  app.add_option("--dt", s.dt, "Time step")->check(CLI::PositiveNumber);
  app.add_option("--length", s.length, "Billet length")->check(CLI::PositiveNumber);
  app.add_option("--height", s.height, "Billet half height (container radius)")->check(CLI::PositiveNumber);
  app.add_option("--reduction", s.reduction, "Reduction 1 - opening / height")->check(CLI::Range(0.05, 0.95));
  app.add_option("--land", s.land, "Die land length")->check(CLI::NonNegativeNumber);
  app.add_option("--die-radius", s.die_radius, "Radius of the die corner (0: square)")->check(CLI::NonNegativeNumber);
  app.add_option("--grade", s.grade,
                 "Billet nodes graded toward the die corner, same count: spacing h / grade there (1: uniform)")
      ->check(CLI::Range(1.0, 20.0));
  app.add_option("--velocity", s.V, "Ram speed")->check(CLI::PositiveNumber);
  app.add_option("--gamma", s.gamma, "Max-ent locality gamma")->check(CLI::PositiveNumber);
  app.add_option("--tol0", s.tol0, "Max-ent support cut-off on the prior weight")->check(CLI::Range(1e-300, 0.5));
  app.add_option("--Cs", s.Cs, "Stabilization constant Cs (Eq. 14)")->check(CLI::NonNegativeNumber);
  app.add_option("--alpha", s.alpha, "Alpha-shape parameter (circumradius <= alpha h)")->check(CLI::PositiveNumber);
  app.add_option("--mu0", s.mu0, "Norton-Hoff mu0")->check(CLI::PositiveNumber);
  app.add_option("--dmin", s.d_min, "Norton-Hoff regularization d_min, relative to V / length")
      ->check(CLI::Range(1e-12, 1e-1));
  app.add_option("--n", s.n, "Norton-Hoff exponent n")->check(CLI::PositiveNumber);
  app.add_flag("--axisymmetric", s.axisymmetric, "A round bar (axisymmetric) instead of plane strain");
  app.add_flag("!--no-rezone", s.rezone, "Keep the initial nodes (no node removal or insertion)");
  app.add_option("--node-update", o.node_update,
                 "How nodes move: euler (Eq. 18) or ab2 (Adams-Bashforth 2 on each node's velocity history)")
      ->check(CLI::IsMember({"euler", "ab2"}));
  app.add_option("--rezone-min", s.rezone_min, "Rezoning: remove a node on an edge shorter than this * h0")
      ->check(CLI::Range(0.05, 0.9));
  app.add_option("--rezone-max", s.rezone_max, "Rezoning: split an edge longer than this * h0")
      ->check(CLI::Range(1.2, 10.0));
  app.add_option("--rezone-min-spacing", s.rezone_min_spacing,
                 "Rezoning: remove a node on an edge shorter than this * the nodal spacing h_a (a crowded, "
                 "anisotropic cloud; 0: off)")
      ->check(CLI::Range(0.0, 0.9));
  auto* zone_flag =
      app.add_flag("--zone", o.zone,
                   "An Eulerian zone at the die: the container's end and the land keep their nodes in place once "
                   "the material fills them, from 2 h ahead of the ram's last position (eulerian_zone.hpp). The "
                   "default for a square die where the stroke leaves room for it; here an error "
                   "where it cannot be set");
  app.add_flag("--no-zone", o.no_zone, "No Eulerian zone: every node travels with the material (Lagrangian)")
      ->excludes(zone_flag);
  app.add_option("--zone-from", o.zone_from, "Where the Eulerian zone starts along the billet")
      ->check(CLI::PositiveNumber)
      ->excludes("--no-zone");
  app.add_option("--vtu-every", o.vtu_every, "Write a VTU every this many steps (and at steps 1, 10, last)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--out-dir", o.out, "Results folder");
  app.add_flag("--no-plots", o.no_plots, "Skip the PNG figures");
  o.friction.add_to(app);
  o.restart.add_to(app);
  app.add_flag("--verbose", o.verbose, "Log every nonlinear iteration");
  app.add_flag("--check", o.check,
               "Exit 1 unless: no penetration, area change < --area-tol, product width within 5 % of the "
               "die opening, its free surface within --surface-tol of the opening's line, step-1 axis pressure "
               "decreasing, die-face pressure peaking next to the die corner, the ram load steady to "
               "--load-rms-tol and --load-band-tol over --load-window where given");
  app.add_option("--area-tol", o.area_tol, "Largest area (volume) change --check accepts")->check(CLI::PositiveNumber);
  app.add_option("--surface-tol", o.surface_tol,
                 "Largest distance (in h = length / (nx - 1)) --check accepts between a node of the product's free "
                 "surface, from the land's end to 3 h before the nose's front face, and the opening's line")
      ->check(CLI::PositiveNumber);
  app.add_option("--load-rms-tol", o.load_rms_tol,
                 "Largest step-to-step change of the ram load (rms, relative to its mean) over --load-window "
                 "that --check accepts (not checked unless given)")
      ->check(CLI::PositiveNumber);
  app.add_option("--load-band-tol", o.load_band_tol,
                 "Largest deviation of the ram load from its mean over --load-window (relative) that --check "
                 "accepts (not checked unless given)")
      ->check(CLI::PositiveNumber);
  app.add_option("--load-window", o.load_window,
                 "Ram strokes (from,to) over which the ram load's steadiness is reported")
      ->delimiter(',')
      ->expected(2)
      ->check(CLI::NonNegativeNumber);
  app.add_option("--convergence", o.convergence,
                 "Only step 1 on billets of these nodes per side; compare the axis and die-face pressure with the finest")
      ->delimiter(',');
}

// What the run measured along the way.
struct RunMeasures {
  Profiles first;               // step-1 pressure profiles
  double max_area_change = 0;  // relative to the billet's
  double min_gap = 0;          // most negative tool gap after a move, in h
  double zone_min_gap = 0;     // the same for the Eulerian zone's nodes, which are put back
};

// The steps, each recorded; on a failed step the configuration it failed
// from is kept as failed_step_nodes.csv before the error goes on. With
// --restart, from the checkpoint in dir; a checkpoint as --checkpoint-every says.
RunMeasures run(const Setup& s, const Options& o, const std::string& signature, Stepper<NortonHoff>& sim,
                const fs::path& dir) {
  ResultsWriter results(dir);
  const double area0 = s.axisymmetric ? M_PI * s.height * s.height * s.length : s.length * s.height;
  RunMeasures m;
  if (o.restart.restarting()) {
    examples::RestartOptions::resume(dir, signature, sim, results, o.steps, "extrusion", [&](CheckpointIn& in) {
      m.max_area_change = in.get_double();
      m.min_gap = in.get_double();
      m.zone_min_gap = in.get_double();
      m.first.xs = in.get_matrix();
      m.first.p_axis = in.get_matrix();
      m.first.ys = in.get_matrix();
      m.first.p_die = in.get_matrix();
    });
  }
  for (int k = sim.steps_done() + 1; k <= o.steps; ++k) {
    try {
      sim.step();
    } catch (const Error&) {
      CsvTable nodes({"x", "y"});
      for (Eigen::Index a = 0; a < sim.nodes().cols(); ++a) {
        nodes.cell(sim.nodes()(0, a)).cell(sim.nodes()(1, a));
        nodes.end_row();
      }
      nodes.write(dir / "failed_step_nodes.csv");
      throw;
    }
    const bool vtu = k == 1 || k == 10 || k == o.steps || k == (o.steps + 1) / 2 || k % o.vtu_every == 0;
    results.record(sim, vtu);
    if (k == 1) {
      m.first = profiles(s, sim, 301);
      write_profiles(dir, m.first);
    }
    // Mass: the area (volume) inside the alpha-shape boundary.
    m.max_area_change = std::max(m.max_area_change, std::abs(material_measure(s, sim.mesh()) - area0) / area0);
    // Penetration after the move, relative to the nodal spacing; a node of
    // the Eulerian zone that is still inside it (or in a tool) goes back to
    // its place before the next step, so its gap is reported on its own.
    const auto& zone = sim.eulerian_zone();
    for (int a : sim.mesh().boundary_nodes()) {
      const Eigen::Vector2d p = sim.nodes().col(a);
      const bool put_back = zone && sim.nodal_field("zone_node")(0, a) > 0 &&
                            (zone->inside(p) || std::any_of(sim.tools().begin(), sim.tools().end(),
                                                            [&](const RigidTool& t) { return t.gap(p) < 0; }));
      double& gap = put_back ? m.zone_min_gap : m.min_gap;
      for (const auto& tool : sim.tools()) gap = std::min(gap, tool.gap(p) / sim.mesh().h()(a));
    }
    if (o.restart.due(k, vtu))
      write_checkpoint(dir, signature, sim, results, [&](CheckpointOut& out) {
        out.put(m.max_area_change).put(m.min_gap).put(m.zone_min_gap).put(m.first.xs).put(m.first.p_axis).put(m.first.ys).put(m.first.p_die);
      });
  }
  return m;
}

// Product width: the material's area between the die exit and the nose (away
// from both by a spacing or three) over that length, i.e. the mean thickness
// that carries the mass flow; the top node alone follows the free surface's
// node-scale waviness. On the last solved configuration.
struct ProductWidth {
  double width = 0, error = 1, top = 0;
  int nodes = 0;
  // The product's free surface between the land's end and 3 h before the
  // nose's front face: the boundary node farthest from the opening's line (in h0).
  double surface_dev = 0, surface_x = 0;
};
ProductWidth product_width(const Setup& s, const IntegrationMesh<>& mesh) {
  const double exit = s.length + s.land;
  double front = -1e300;
  for (Eigen::Index a = 0; a < mesh.nodes().cols(); ++a) front = std::max(front, frame(s, mesh.nodes().col(a)).x());
  const double hmean = s.length / (s.nx - 1);
  const double x1 = exit + hmean, x2 = front - 3 * hmean;
  double area = 0;
  ProductWidth w;
  for (std::size_t t = 0; t < mesh.triangles().size(); ++t) {
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (int a : mesh.triangles()[t]) c += frame(s, mesh.nodes().col(a)) / 3.0;
    if (c.x() > x1 && c.x() < x2) area += mesh.area(static_cast<int>(t));
  }
  for (Eigen::Index a = 0; a < mesh.nodes().cols(); ++a) {
    const Eigen::Vector2d q = frame(s, mesh.nodes().col(a));
    if (q.x() > x1 && q.x() < x2) {
      w.top = std::max(w.top, q.y());
      ++w.nodes;
    }
  }
  // The free surface ends where the nose's front face begins: its bulge is
  // a length of the process (about 18 at E2's size), not a few spacings.
  double top_front = -1e300;
  for (int a : mesh.boundary_nodes()) {
    const Eigen::Vector2d q = frame(s, mesh.nodes().col(a));
    if (q.x() > exit && q.y() >= s.opening() - 0.5 * hmean) top_front = std::max(top_front, q.x());
  }
  const double x2_surface = std::min(x2, top_front - 3 * hmean);
  for (int a : mesh.boundary_nodes()) {
    const Eigen::Vector2d q = frame(s, mesh.nodes().col(a));
    const double dev = std::abs(q.y() - s.opening()) / hmean;
    if (q.x() > exit && q.x() < x2_surface && q.y() > 0.5 * s.opening() && dev > w.surface_dev) {
      w.surface_dev = dev;
      w.surface_x = q.x();
    }
  }
  w.width = x2 > x1 ? area / (x2 - x1) : 0.0;
  w.error = w.nodes ? std::abs(w.width - s.opening()) / s.opening() : 1.0;
  return w;
}

// The step-1 profiles' shape: the axis pressure's largest rise (it should
// decrease toward the die) and where the die-face pressure peaks. The max-ent
// basis smooths the corner singularity (the paper's Fig. 7: the FEM peak is
// sharper), so "at the corner" means: the die-face maximum is on the lower
// half of the face, and at least 1.5 times the pressure on the die opening
// just below the corner.
struct Step1Shape {
  double range = 0, rise = 0, peak_y = 0, peak = 0, die_below = 0;
};
Step1Shape step1_shape(const Setup& s, const Profiles& first) {
  Step1Shape f;
  f.range = first.p_axis.maxCoeff() - first.p_axis.minCoeff();
  for (Eigen::Index i = 1; i < first.p_axis.size(); ++i)
    f.rise = std::max(f.rise, first.p_axis[i] - first.p_axis[i - 1]);
  Eigen::Index peak = 0;
  f.peak = first.p_die.maxCoeff(&peak);
  f.peak_y = first.ys[peak];
  for (Eigen::Index i = 0; i < first.ys.size(); ++i)
    if (first.ys[i] < s.opening()) f.die_below = std::max(f.die_below, first.p_die[i]);
  return f;
}

// The physical checks of --check; the failed ones, named.
std::vector<std::string> failed_checks(const Setup& s, const Options& o, const RunMeasures& m,
                                       const ProductWidth& w, const Step1Shape& f) {
  std::vector<std::string> failed;
  if (m.min_gap < -1e-3) failed.push_back("a node penetrates a tool");
  if (m.max_area_change > o.area_tol) failed.push_back("area changes by more than --area-tol");
  if (o.steps * s.dt * s.V >= 0.5 * s.length && w.error > 0.05)
    failed.push_back("product width off the die opening by > 5 %");
  if (o.steps * s.dt * s.V >= 0.5 * s.length && w.surface_dev > o.surface_tol)
    failed.push_back("a node of the product's free surface is more than --surface-tol h off the opening's line");
  if (f.rise > 0.01 * f.range) failed.push_back("step-1 axis pressure not decreasing");
  if (f.peak_y < s.opening() || f.peak_y > s.opening() + 0.5 * (s.height - s.opening()) || !(f.peak > 1.5 * f.die_below))
    failed.push_back("die-face pressure does not peak next to the die corner");
  return failed;
}

}  // namespace

int main(int argc, char** argv) {
  // 1. Options: every parameter of the case on the command line.
  CLI::App app{"maxentflow E2: forward extrusion (paper Figs. 6-7)"};
  Setup s;
  Options o;
  add_options(app, s, o);
  CLI11_PARSE(app, argc, argv);
  set_blas_threads(1);  // the cores go to the OpenMP loops (parallel.hpp)
  s.node_update = o.node_update == "ab2" ? NodeUpdate::adams_bashforth2 : NodeUpdate::euler;
  s.law = o.friction.law(s.V);
  if (o.restart.restarting()) o.out = o.restart.dir;
  if (o.convergence.empty() && !(o.steps * s.dt * s.V < s.length)) {
    std::cerr << "extrusion: the ram's stroke --steps x --dt x --velocity = " << o.steps * s.dt * s.V
              << " reaches the die face (--length " << s.length << ")\n";
    return 2;
  }
  if (!o.convergence.empty() && o.restart.restarting()) {
    std::cerr << "extrusion: --convergence solves step 1 only; there is nothing to --restart\n";
    return 2;
  }
  const fs::path dir(o.out);
  try {
    if (!o.convergence.empty()) return convergence(s, o.convergence, dir, o.check);
    // 2. The case (extrusion_case.hpp): billet nodes, the ram and the die as
    //    rigid tools (frictionless unless a friction option is given), v_y = 0
    //    on the axis, rezoning, and with --zone an Eulerian zone at the die.
    // The zone is asked for (--zone, --zone-from), or the default where it applies.
    const bool asked = o.zone || !std::isnan(o.zone_from);
    if (asked && s.die_radius != 0.0) throw Error("--zone needs a square die (--die-radius 0)", "extrusion");
    if (asked || (!o.no_zone && zone_by_default(s) && !std::isnan(default_zone_from(s, o.steps)))) {
      s.zone_from = std::isnan(o.zone_from) ? default_zone_from(s, o.steps) : o.zone_from;
      if (!std::isnan(o.zone_from) && o.zone_from > s.length - 2 * s.length / (s.nx - 1))
        throw Error("--zone-from must lie at least 2 h before the die face", "extrusion");
      if (std::isnan(s.zone_from))
        throw Error("--zone: the ram's stroke leaves no room for the zone before the die face", "extrusion");
    }
    Stepper<NortonHoff> sim = make_simulation(s);
    sim.set_log(&std::cout);
    if (o.verbose) sim.parameters().solver.log = &std::cout;

    // 3. March, recording each step (VTU/PVD, forces.csv), the step-1
    //    profiles, the area and the penetration.
    const RunMeasures m = run(s, o, examples::RestartOptions::signature(app), sim, dir);

    // 4. What an engineer checks: the product's width against the die
    //    opening, the step-1 pressure along the axis and the die face.
    const ProductWidth w = product_width(s, sim.mesh());
    const Step1Shape f = step1_shape(s, m.first);
    double total = 0;
    // The load a press reads: the ram force against the ram's motion.
    const Eigen::Vector2d ram_dir = sim.tools()[0].velocity().normalized();
    std::vector<double> ram_load;
    std::vector<const StepRecord*> window;
    int zone_since = 0;  // the first step with the Eulerian zone in place
    for (const auto& r : sim.history()) {
      total += r.seconds;
      if (r.zone_active && !zone_since) zone_since = r.step;
      if (r.tool_stroke[0] >= o.load_window[0] && r.tool_stroke[0] <= o.load_window[1]) {
        ram_load.push_back(-r.tool_force[0].dot(ram_dir));
        window.push_back(&r);
      }
    }
    const examples::LoadSteadiness load = examples::load_steadiness(ram_load);
    const examples::PowerShares power = examples::power_shares(window, sim.tools()[0].velocity().norm());
    std::cout << "extrusion: " << o.steps << " steps, " << sim.nodes().cols() << " nodes, " << total << " s\n"
              << "  max area change " << 100 * m.max_area_change << " %, min gap " << m.min_gap << " h"
              << (sim.eulerian_zone() ? detail::cat(" (the Eulerian zone's nodes, before they are put back: ",
                                                     m.zone_min_gap, " h; zone from ", s.zone_from, ", ",
                                                     zone_since ? detail::cat("in place from step ", zone_since)
                                                                : std::string("never filled: the run stayed Lagrangian"),
                                                     ")")
                                      : std::string())
              << ", product width " << w.width << " (die opening " << s.opening() << ", " << 100 * w.error
              << " %; top node at " << w.top << ", " << w.nodes << " nodes)\n"
              << "  free surface from the land's end to 3 h before the nose's front face: farthest boundary node "
              << w.surface_dev << " h from the opening's line (at " << w.surface_x << ")\n"
              << "  step-1 axis pressure " << m.first.p_axis[0] << " at the ram to "
              << m.first.p_axis[m.first.p_axis.size() - 1] << " at the die; largest rise " << f.rise / f.range
              << " of the range; die-face peak at y = " << f.peak_y << "\n"
              << "  ram load over the stroke " << o.load_window[0] << "-" << o.load_window[1] << ": "
              << (load.samples > 1 ? detail::cat(load) : std::string("fewer than two steps in the window"))
              << "\n"
              << "  ram power (load x speed) over the same strokes: "
              << (power.samples > 1 ? detail::cat(power) : std::string("fewer than two steps in the window")) << "\n"
              << "  friction: " << o.friction.describe() << "\n"
              << "results in " << dir << " (step.pvd: open in ParaView)\n";

    // 5. Figures: pressure and velocity maps, ram force against stroke, the
    //    step-1 profiles.
    if (!o.no_plots) {
      std::ostringstream args;
      const int mid = (o.steps + 1) / 2, early = std::min(10, o.steps);
      args << '"' << dir.string() << "\" --maps pressure:1," << early << ',' << mid << ',' << o.steps
           << " velocity_x:" << early << " velocity_y:" << early
           << " --force-tool ram --profile profile_axis_step1.csv profile_die_step1.csv";
      examples::run_plot_script(fs::path(MAXENTFLOW_EXAMPLE_DIR) / "../common/plot_forming.py", args.str());
    }

    // 6. --check: exit 1 when a physical check fails.
    if (o.check) {
      auto failed = failed_checks(s, o, m, w, f);
      if (load.samples > 1 && !(load.rms_change <= o.load_rms_tol))
        failed.push_back(detail::cat("the ram load changes from step to step by ", 100 * load.rms_change,
                                     " % rms over the load window, more than --load-rms-tol"));
      if (load.samples > 1 && !(load.band() <= o.load_band_tol))
        failed.push_back(detail::cat("the ram load strays from its mean by up to ", 100 * load.band(),
                                     " % over the load window, more than --load-band-tol"));
      for (const auto& msg : failed) std::cerr << "check failed: " << msg << "\n";
      if (!failed.empty()) return 1;
    }
  } catch (const Error& e) {
    std::cerr << "extrusion failed: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

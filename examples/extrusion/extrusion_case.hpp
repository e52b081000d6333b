// The E2 extrusion case (docs/cases.md) as a Stepper: billet, ram, die,
// symmetry axis. Shared by the `extrusion` example and its benchmark.
#pragma once

#include <maxentflow/maxentflow.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace maxentflow::examples {

struct Setup {
  int nx = 32, ny = 32;
  double length = 300, height = 300, reduction = 0.5, land = 30, V = 5, dt = 0.3;
  double die_radius = 0.0;  ///< the die corner's radius (0: the paper's square die)
  /// Billet nodes graded toward the die corner, same node count: the spacing
  /// there is h / grade (1: the uniform grid; graded_billet). At 3 the 32 x 32
  /// step-1 pressure is closer to a 256 x 256 run than the uniform grid's
  /// (axis 0.0135 against 0.0244, die face 0.062 against 0.082, rms over the
  /// largest |p|) and than a P1b-P1 FEM's at 32 per side (docs/method.md, 9).
  double grade = 3.0;
  double gamma = 1.6, Cs = 0.5, alpha = 1.3, mu0 = 150, n = 0.2;
  double tol0 = StepperParams{}.tol0;  ///< max-ent support cut-off
  /// Norton-Hoff regularization, relative to V / L: moves the ram force by
  /// 1e-4 against 1e-6 and saves a third of the Newton iterations in the
  /// rigid product and dead zone (docs/method.md, section 7).
  double d_min = 1e-2;
  bool axisymmetric = false;
  /// Node rezoning (node_adaptivity.hpp): the end of the stroke compresses the
  /// billet next to the ram about 4:1 along the ram face.
  bool rezone = true;
  double rezone_min = 0.35, rezone_max = 2.5;
  double rezone_min_spacing = NodeAdaptivityParams{}.min_spacing_ratio;
  /// An Eulerian zone (eulerian_zone.hpp) from `zone_from` along the billet
  /// to the land's end: the container's end and the die land keep their nodes
  /// in place once the material fills them, so that the flow through the die
  /// is solved on the same cloud every step, with no rezoning there
  /// (docs/method.md, section 11). A square die only; zone_from must stay
  /// ahead of the ram (the example puts it two spacings ahead of the
  /// stroke's end). NaN: no zone (the default).
  double zone_from = std::numeric_limits<double>::quiet_NaN();
  Predictor predictor = Predictor::spatial;  ///< steady flow through the die
  NodeUpdate node_update = StepperParams{}.node_update;
  AnyContactLaw law = Frictionless{};  ///< on the ram and the die
  double opening() const { return (1.0 - reduction) * height; }
};

// Model coordinates of a billet point (along, across).
inline Eigen::Vector2d to_model(const Setup& s, const Eigen::Vector2d& q) {
  return s.axisymmetric ? Eigen::Vector2d(q.y(), s.length - q.x()) : q;
}

/// The billet's nx x ny nodes (along, across), moved radially toward the die
/// corner c = (length, opening): a node at distance r < R from c goes to
/// distance R q(r / R), q(u) = u / g + (1 - 1/g)(2 u^2 - u^3) (q(0) = 0,
/// q'(0) = 1/g: spacing h / g at c; q(1) = 1, q'(1) = 1: the uniform grid
/// from R on, with no kink). R is c's distance to the nearest side it does
/// not lie on, so every side keeps its nodes and the node count is that of
/// the uniform grid. Near c the map scales both directions alike (cells stay
/// near square); the flow's singular point is where the step-1 pressure
/// converges slowest (docs/method.md, section 9).
inline Eigen::Vector2d graded(const Setup& s, const Eigen::Vector2d& p) {
  const Eigen::Vector2d c(s.length, s.opening());
  const double R = std::min({s.opening(), s.height - s.opening(), s.length});
  const double g = s.grade, u = (p - c).norm() / R;
  const double q = u / g + (1.0 - 1.0 / g) * (2.0 * u * u - u * u * u);
  return u < 1.0 && u > 0.0 ? Eigen::Vector2d(c + (p - c) * (q / u)) : p;
}
inline Eigen::Matrix2Xd graded_billet(const Setup& s) {
  require(std::isfinite(s.grade) && s.grade >= 1.0, detail::cat("grade must be >= 1, got ", s.grade),
          "graded_billet");
  Eigen::Matrix2Xd x(2, s.nx * s.ny);
  for (int j = 0; j < s.ny; ++j)
    for (int i = 0; i < s.nx; ++i)
      x.col(j * s.nx + i) = graded(s, {s.length * i / (s.nx - 1), s.height * j / (s.ny - 1)});
  return x;
}

/// Whether the example sets an Eulerian zone unless told not to (--no-zone):
/// a square die, plane strain (E2) or axisymmetric (32 x 32: the ram load
/// 0.08 % rms step to step against 6.0 % without). A round die corner has
/// no zone yet.
inline bool zone_by_default(const Setup& s) { return s.die_radius == 0.0; }

/// Where the example's Eulerian zone (--zone) starts: two spacings ahead of
/// the ram's position after `steps` steps; NaN where that leaves less than
/// two spacings before the die face, or the die corner is rounded.
inline double default_zone_from(const Setup& s, int steps) {
  const double h = s.length / (s.nx - 1), from = steps * s.dt * s.V + 2 * h;
  return s.die_radius == 0.0 && from <= s.length - 2 * h ? from : std::numeric_limits<double>::quiet_NaN();
}

// Billet coordinates (along, across) of a model point (to_model's inverse).
inline Eigen::Vector2d to_billet(const Setup& s, const Eigen::Vector2d& m) {
  return s.axisymmetric ? Eigen::Vector2d(s.length - m.y(), m.x()) : m;
}

/// The Eulerian zone of Setup::zone_from (model coordinates): the billet's
/// nodes from zone_from on, the die corner, and the land's nodes: the graded
/// billet's grid continued past the die face (the same radial map, so the
/// spacing at the corner is h / grade on both sides), a node on the land's
/// face in each column, and a column on the land's end, where the product
/// leaves the zone.
inline EulerianZone extrusion_zone(const Setup& s) {
  require(s.die_radius == 0.0, "an Eulerian zone needs a square die (--die-radius 0)", "extrusion_zone");
  const double L = s.length, H = s.height, a = s.opening(), end = L + s.land;
  const double hx = L / (s.nx - 1), hy = H / (s.ny - 1);
  require(std::isfinite(s.zone_from) && s.zone_from > 0 && s.zone_from <= L - 2 * hx,
          detail::cat("the zone's start (", s.zone_from, ") must lie in (0, length - 2 h]"), "extrusion_zone");
  const Eigen::Vector2d c(L, a);
  std::vector<Eigen::Vector2d> z;
  const Eigen::Matrix2Xd billet = graded_billet(s);
  for (Eigen::Index k = 0; k < billet.cols(); ++k)
    if (billet(0, k) >= s.zone_from) z.push_back(billet.col(k));
  z.push_back(c);
  // Short of the land's end by half their own spacing at least.
  auto before_end = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector2d q = graded(s, p);
    return q.x() <= end - 0.5 * (graded(s, p + Eigen::Vector2d(hx, 0)) - q).norm();
  };
  // Rows evenly from the axis to the land's face (about hy apart).
  const int rows = std::max(1, static_cast<int>(std::lround(a / hy)));
  for (int i = 1; L + i * hx < end + s.land; ++i)
    for (int j = 0; j <= rows; ++j)
      if (before_end({L + i * hx, a * j / rows})) z.push_back(graded(s, {L + i * hx, a * j / rows}));
  for (int j = 0; j <= rows; ++j) z.push_back({end, a * j / rows});
  EulerianZone zone;
  // The land face's nodes count as filled within 0.75 of their spacing: on
  // fine billets the Lagrangian product runs 0.3-0.6 of it below the land,
  // and at 0.25 the 64 x 64 zone started at step 67 of 100, the product
  // before it off the opening's line by 1.1 h (docs/method.md, section 11).
  zone.fill_tols.assign(z.size(), zone.fill_tol);
  for (std::size_t k = 0; k < z.size(); ++k)
    if (z[k].x() > L + 1e-9 * L && std::abs(z[k].y() - a) <= 1e-9 * L) zone.fill_tols[k] = 0.75;
  zone.nodes.resize(2, static_cast<Eigen::Index>(z.size()));
  for (std::size_t k = 0; k < z.size(); ++k) zone.nodes.col(static_cast<Eigen::Index>(k)) = to_model(s, z[k]);
  const double tol = 1e-9 * L;
  zone.inside = [s, tol, a, end](const Eigen::Vector2d& m) {
    const Eigen::Vector2d p = to_billet(s, m);
    return p.x() >= s.zone_from - tol && p.y() >= -tol &&
           ((p.x() <= s.length + tol && p.y() <= s.height + tol) || (p.x() <= end + tol && p.y() <= a + tol));
  };
  return zone;
}

/// Linear: the stepper's linear-solver policy (GmresSolver<> by default).
template <LinearSolverPolicy Linear = GmresSolver<>>
Stepper<NortonHoff, Linear> make_simulation(const Setup& s) {
  Eigen::Matrix2Xd x = graded_billet(s);
  StepperParams prm;
  prm.geometry = s.axisymmetric ? Geometry::axisymmetric : Geometry::plane_strain;
  prm.dt = s.dt;
  prm.gamma = s.gamma;
  prm.tol0 = s.tol0;
  prm.mesh.alpha = s.alpha;
  prm.stabilization.Cs = s.Cs;
  // Each step starts from the last one's coefficients, ~10-30 % off in
  // residual at the die corner and the product's nose; direct iteration gets
  // there with fewer iterations than damped Newton steps (16 x 16, 30 steps:
  // 344 iterations and 17k Krylov against 442 and 22k).
  prm.solver.newton_from_warm_start = false;
  prm.solver.switch_increment = 0.1;
  // Kept-LU Newton solves only as tight as Eisenstat-Walker asks (eta_max):
  // fewer GMRES iterations and LUs, forces moved by < 3e-9 (docs/method.md, 8).
  prm.solver.eta_kept_lu = prm.solver.eta_max;
  prm.predictor = s.predictor;
  prm.node_update = s.node_update;
  prm.adapt.enabled = s.rezone;
  prm.adapt.min_ratio = s.rezone_min;
  prm.adapt.max_ratio = s.rezone_max;
  prm.adapt.min_spacing_ratio = s.rezone_min_spacing;
  const bool zone = std::isfinite(s.zone_from);
  // Axisymmetric: x = (r, z), the axis r = 0. The die helper keeps the axis on
  // the right of the extrusion direction, so the bar is extruded along -z: the
  // billet point (along, across) sits at (r, z) = (across, L - along).
  if (s.axisymmetric)
    for (Eigen::Index a = 0; a < x.cols(); ++a) x.col(a) = to_model(s, x.col(a));
  // d_min far below the process strain rate V / L (see NortonHoff).
  Stepper<NortonHoff, Linear> sim(x, NortonHoff(s.mu0, s.n, s.d_min * s.V / s.length), prm);
  const double H = s.height, L = s.length;
  const Eigen::Vector2d along = s.axisymmetric ? Eigen::Vector2d(0, -1) : Eigen::Vector2d(1, 0);
  RigidTool ram = flat_plate("ram", to_model(s, {0, 0.5 * H}), along, 0.75 * H);
  ram.set_velocity(s.V * along);
  sim.add_tool(ram, s.law);
  sim.add_tool(extrusion_die("die", to_model(s, {L, s.opening()}), along, H - s.opening(), s.land, s.die_radius,
                             1.5 * L, H - s.opening()),
               s.law);
  const Eigen::Vector2d across = s.axisymmetric ? Eigen::Vector2d(1, 0) : Eigen::Vector2d(0, 1);
  sim.add_velocity_condition({"axis", on_line({0, 0}, across, 1e-9 * H), across, 0.0});
  if (zone) sim.set_eulerian_zone(extrusion_zone(s));
  return sim;
}

}  // namespace maxentflow::examples

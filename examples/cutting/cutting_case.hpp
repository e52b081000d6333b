// The E3 cutting case (docs/cases.md) as a Stepper: workpiece, tool, fixed
// edges. Shared by the `cutting` example and its benchmark.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <tuple>
#include <vector>

#include <maxentflow/maxentflow.hpp>

namespace maxentflow::examples {

struct CuttingSetup {
  int nx = 122, ny = 41;
  double length = 40, height = 13.2, V = 1500, dt = 2e-5, t0 = 1.5;
  double rake = 5, clearance = 7, edge_radius = 0;  ///< degrees, degrees, length
  double gamma = 1.6, Cs = 0.5, alpha = 1.3, mu0 = 150, n = 0.2;
  double tol0 = StepperParams{}.tol0;  ///< max-ent support cut-off
  /// Norton-Hoff regularization, relative to V / t0: moves the first forces
  /// by 0.4 % against 1e-6 (1e-2: 4 %; docs/method.md, section 7).
  double d_min = 1e-3;
  /// Newton's tolerance on the relative velocity increment and residual
  /// (the library's 1e-7): the forces move by < 3e-4 until a rezoning falls
  /// on another step; the whole run 6 % faster (docs/method.md, section 13).
  double tol = 1e-5;
  bool rezone = true;
  /// An Eulerian zone round the tool's tip that moves with the tool
  /// (cutting_zone); a sharp tool only.
  bool zone = true;
  /// The zone's extent, in t0: ahead of the tip, below it, behind it, and
  /// the chip's strip along the rake face above the uncut surface (width
  /// from the face, height).
  double zone_front = 2.0, zone_depth = 0.5, zone_back = 0.5, zone_strip = 0.5, zone_rise = 0.0;
  AnyContactLaw law = Frictionless{};
  double spacing() const { return length / (nx - 1); }
  /// The tip at the start: just right of the workpiece, t0 below its top.
  Eigen::Vector2d tip_start() const { return {length + 0.05 * spacing(), height - t0}; }
};

/// The Eulerian zone round the tool's tip (eulerian_zone.hpp), moving with
/// the tool: in the tool's frame the cut is a steady flow, so the nodes next
/// to the tip (where the uncut layer splits into the chip and the machined
/// surface) can stay where they are, and the tip's contact is the same cloud
/// every step; with Lagrangian nodes each node that reaches the tip changes
/// the contact there and the cutting force by up to a third. Rows at
/// h_z = t0 / round(t0 / h) from the tip's height, so that the tip and the
/// uncut surface lie on rows; along a row the nodes are h_z apart, the first
/// on the rake face above the tip's height. The region: the uncut layer from
/// zone_front t0 ahead of the rake face to the face, the layer below the
/// tip from zone_front ahead to zone_back behind it, zone_depth deep, and
/// a strip zone_strip wide along the face up to zone_rise above the uncut
/// surface. Material enters ahead and leaves by the chip and behind the
/// tip, where its nodes are emitted into the Lagrangian cloud.
inline EulerianZone cutting_zone(const CuttingSetup& s) {
  const std::string at = "cutting_zone";
  require(s.edge_radius == 0.0, "an Eulerian zone at the tip needs a sharp tool (--edge-radius 0)", at);
  for (double e : {s.zone_front, s.zone_depth, s.zone_back, s.zone_strip, s.zone_rise})
    require(std::isfinite(e) && e >= 0, detail::cat("zone extents must be finite and >= 0, got ", e), at);
  const Eigen::Vector2d T = s.tip_start();
  const double tr = std::tan(s.rake * std::numbers::pi / 180.0), H = s.height;
  const double m = std::max(1.0, std::round(s.t0 / s.spacing())), hz = s.t0 / m;
  const auto cells = [&](double e) { return static_cast<int>(std::round(e * s.t0 / hz)); };
  const int K = std::max(1, cells(s.zone_front)), Kb = cells(s.zone_back);
  const int kw = cells(s.zone_strip), js = cells(s.zone_rise), M = static_cast<int>(m);
  require(T.y() - s.zone_depth * s.t0 > 0, "the zone reaches below the workpiece (--zone-depth too large)", at);
  const double tol = 1e-9 * s.length, tip_lift = 0.25;
  // u: the distance ahead of the rake face (its line, continued below the tip as a vertical).
  const auto face = [=](double y) { return T.x() + std::max(0.0, y - T.y()) * tr; };
  // Rows: below the tip the workpiece grid's own (the material there stays
  // where the tool leaves it, so the rows emitted behind the tip continue
  // the grid's), skipping one closer than h / 2 to the tip's height, and at
  // least one; from the tip up, h_z apart.
  std::vector<double> rows;
  const double h = s.spacing(), bottom = T.y() - s.zone_depth * s.t0 - 1e-9 * h;
  for (int k = 0; k < s.ny; ++k)
    if (const double y = H - k * h; y < T.y() - 0.5 * h + tol && (y >= bottom || (rows.empty() && s.zone_depth > 0)))
      rows.push_back(y);  // at least one row where the depth holds none
  for (int j = 0; j <= M + js; ++j) rows.push_back(T.y() + j * hz);
  std::sort(rows.begin(), rows.end());
  std::vector<Eigen::Vector2d> z;
  for (double y : rows) {
    const int lo = y > H + tol ? -kw : -K, hi = y > T.y() + tol ? 0 : Kb;
    for (int k = lo; k <= hi; ++k) z.emplace_back(face(y) + k * hz, y);
  }
  // The tip's node a quarter of h_z up the rake face, not on the tip: a node on
  // the corner is held along the corner's bisector, and its force (a third
  // of the cutting force) would tilt the tool's toward the clearance face.
  const double ang = s.rake * std::numbers::pi / 180.0;
  for (auto& p : z)
    if (p == T) p += tip_lift * hz * Eigen::Vector2d(std::sin(ang), std::cos(ang));
  const double y_lo = rows.front(), y_hi = rows.back();
  EulerianZone zone;
  zone.tool = 0;
  zone.nodes.resize(2, static_cast<Eigen::Index>(z.size()));
  for (std::size_t k = 0; k < z.size(); ++k) zone.nodes.col(static_cast<Eigen::Index>(k)) = z[k];
  zone.emit_ahead = 0.5;
  zone.inside = [=](const Eigen::Vector2d& p) {
    if (p.y() < y_lo - tol || p.y() > y_hi + tol) return false;
    const double u = p.x() - face(p.y());
    const double lo = p.y() > H + tol ? -kw * hz : -K * hz, hi = p.y() > T.y() + tol ? 0.0 : Kb * hz;
    return u >= lo - tol && u <= hi + tol;
  };
  return zone;
}

/// The workpiece grid with v = 0 on its bottom and left edges, and the tool
/// (faces 8 t0 long) moving -x at V. Rezoning keeps the spacing where the
/// chip forms; each step starts with Newton from the extrapolated last
/// coefficients (the library's default: with the Eulerian zone a step's start
/// is a few per cent off in residual, median 7 %, within Newton's basin; one
/// kept LU a step instead of two).
inline Stepper<NortonHoff> make_cutting(const CuttingSetup& s) {
  Eigen::Matrix2Xd x(2, s.nx * s.ny);
  for (int j = 0; j < s.ny; ++j)
    for (int i = 0; i < s.nx; ++i) x.col(j * s.nx + i) << s.length * i / (s.nx - 1), s.height * j / (s.ny - 1);
  StepperParams prm;
  prm.dt = s.dt;
  prm.gamma = s.gamma;
  prm.tol0 = s.tol0;
  prm.mesh.alpha = s.alpha;
  prm.stabilization.Cs = s.Cs;
  prm.adapt.enabled = s.rezone;
  prm.solver.switch_increment = 0.1;
  // As E2's: kept-LU Newton solves to eta_max (docs/method.md, section 8).
  prm.solver.eta_kept_lu = prm.solver.eta_max;
  prm.solver.velocity_tol = prm.solver.residual_tol = s.tol;
  // A kept LU that failed is tried again at the next solve's start: here an
  // LU (12M entries) costs ~25 GMRES iterations, and the tool-tip contact
  // makes most failures one-offs (150 steps: 40 s of factorization against
  // 73-76 s, 10.8k GMRES iterations against 9.4k, 11 % less time; E2 keeps
  // the library's 4; docs/method.md, section 8).
  prm.solver.kept_lu_skip_carry = 0;
  // The zone's nodes on the rake face lie inside the chip's contact: one
  // released there is the tip's multiplier oscillation (ToolContact::params).
  prm.contact.release_put_back = !s.zone;
  Stepper<NortonHoff> sim(x, NortonHoff(s.mu0, s.n, s.d_min * s.V / s.t0), prm);
  RigidTool tool = cutting_tool("tool", s.tip_start(), s.rake, s.clearance, s.edge_radius, 8 * s.t0);
  tool.set_velocity({-s.V, 0});
  sim.add_tool(tool, s.law);
  if (s.zone) sim.set_eulerian_zone(cutting_zone(s));
  const double tol = 1e-9 * s.length;
  for (const auto& [name, point, normal] :
       {std::tuple{"bottom", Eigen::Vector2d(0, 0), Eigen::Vector2d(0, 1)},
        std::tuple{"left", Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0)}}) {
    sim.add_velocity_condition({std::string(name) + " x", on_line(point, normal, tol), {1, 0}, 0.0});
    sim.add_velocity_condition({std::string(name) + " y", on_line(point, normal, tol), {0, 1}, 0.0});
  }
  return sim;
}

}  // namespace maxentflow::examples

// The E3 cutting case (docs/cases.md) as a Stepper: workpiece, tool, fixed
// edges. Shared by the `cutting` example and its benchmark.
#pragma once

#include <cmath>
#include <numbers>
#include <string>
#include <tuple>

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
  bool rezone = true;
  AnyContactLaw law = Frictionless{};
  double spacing() const { return length / (nx - 1); }
  /// The tip at the start: just right of the workpiece, t0 below its top.
  Eigen::Vector2d tip_start() const { return {length + 0.05 * spacing(), height - t0}; }
};

/// The workpiece grid with v = 0 on its bottom and left edges, and the tool
/// (faces 8 t0 long) moving -x at V. Rezoning keeps the spacing where the
/// chip forms; each step starts with Picard from the last one's coefficients
/// (as in E2: direct iteration reaches Newton's basin from there).
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
  prm.solver.newton_from_warm_start = false;
  prm.solver.switch_increment = 0.1;
  // As E2's: kept-LU Newton solves to eta_max (docs/method.md, section 8).
  prm.solver.eta_kept_lu = prm.solver.eta_max;
  // A kept LU that failed is tried again at the next solve's start: here an
  // LU (12M entries) costs ~25 GMRES iterations, and the tool-tip contact
  // makes most failures one-offs (150 steps: 40 s of factorization against
  // 73-76 s, 10.8k GMRES iterations against 9.4k, 11 % less time; E2 keeps
  // the library's 4; docs/method.md, section 8).
  prm.solver.kept_lu_skip_carry = 0;
  Stepper<NortonHoff> sim(x, NortonHoff(s.mu0, s.n, s.d_min * s.V / s.t0), prm);
  RigidTool tool = cutting_tool("tool", s.tip_start(), s.rake, s.clearance, s.edge_radius, 8 * s.t0);
  tool.set_velocity({-s.V, 0});
  sim.add_tool(tool, s.law);
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

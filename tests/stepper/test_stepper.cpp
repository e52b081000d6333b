// The updated-Lagrangian stepper with rigid-tool contact: V1 and V2 along a
// whole stroke, contact against inclined and cornered tools, dt retries, and
// the results files (VTU/PVD/CSV parse, whole after every step).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "../support/flow_problems.hpp"

using namespace maxentflow;
using maxentflow::test::block_nodes;

namespace {

// Upsetting's tools: a fixed bottom plate, a top plate at H0 moving down at
// V (both frictionless), and v_x = 0 on the axis (symmetry line) x = 0.
void add_plates(Stepper<NortonHoff>& s, double H0, double V, const AnyContactLaw& law = Frictionless{}) {
  s.add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 100), law);
  RigidTool top = flat_plate("top", {0, H0}, {0, -1}, 100);
  top.set_velocity({0, -V});
  s.add_tool(top, law);
  s.add_velocity_condition({"axis", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
}

struct Upset {
  double max_force_error = 0, max_shape_error = 0;
  int steps = 0;
  std::vector<double> force;  // top plate, per step
};

// Frictionless upsetting between flat plates (contact, not prescribed
// velocities): the homogeneous solution V1 / V2 at every step.
Upset upsetting(Geometry g, int steps, double dt, Predictor predictor = Predictor::material,
               const AnyContactLaw& law = Frictionless{}, bool symmetric_lu = true) {
  const double R0 = 10, H0 = 12, V = 0.06;
  const NortonHoff mat(150.0, 0.2, 1e-8);
  StepperParams prm;
  prm.solver.symmetric_lu = symmetric_lu;
  prm.geometry = g;
  prm.dt = dt;
  prm.predictor = predictor;
  prm.node_update = NodeUpdate::euler;  // the shape check follows Eq. (18)'s path
  Stepper<NortonHoff> s(block_nodes(7, 8, R0, H0, false), mat, prm);
  add_plates(s, H0, V, law);
  if (std::getenv("MAXENTFLOW_TEST_LOG")) s.set_log(&std::cout);
  const bool axi = g == Geometry::axisymmetric;
  Upset u;
  // The billet stays a rectangle; its width follows the Eq. (18) update
  // x += v dt of the homogeneous field: R_{k+1} = R_k (1 + e_k dt) (plane strain)
  // or R_k (1 + e_k dt / 2) (axisymmetric), H_{k+1} = H_k - V dt.
  double R = R0, H = H0, sx = 1.0;
  const Eigen::Matrix2Xd x0 = block_nodes(7, 8, R0, H0, false);
  for (int k = 0; k < steps; ++k) {
    // Exact force on the configuration the step solves (its start).
    const double e = V / H;
    const double d = axi ? e : 2 * e / std::sqrt(3.0);
    const double mu = mat.viscosity(d).mu;
    const double F = axi ? 3 * mu * e * M_PI * R * R : 4 * mu * e * R;
    const auto& rec = s.step();
    u.max_force_error = std::max({u.max_force_error, std::abs(rec.tool_force[1].y() - F) / F,
                                  std::abs(rec.tool_force[0].y() + F) / F,
                                  std::abs(rec.tool_force[1].x()) / F});
    u.force.push_back(rec.tool_force[1].y());
    const double f = axi ? 1 + e * dt / 2 : 1 + e * dt;
    R *= f;
    sx *= f;
    H -= V * dt;
    for (int a = 0; a < x0.cols(); ++a)
      u.max_shape_error = std::max({u.max_shape_error, std::abs(s.nodes()(0, a) - sx * x0(0, a)) / R0,
                                    std::abs(s.nodes()(1, a) - H / H0 * x0(1, a)) / R0});
    ++u.steps;
  }
  return u;
}

}  // namespace

TEST_CASE("V2 along the stroke: axisymmetric upsetting by contact stays exact",
          "[verification][stepper]") {
  const auto u = upsetting(Geometry::axisymmetric, 100, 1.0);
  CHECK(u.steps == 100);
  CHECK(u.max_force_error < 1e-8);
  CHECK(u.max_shape_error < 1e-8);
}

TEST_CASE("V1 along the stroke: plane-strain compression by contact stays exact",
          "[verification][stepper]") {
  const auto u = upsetting(Geometry::plane_strain, 100, 1.0);
  CHECK(u.steps == 100);
  CHECK(u.max_force_error < 1e-8);
  CHECK(u.max_shape_error < 1e-8);
}

TEST_CASE("V1 and V2 along the stroke with m = 0 and mu = 0: the frictionless run to 1e-12",
          "[verification][stepper][friction]") {
  // Tresca and Coulomb with a zero coefficient add a zero traction: the same
  // run, with the same linear algebra (a friction law's matrices are not
  // symmetric, so their kept LUs are LUs: the reference's too).
  for (const Geometry g : {Geometry::axisymmetric, Geometry::plane_strain}) {
    CAPTURE(g == Geometry::axisymmetric);
    const auto ref = upsetting(g, 30, 1.0, Predictor::material, Frictionless{}, false);
    for (const AnyContactLaw& law : {AnyContactLaw(Tresca(0.0, 6e-4)), AnyContactLaw(Coulomb(0.0, 6e-4))}) {
      CAPTURE(law.name());
      const auto u = upsetting(g, 30, 1.0, Predictor::material, law);
      REQUIRE(u.steps == 30);
      CHECK(u.max_force_error < 1e-8);
      CHECK(u.max_shape_error < 1e-8);
      double diff = 0.0;
      for (int k = 0; k < 30; ++k) diff = std::max(diff, std::abs(u.force[k] - ref.force[k]) / ref.force[k]);
      CHECK(diff <= 1e-12);
    }
  }
}

TEST_CASE("bad stepper input is refused with an Error naming what and where", "[stepper]") {
  const Eigen::Matrix2Xd nodes = block_nodes(4, 4, 1, 1, false);
  auto message = [&](const StepperParams& prm, const Eigen::Matrix2Xd& x) -> std::string {
    try {
      Stepper<NortonHoff> s(x, NortonHoff(), prm);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  struct Bad {
    const char* name;
    std::function<void(StepperParams&)> set;
  };
  const std::vector<Bad> bad = {
      {"dt", [&](StepperParams& p) { p.dt = nan; }},
      {"dt", [&](StepperParams& p) { p.dt = -1; }},
      {"gamma", [&](StepperParams& p) { p.gamma = 0; }},
      {"tol0", [&](StepperParams& p) { p.tol0 = 1.0; }},
      {"max_active_set_iterations", [&](StepperParams& p) { p.max_active_set_iterations = 0; }},
      {"max_retries", [&](StepperParams& p) { p.max_retries = -1; }},
      {"penetration_tol", [&](StepperParams& p) { p.penetration_tol = inf; }},
      {"snap_tol", [&](StepperParams& p) { p.snap_tol = -0.1; }},
      {"contact.release_tol", [&](StepperParams& p) { p.contact.release_tol = nan; }},
      {"contact.leave_tol", [&](StepperParams& p) { p.contact.leave_tol = -0.1; }},
      {"solver.velocity_tol", [&](StepperParams& p) { p.solver.velocity_tol = 0; }},
      {"solver.max_iterations", [&](StepperParams& p) { p.solver.max_iterations = 0; }},
  };
  for (const auto& b : bad) {
    CAPTURE(b.name);
    StepperParams prm;
    b.set(prm);
    const std::string what = message(prm, nodes);
    CHECK_THAT(what, Catch::Contains(b.name) && Catch::Contains("Stepper"));
  }
  Eigen::Matrix2Xd x = nodes;
  x(1, 5) = nan;
  CHECK_THAT(message(StepperParams{}, x), Catch::Contains("node 5") && Catch::Contains("non-finite"));
  CHECK_THAT(message(StepperParams{}, nodes.leftCols(2)), Catch::Contains("at least 3 nodes"));
  // Parameters changed between steps are checked when the step starts.
  Stepper<NortonHoff> s(nodes, NortonHoff(), StepperParams{});
  s.parameters().dt = 0;
  try {
    s.step();
    FAIL("no exception");
  } catch (const Error& e) {
    CHECK_THAT(std::string(e.what()), Catch::Contains("dt") && Catch::Contains("Stepper::step 1"));
  }
  CHECK(s.steps_done() == 0);
}

TEST_CASE("no silent fallback: the spatial predictor's misses are counted, said in the record, logged once",
          "[stepper]") {
  // Plane-strain upsetting: the free side moves outward, so x + dt v of its
  // nodes lies beyond the configuration's hull and they keep the material
  // predictor; the step records it, the log says it once per run.
  for (const Predictor pr : {Predictor::material, Predictor::spatial}) {
    CAPTURE(pr == Predictor::spatial);
    StepperParams prm;
    prm.geometry = Geometry::plane_strain;
    prm.predictor = pr;
    Stepper<NortonHoff> s(block_nodes(7, 8, 10, 12, false), NortonHoff(150.0, 0.2, 1e-8), prm);
    add_plates(s, 12, 0.06);
    std::ostringstream log;
    s.set_log(&log);
    int fallbacks = 0;
    for (int k = 0; k < 3; ++k) {
      const StepRecord& r = s.step();
      fallbacks += r.predictor_fallbacks;
      CHECK(!r.nodal_gradient_fallback);
      if (pr == Predictor::spatial) {
        CHECK(r.predictor_fallbacks >= 8);  // the free side's column, corners included
        CHECK(r.predictor_fallbacks <= 16);
        CHECK_THAT(r.degraded, Catch::Contains("spatial predictor") && Catch::Contains("keep the material predictor"));
      } else {
        CHECK(r.predictor_fallbacks == 0);
        CHECK(r.degraded.empty());
      }
    }
    const std::string text = log.str();
    std::size_t notes = 0;
    for (std::size_t at = text.find("note (step"); at != std::string::npos; at = text.find("note (step", at + 1)) ++notes;
    CHECK(notes == (pr == Predictor::spatial ? 1u : 0u));
    CHECK((fallbacks > 0) == (pr == Predictor::spatial));
  }
}

TEST_CASE("V1 with the spatial predictor: the start moves, the solution does not",
          "[verification][stepper]") {
  // The predictor only changes where each solve starts (V + f(x + dt v) - f(x)).
  const auto u = upsetting(Geometry::plane_strain, 30, 1.0, Predictor::spatial);
  CHECK(u.steps == 30);
  CHECK(u.max_force_error < 1e-8);
  CHECK(u.max_shape_error < 1e-8);
}

namespace {

// A billet pressed by a tool; returns the most negative gap (relative to h)
// over all boundary nodes and steps, and the contact counts.
struct Pressed {
  double min_gap = 1e300;
  int max_contact = 0, min_free_top = 1 << 30;
  double force_y = 0;
};

Pressed press(RigidTool tool, int steps) {
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.dt = 0.5;
  Stepper<NortonHoff> s(block_nodes(9, 7, 8, 6, false), NortonHoff(150.0, 0.2, 1e-7), prm);
  s.add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 100));
  s.add_tool(std::move(tool));
  s.add_velocity_condition({"symmetry", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
  Pressed p;
  for (int k = 0; k < steps; ++k) {
    const auto& r = s.step();
    p.max_contact = std::max(p.max_contact, r.contact_nodes);
    p.force_y = r.tool_force[1].y();
    int free_top = 0;
    for (int a : s.mesh().boundary_nodes()) {
      const double h = s.mesh().h()(a);
      for (const auto& t : s.tools()) p.min_gap = std::min(p.min_gap, t.gap(s.nodes().col(a)) / h);
      if (s.nodes()(1, a) > 5.0 && s.contact_flags()[static_cast<std::size_t>(a)] == 0) ++free_top;
    }
    p.min_free_top = std::min(p.min_free_top, free_top);
  }
  return p;
}

}  // namespace

TEST_CASE("contact: an inclined plate does not penetrate the billet", "[stepper][contact]") {
  // A plate tilted by 10 degrees, touching the billet's top-left corner, moving down.
  const double a = 10 * M_PI / 180;
  RigidTool plate = flat_plate("inclined", {0, 6}, {std::sin(a), -std::cos(a)}, 50);
  plate.set_velocity({0, -0.1});
  const auto p = press(plate, 4);
  CHECK(p.min_gap >= -1e-5);  // weak (hat) imposition: measured -1.2e-6 h
  CHECK(p.max_contact > 1);
  CHECK(p.force_y > 0);  // the billet pushes the plate up
}

TEST_CASE("contact: a node at a tool's end that the velocity guess moves off starts free; one on the face "
          "or rounding the end stays",
          "[stepper][contact]") {
  const Eigen::Matrix2Xd x = block_nodes(6, 6, 5, 5, false);  // [0, 5]^2, h = 1
  const IntegrationMesh<> mesh(x);
  auto node = [&](double px, double py) {
    for (Eigen::Index k = 0; k < x.cols(); ++k)
      if ((x.col(k) - Eigen::Vector2d(px, py)).norm() < 1e-12) return static_cast<int>(k);
    return -1;
  };
  // A plate on the top over x in [0, 5]: (5, 5) sits on its open end, as a
  // node on a die land's exit; (3, 5) on its face.
  const RigidTool plate = flat_plate("land", {2.5, 5}, {0, -1}, 2.5);
  const int end = node(5, 5), face = node(3, 5);
  const double dt = 0.1;
  auto active = [&](ToolContact::params prm, const Eigen::Vector2d& move_end) {
    Eigen::Matrix2Xd v = Eigen::Matrix2Xd::Zero(2, x.cols());
    v.col(end) = move_end / dt;
    v.col(face) = Eigen::Vector2d(0.3, -0.3) / dt;  // off the face by 0.3 h
    ToolContact c(prm);
    c.detect(mesh, plate, v, dt);
    std::vector<int> on;
    for (const auto& p : c.points())
      if (p.active) on.push_back(p.node);
    return std::make_pair(std::count(on.begin(), on.end(), end) == 1, std::count(on.begin(), on.end(), face) == 1);
  };
  const ToolContact::params prm;
  REQUIRE(prm.leave_tol == 0.1);
  CHECK(active(prm, {0.3, -0.3}) == std::make_pair(false, true));   // leaves by 0.42 h
  CHECK(active(prm, {0.06, -0.06}) == std::make_pair(true, true));  // 0.085 h: the multiplier decides
  ToolContact::params keep = prm;
  keep.leave_tol = 1e9;  // the rule off: in contact as its gap says
  CHECK(active(keep, {0.3, -0.3}) == std::make_pair(true, true));
  // Eulerian zone nodes (put back at fixed places, with their state at the
  // end of the last step), their own last velocity the guess: one held at
  // the end starts in contact whatever that velocity says; one that ended
  // free starts free unless it would penetrate, on the face too.
  auto zone_node = [&](int a, PutBack mark, const Eigen::Vector2d& move) {
    Eigen::Matrix2Xd v = Eigen::Matrix2Xd::Zero(2, x.cols());
    v.col(a) = move / dt;
    std::vector<PutBack> put_back(static_cast<std::size_t>(x.cols()), PutBack::no);
    put_back[static_cast<std::size_t>(a)] = mark;
    ToolContact c(prm);
    c.detect(mesh, plate, v, dt, put_back);
    const auto it = std::find_if(c.points().begin(), c.points().end(),
                                 [&](const ContactPoint& p) { return p.node == a; });
    REQUIRE(it != c.points().end());
    CHECK(it->put_back == (mark != PutBack::no));
    return it->active;
  };
  const Eigen::Vector2d off(0.3, -0.3), into(0, 0.3);
  CHECK_FALSE(zone_node(end, PutBack::no, off));
  CHECK_FALSE(zone_node(end, PutBack::unknown, off));
  CHECK(zone_node(end, PutBack::held, off));
  CHECK_FALSE(zone_node(end, PutBack::free, off));
  CHECK(zone_node(face, PutBack::unknown, off));  // on the face: by its gap, as a material node
  CHECK_FALSE(zone_node(face, PutBack::free, off));
  CHECK(zone_node(face, PutBack::free, into));
}

TEST_CASE("contact: a zone opens from its edges, a whole tensile run in one update",
          "[stepper][contact]") {
  // [0, 5]^2, h = 1, under a plate wider than the block: the six top nodes
  // are in contact, the block's top corners are the zone's edges.
  const Eigen::Matrix2Xd x = block_nodes(6, 6, 5, 5, false);
  const IntegrationMesh<> mesh(x);
  const RigidTool plate = flat_plate("top", {2.5, 5}, {0, -1}, 3.5);
  const Eigen::Matrix2Xd v = Eigen::Matrix2Xd::Zero(2, x.cols());
  const double dt = 0.1;
  const int n = static_cast<int>(x.cols());
  // The nodes the update releases when the top node at x = i has multiplier lambda(i).
  auto released = [&](const std::function<double(double)>& lambda) {
    ToolContact c;
    c.detect(mesh, plate, v, dt);
    REQUIRE(c.active_count() == 6);
    ConstraintSet cs;
    const int part = cs.add_part("tool top");
    std::vector<double> l;
    for (const auto& p : c.points())
      if (p.active) {
        ConstraintRow row;
        row.part = part;
        row.node = p.node;
        row.direction = {0, -1};
        cs.add(row);
        l.push_back(lambda(x(0, p.node)));
      }
    Eigen::VectorXd X = Eigen::VectorXd::Zero(DofLayout::fields_of(n) + cs.size());
    for (int i = 0; i < cs.size(); ++i) X[DofLayout::fields_of(n) + i] = l[static_cast<std::size_t>(i)];
    c.update(cs, part, X, n, x, v, plate, dt);
    std::vector<double> at;
    for (int a : c.changed_nodes()) at.push_back(x(0, a));
    std::sort(at.begin(), at.end());
    return at;
  };
  // The whole zone tensile (the plate pulled off): all six go at once, not
  // the two edge nodes (one per end per update, too slow for a long zone).
  CHECK(released([](double) { return 1.0; }) == std::vector<double>{0, 1, 2, 3, 4, 5});
  // Tensile from the left edge to x = 2: that run goes, the rest stays.
  CHECK(released([](double px) { return px < 2.5 ? 1.0 : -1.0; }) == std::vector<double>{0, 1, 2});
  // Tensile inside the zone only (the weak imposition's oscillation): nothing goes.
  CHECK(released([](double px) { return px > 1.5 && px < 3.5 ? 1.0 : -1.0; }).empty());
}

TEST_CASE("contact: a node in a concave tool corner is held by both faces", "[stepper][contact]") {
  // [0, 5]^2, h = 1, its top-right corner in the corner of an L-shaped tool:
  // a face x = 5 (normal -x) turning into a wall y = 5 (normal -y).
  Eigen::Matrix2Xd x = block_nodes(6, 6, 5, 5, false);
  const Eigen::Matrix<double, 2, 3> L{{5, 5, -1}, {-1, 5, 5}};
  const RigidTool tool("L", L);
  REQUIRE(tool.concave_corners().size() == 1);
  const Eigen::Matrix2Xd v = Eigen::Matrix2Xd::Zero(2, x.cols());
  int corner = -1;
  for (int a = 0; a < x.cols(); ++a)
    if ((x.col(a) - Eigen::Vector2d(5, 5)).norm() < 1e-12) corner = a;
  REQUIRE(corner >= 0);
  // The corner node a hair off one face, then the other (E2's dead-zone
  // corner after a step and its snap): the same face's condition first
  // both times, and the other face's as its second. With the nearer face
  // alone, the node's one condition swapped faces between the two.
  for (const Eigen::Vector2d& off : {Eigen::Vector2d(-8e-4, -2e-4), Eigen::Vector2d(-2e-4, -8e-4)}) {
    x.col(corner) = Eigen::Vector2d(5, 5) + off;
    const IntegrationMesh<> mesh(x);
    ToolContact c;
    c.detect(mesh, tool, v, 0.1);
    const auto it = std::find_if(c.points().begin(), c.points().end(),
                                 [&](const ContactPoint& p) { return p.node == corner; });
    REQUIRE(it != c.points().end());
    INFO("offset " << off.transpose());
    CHECK(it->active);
    CHECK(it->projection.normal.isApprox(Eigen::Vector2d(-1, 0)));
    REQUIRE(it->second_normal.has_value());
    CHECK(it->second_normal->isApprox(Eigen::Vector2d(0, -1)));
    // Its neighbours on each face keep their own face's one condition.
    for (const auto& p : c.points())
      if (p.node != corner && p.active) CHECK_FALSE(p.second_normal.has_value());
  }
}

TEST_CASE("contact: a cornered punch indents without penetration; the free top stays free",
          "[stepper][contact]") {
  // A square punch over x in [-1, 3] (the symmetry line at x = 0) on a billet 8 wide.
  RigidTool punch = rectangle("punch", {-1, 6}, {3, 9});
  punch.set_velocity({0, -0.1});
  const auto p = press(punch, 4);
  // A node released at the punch corner stays free unless it would penetrate
  // by more than ToolContact::params::reentry_tol = 1e-3 h (the anti-chatter
  // hysteresis); measured -1.4e-3 h with the default GMRES solver.
  CHECK(p.min_gap >= -2e-3);
  CHECK(p.max_contact >= 3);
  CHECK(p.min_free_top >= 3);  // the top beyond the punch is not in contact
  CHECK(p.force_y > 0);
}

TEST_CASE("contact: the active set checked on a loose solve first ends where full solves end, in fewer "
          "iterations",
          "[stepper][contact]") {
  // The cornered punch: its corner node is released and the set changes.
  auto run = [](double active_set_tol) {
    StepperParams prm;
    prm.geometry = Geometry::plane_strain;
    prm.dt = 0.5;
    prm.active_set_tol = active_set_tol;
    Stepper<NortonHoff> s(block_nodes(9, 7, 8, 6, false), NortonHoff(150.0, 0.2, 1e-7), prm);
    s.add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 100));
    RigidTool punch = rectangle("punch", {-1, 6}, {3, 9});
    punch.set_velocity({0, -0.1});
    s.add_tool(std::move(punch));
    s.add_velocity_condition({"symmetry", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
    struct Run {
      std::vector<double> force;
      std::vector<std::vector<int>> contact;
      int iterations = 0, passes = 0;
    } out;
    for (int k = 0; k < 4; ++k) {
      const auto& r = s.step();
      out.force.push_back(r.tool_force[1].y());
      out.contact.push_back(s.contact_flags());
      out.iterations += r.picard + r.newton;
      out.passes += r.active_set_iterations;
    }
    return out;
  };
  REQUIRE(StepperParams{}.active_set_tol == 1e-2);
  const auto loose = run(1e-2), full = run(0.0);
  REQUIRE(full.passes > 4);  // the set changed in some step
  CHECK(loose.passes == full.passes);
  CHECK(loose.contact == full.contact);
  for (std::size_t k = 0; k < full.force.size(); ++k)
    CHECK(std::abs(loose.force[k] - full.force[k]) <= 1e-9 * std::abs(full.force[k]));
  CHECK(loose.iterations < full.iterations);
}

TEST_CASE("a step that cannot be done throws and leaves the state of its start",
          "[stepper]") {
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.max_retries = 2;
  prm.solver.max_iterations = 1;  // no solve can converge
  Stepper<NortonHoff> s(block_nodes(5, 5, 4, 4, false), NortonHoff(), prm);
  RigidTool top = flat_plate("top", {0, 4}, {0, -1}, 50);
  top.set_velocity({0, -0.1});
  s.add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 50));
  s.add_tool(top);
  s.add_velocity_condition({"symmetry", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
  const Eigen::Matrix2Xd x0 = s.nodes();
  try {
    s.step();
    FAIL("no exception");
  } catch (const Error& e) {
    CHECK_THAT(std::string(e.what()), Catch::Contains("dt/4") && Catch::Contains("no convergence"));
  }
  CHECK(s.nodes() == x0);
  CHECK(s.time() == 0.0);
  CHECK(s.tools()[1].stroke() == 0.0);
  CHECK(s.steps_done() == 0);
}

namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Value of attribute `name` in the tag starting at `from`.
std::string attribute(const std::string& s, std::size_t from, const std::string& name) {
  const std::size_t end = s.find('>', from);
  const std::size_t a = s.find(" " + name + "=\"", from);
  REQUIRE(a != std::string::npos);
  REQUIRE(a < end);
  const std::size_t b = a + name.size() + 3;
  return s.substr(b, s.find('"', b) - b);
}

std::size_t count_numbers(const std::string& text) {
  std::istringstream in(text);
  std::size_t n = 0;
  double v;
  while (in >> v) {
    REQUIRE(std::isfinite(v));
    ++n;
  }
  REQUIRE(in.eof());  // nothing that is not a number
  return n;
}

// A VTU as ParaView needs it: every DataArray has NumberOfPoints (cells) x
// components finite values; connectivity 3 per triangle, indices in range.
void check_vtu(const std::filesystem::path& p, int nodes) {
  const std::string s = slurp(p);
  REQUIRE(s.rfind("<?xml", 0) == 0);
  REQUIRE(s.find("</VTKFile>") != std::string::npos);
  const std::size_t piece = s.find("<Piece ");
  REQUIRE(piece != std::string::npos);
  const long np = std::stol(attribute(s, piece, "NumberOfPoints"));
  const long nc = std::stol(attribute(s, piece, "NumberOfCells"));
  CHECK(np == nodes);
  CHECK(nc > 0);
  const std::size_t cell_data = s.find("<CellData>"), points = s.find("<Points>");
  int arrays = 0;
  for (std::size_t at = s.find("<DataArray", piece); at != std::string::npos;
       at = s.find("<DataArray", at + 1)) {
    const std::size_t body = s.find('>', at) + 1;
    const std::string values = s.substr(body, s.find("</DataArray>", body) - body);
    const std::size_t n = count_numbers(values);
    const std::string name = s.find(" Name=\"", at) < body ? attribute(s, at, "Name") : "";
    const long comps = s.find(" NumberOfComponents=", at) < body ? std::stol(attribute(s, at, "NumberOfComponents")) : 1;
    INFO("DataArray " << name);
    if (name == "connectivity")
      CHECK(n == static_cast<std::size_t>(3 * nc));
    else if (name == "offsets" || name == "types")
      CHECK(n == static_cast<std::size_t>(nc));
    else if (at > cell_data && at < points)
      CHECK(n == static_cast<std::size_t>(comps * nc));
    else
      CHECK(n == static_cast<std::size_t>(comps * np));
    ++arrays;
  }
  CHECK(arrays >= 8);  // points, 3 cell arrays, velocity, pressure, strain rate, strain, flags
}

}  // namespace

TEST_CASE("results: VTU, PVD and CSV files parse and are whole after every step",
          "[stepper][results]") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "maxentflow_test_results";
  fs::remove_all(dir);
  const double H0 = 12, V = 0.06;
  StepperParams prm;
  prm.geometry = Geometry::axisymmetric;
  prm.dt = 2.0;
  Stepper<NortonHoff> s(block_nodes(5, 6, 10, H0, false), NortonHoff(150.0, 0.2, 1e-8), prm);
  add_plates(s, H0, V);
  ResultsWriter out(dir);
  std::vector<std::string> vtus;
  for (int k = 1; k <= 4; ++k) {
    s.step();
    const bool vtu = k % 2 == 1;
    out.record(s, vtu);
    if (vtu) vtus.push_back(detail::cat("step_000", k, ".vtu"));
    // A run stopped here (between steps) leaves complete files: check them now.
    const std::string pvd = slurp(dir / "step.pvd");
    REQUIRE(pvd.find("</VTKFile>") != std::string::npos);
    std::size_t datasets = 0;
    for (std::size_t at = pvd.find("<DataSet"); at != std::string::npos; at = pvd.find("<DataSet", at + 1)) {
      const std::string file = attribute(pvd, at, "file");
      REQUIRE(datasets < vtus.size());
      CHECK(file == vtus[datasets]);
      CHECK(fs::exists(dir / file));
      ++datasets;
    }
    CHECK(datasets == vtus.size());
    for (const auto& f : vtus) check_vtu(dir / f, 30);
    std::istringstream forces(slurp(dir / "forces.csv"));
    std::string line;
    std::getline(forces, line);
    CHECK(line == "step,time,tool,stroke,fx,fy");
    int rows = 0;
    while (std::getline(forces, line)) {
      CHECK(std::count(line.begin(), line.end(), ',') == 5);
      ++rows;
    }
    CHECK(rows == 2 * k);  // two tools per step
    // power.csv: one row per step, the step's record (V2: the plates' power is the plastic dissipation).
    std::istringstream power(slurp(dir / "power.csv"));
    std::getline(power, line);
    CHECK(line == "step,time,tool_power,delivered_power,plastic_power,stabilization_power");
    rows = 0;
    while (std::getline(power, line)) {
      std::vector<double> c;
      std::istringstream cells(line);
      for (std::string cell; std::getline(cells, cell, ',');) c.push_back(std::stod(cell));
      REQUIRE(c.size() == 6);
      const StepRecord& r = s.history()[static_cast<std::size_t>(rows)];
      CHECK(c[0] == r.step);
      CHECK(c[2] == Approx(r.tool_power).epsilon(1e-15));
      CHECK(c[4] == Approx(c[2]).epsilon(1e-9));
      ++rows;
    }
    CHECK(rows == k);
    for (const auto& e : fs::directory_iterator(dir))
      CHECK(e.path().filename().string().find(".tmp.") == std::string::npos);
  }
  fs::remove_all(dir);
}

TEST_CASE("rezoning: a 3:1 stretched, 1:3 compressed grid gets back to its spacing; corners, area "
          "and linear fields kept",
          "[stepper][rezoning]") {
  // A unit grid (h0 = 1) stretched 3:1 along x and compressed 3:1 along y.
  Eigen::Matrix2Xd x = block_nodes(21, 21, 20, 20, false);
  Eigen::VectorXd h0 = Eigen::VectorXd::Ones(x.cols());
  x.row(0) *= 3.0;
  x.row(1) /= 3.0;
  const double W = 60, H = 20.0 / 3.0;
  auto linear = [](const Eigen::Vector2d& p) { return 2 + 0.5 * p.x() - 0.25 * p.y(); };
  Eigen::RowVectorXd f(x.cols());
  for (Eigen::Index a = 0; a < x.cols(); ++a) f[a] = linear(x.col(a));
  NodeAdaptivityParams prm;
  prm.enabled = true;
  int removed = 0, added = 0, passes = 0;
  for (; passes < 12; ++passes) {
    const IntegrationMesh<> mesh(x);
    const NodeAdaptation a = plan_node_adaptation(mesh, h0, prm);
    if (a.empty()) break;
    for (int r : a.removed) {  // never a corner
      const bool corner = (x(0, r) == 0 || x(0, r) == W) && (x(1, r) == 0 || x(1, r) == H);
      CHECK_FALSE(corner);
    }
    removed += static_cast<int>(a.removed.size());
    added += a.added();
    x = a.positions(x);
    h0 = a.transfer(h0.transpose()).transpose();
    f = a.transfer(f);
  }
  CHECK(passes < 12);  // it settles
  CHECK(removed > 200);
  CHECK(added > 100);
  const IntegrationMesh<> mesh(x);
  CHECK(mesh.total_area() == Approx(W * H).epsilon(1e-12));  // straight sides stay straight
  CHECK(mesh.boundary_loops().size() == 1);
  CHECK(mesh.orphan_nodes().empty());
  double fmax = 0, rmin = 1e300, rmax = 0;
  for (Eigen::Index a = 0; a < x.cols(); ++a) {
    CHECK(x(0, a) >= 0);
    CHECK(x(0, a) <= W);
    CHECK(x(1, a) >= 0);
    CHECK(x(1, a) <= H);
    fmax = std::max(fmax, std::abs(f[a] - linear(x.col(a))));
  }
  for (const auto& e : mesh.edges()) {
    const double r = (x.col(e.b) - x.col(e.a)).norm() / (0.5 * (h0[e.a] + h0[e.b]));
    rmin = std::min(rmin, r);
    rmax = std::max(rmax, r);
  }
  CHECK(fmax < 1e-12);  // the transfer is linear along the split edges
  INFO("edge / h0 from " << rmin << " to " << rmax << ", " << x.cols() << " nodes");
  CHECK(rmin >= prm.min_ratio);
  CHECK(rmax <= prm.max_ratio);
}

TEST_CASE("rezoning: a cloud squeezed 6:1 inside the h0 band loses its crowded nodes; area and linear "
          "fields kept",
          "[stepper][rezoning]") {
  // A unit grid (h0 = 1) stretched 2.3:1 along x, squeezed to 0.36 along y:
  // every edge within [min_ratio, max_ratio] h0, so only the spacing rule acts.
  Eigen::Matrix2Xd x = block_nodes(13, 49, 12, 48, false);
  Eigen::VectorXd h0 = Eigen::VectorXd::Ones(x.cols());
  x.row(0) *= 2.3;
  x.row(1) *= 0.36;
  const double W = 12 * 2.3, H = 48 * 0.36;
  auto linear = [](const Eigen::Vector2d& p) { return 1 - 0.5 * p.x() + 2 * p.y(); };
  Eigen::RowVectorXd f(x.cols());
  for (Eigen::Index a = 0; a < x.cols(); ++a) f[a] = linear(x.col(a));
  NodeAdaptivityParams prm;
  prm.enabled = true;
  NodeAdaptivityParams h0_only = prm;
  h0_only.min_spacing_ratio = 0.0;
  CHECK(plan_node_adaptation(IntegrationMesh<>(x), h0, h0_only).empty());
  const Eigen::Index before = x.cols();
  int passes = 0;
  for (; passes < 30; ++passes) {
    const IntegrationMesh<> mesh(x);
    const NodeAdaptation a = plan_node_adaptation(mesh, h0, prm);
    if (a.empty()) break;
    for (int r : a.removed)  // never a corner
      CHECK_FALSE(((x(0, r) == 0 || x(0, r) == Approx(W)) && (x(1, r) == 0 || x(1, r) == Approx(H))));
    x = a.positions(x);
    h0 = a.transfer(h0.transpose()).transpose();
    f = a.transfer(f);
  }
  CHECK(passes < 30);  // it settles (the sides last: a side node's h_a rises as its neighbours go)
  INFO(before << " -> " << x.cols() << " nodes in " << passes << " passes");
  CHECK(x.cols() < 0.7 * before);
  const IntegrationMesh<> mesh(x);
  CHECK(mesh.total_area() == Approx(W * H).epsilon(1e-12));
  CHECK(mesh.orphan_nodes().empty());
  double fmax = 0, smin = 1e300;
  for (Eigen::Index a = 0; a < x.cols(); ++a) fmax = std::max(fmax, std::abs(f[a] - linear(x.col(a))));
  for (const auto& e : mesh.edges())
    smin = std::min(smin, (x.col(e.b) - x.col(e.a)).norm() / (0.5 * (mesh.h()[e.a] + mesh.h()[e.b])));
  CHECK(fmax < 1e-12);
  CHECK(smin >= prm.min_spacing_ratio);
}

TEST_CASE("rezoning: no node is put inside a tool", "[stepper][rezoning]") {
  Eigen::Matrix2Xd x = block_nodes(6, 6, 5, 5, false);
  x.row(0) *= 4.0;  // every horizontal edge is 4 h0
  const IntegrationMesh<> mesh(x);
  const Eigen::VectorXd h0 = Eigen::VectorXd::Ones(x.cols());
  NodeAdaptivityParams prm;
  const NodeAdaptation all = plan_node_adaptation(mesh, h0, prm);
  CHECK(all.added() > 0);
  const NodeAdaptation none =
      plan_node_adaptation(mesh, h0, prm, [](const Eigen::Vector2d& p) { return p.x() < 0; });
  CHECK(none.added() == 0);
  CHECK_THROWS_AS(plan_node_adaptation(mesh, Eigen::VectorXd::Ones(3), prm), Error);
}

TEST_CASE("rezoning: no edge across a tool thinner than the spacing", "[stepper][rezoning]") {
  // Two blocks [0, 1]^2 (h = h0 = 0.1) 0.03 apart with a wall 0.02 thick
  // between them. An edge across the gap is shorter than min_ratio h0
  // (0.035) but is no edge of the material: on the mesh the stepper plans
  // with (the crossing rule, as the solve's) the rezoning leaves it alone.
  const Eigen::Matrix2Xd a = block_nodes(11, 11, 1, 1, false);
  Eigen::Matrix2Xd x(2, 2 * a.cols());
  x << a, a.colwise() + Eigen::Vector2d(1.03, 0);
  const RigidTool wall = rectangle("wall", {1.005, -0.5}, {1.025, 1.5});
  const Eigen::VectorXd h0 = Eigen::VectorXd::Constant(x.cols(), 0.1);
  const NodeAdaptivityParams prm;
  const IntegrationMesh<> plain(x);
  CHECK(plain.boundary_loops().size() == 1);
  CHECK(plan_node_adaptation(plain, h0, prm).removed.size() > 0);  // the gap collapsed
  IntegrationMesh<> mesh;
  mesh.set_solid({}, [&](const Eigen::Vector2d& p, const Eigen::Vector2d& q) { return wall.crosses(p, q); });
  mesh.build(x);
  CHECK(mesh.boundary_loops().size() == 2);
  CHECK(plan_node_adaptation(mesh, h0, prm).empty());
}

TEST_CASE("rezoning: a node on a convex tool corner next to the boundary, once", "[stepper][rezoning]") {
  const Eigen::Matrix2Xd x = block_nodes(6, 6, 5, 5, false);  // h = h0 = 1
  const IntegrationMesh<> mesh(x);
  const Eigen::VectorXd h0 = Eigen::VectorXd::Ones(x.cols());
  NodeAdaptivityParams prm;
  auto node = [&](double px, double py) {
    for (Eigen::Index k = 0; k < x.cols(); ++k)
      if ((x.col(k) - Eigen::Vector2d(px, py)).norm() < 1e-12) return static_cast<int>(k);
    return -1;
  };
  NodeAdaptation a;
  a.inserted.resize(2, 0);
  // On the right side between two nodes, 0.4 h outside it, on a node, far
  // off, and one within min_ratio h0 of the first.
  const std::vector<Eigen::Vector2d> corners{{5, 2.5}, {5.4, 0.5}, {5, 4}, {7, 2.5}, {5, 2.7}};
  add_corner_nodes(mesh, h0, prm, corners, a);
  REQUIRE(a.added() == 2);
  CHECK((a.inserted.col(0) - Eigen::Vector2d(5, 2.5)).norm() < 1e-14);
  CHECK((a.inserted.col(1) - Eigen::Vector2d(5.4, 0.5)).norm() < 1e-14);
  auto same_pair = [](std::array<int, 2> p, int i, int j) { return (p[0] == i && p[1] == j) || (p[0] == j && p[1] == i); };
  CHECK(same_pair(a.parents[0], node(5, 2), node(5, 3)));
  CHECK(same_pair(a.parents[1], node(5, 0), node(5, 1)));
  // The new node's data is its parents' mean; positions keep the corner.
  Eigen::RowVectorXd f = Eigen::RowVectorXd::LinSpaced(x.cols(), 0.0, 1.0);
  const auto g = a.transfer(f);
  CHECK(g(x.cols()) == Approx(0.5 * (f[node(5, 2)] + f[node(5, 3)])));
  CHECK((a.positions(x).col(x.cols() + 1) - Eigen::Vector2d(5.4, 0.5)).norm() < 1e-14);
  // A corner already taken by this pass's insertion is not taken again.
  add_corner_nodes(mesh, h0, prm, {Eigen::Vector2d(5, 2.6)}, a);
  CHECK(a.added() == 2);
}

namespace {
// A zone of the block [0, 10] x [0, 4] (11 x 5 nodes, h = 1): x in [3, 6].
EulerianZone strip_zone(double emit_spacing) {
  EulerianZone z;
  z.emit_surface_spacing = emit_spacing;
  z.inside = [](const Eigen::Vector2d& p) { return p.x() >= 3 - 1e-12 && p.x() <= 6 + 1e-12; };
  z.nodes.resize(2, 20);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 5; ++j) z.nodes.col(5 * i + j) << 3 + i, j;
  z.emit_spacing = emit_spacing;
  return z;
}
}  // namespace

TEST_CASE("Eulerian zone: nodes back in place with the interpolant, outflow at its spacing, not before filled",
          "[stepper][zone]") {
  // The block moved by 0.4 along x (a step of flow): its zone nodes at 3.4,
  // 4.4, 5.4 are inside, those from 6 are at 6.4, out of the zone, with the
  // material's column at 7.4 one spacing beyond.
  Eigen::Matrix2Xd x = block_nodes(11, 5, 10, 4, false);
  Eigen::VectorXd id = Eigen::VectorXd::Zero(x.cols());
  for (Eigen::Index a = 0; a < x.cols(); ++a) {
    const double c = x(0, a);
    if (c >= 3 && c <= 6) id(a) = 5 * (c - 3) + x(1, a) + 1;  // the zone node it was, plus one
    x(0, a) += 0.4;
  }
  const IntegrationMesh<> mesh(x);
  const Eigen::VectorXd h0 = Eigen::VectorXd::Ones(x.cols());
  const MaxEntBasis<2> basis(x, mesh.h());
  const auto admissible = [](const Eigen::Vector2d& p) { return p.y() <= 3.5; };  // a "tool" above y = 3.5
  const ZoneUpdate z = plan_zone_update(mesh, basis, strip_zone(0.8), id, h0, Eigen::VectorXd::Ones(20), admissible);
  REQUIRE(z.active);
  // Gone: the 15 old nodes inside (3.4, 4.4, 5.4) and the zone node at (6.4, 4), in the "tool".
  CHECK(z.change.removed.size() == 16);
  CHECK(z.emitted.size() == 4);
  for (int a : z.emitted) CHECK(x(0, a) == Approx(6.4));
  CHECK(z.fallbacks == 0);
  // The zone's nodes come back in order; a linear field's data is exact there.
  REQUIRE(z.change.added() == 20);
  Eigen::RowVectorXd f(x.cols());
  for (Eigen::Index a = 0; a < x.cols(); ++a) f(a) = 1 + 2 * x(0, a) - 3 * x(1, a);
  const Eigen::RowVectorXd g = z.change.transfer(f);
  const Eigen::Index kept = x.cols() - 16;
  for (int t = 0; t < 20; ++t) {
    const Eigen::Vector2d p = z.change.positions(x).col(kept + t);
    CHECK((p - strip_zone(0.8).nodes.col(t)).norm() == 0.0);
    CHECK(g(kept + t) == Approx(1 + 2 * p.x() - 3 * p.y()).margin(1e-10));
  }
  // A wider emit spacing: the column at 6.4 crowds the material at 7.4 and goes.
  const ZoneUpdate wide = plan_zone_update(mesh, basis, strip_zone(1.2), id, h0, Eigen::VectorXd::Ones(20));
  CHECK(wide.emitted.empty());
  CHECK(wide.change.removed.size() == 20);
  // The surface's own emit spacing: the column's node on the material's
  // boundary (6.4, 0), 1 from the material's (7.4, 0), stays at 0.6; the
  // ones inside go (the top one is in the "tool").
  EulerianZone surface = strip_zone(1.2);
  surface.emit_surface_spacing = 0.6;
  surface.validate("test");
  const ZoneUpdate surf = plan_zone_update(mesh, basis, surface, id, h0, Eigen::VectorXd::Ones(20), admissible);
  REQUIRE(surf.emitted.size() == 1);
  CHECK((x.col(surf.emitted[0]) - Eigen::Vector2d(6.4, 0)).norm() < 1e-12);
  CHECK(surf.change.removed.size() == 19);
  // Not filled (a zone node beyond the material): nothing changes.
  EulerianZone beyond = strip_zone(0.8);
  beyond.inside = [](const Eigen::Vector2d& p) { return p.x() >= 3 - 1e-12 && p.x() <= 12; };
  beyond.nodes(0, 19) = 11.0;
  const ZoneUpdate none = plan_zone_update(mesh, basis, beyond, id, h0, Eigen::VectorXd::Ones(20));
  CHECK_FALSE(none.active);
  CHECK(none.change.empty());
  CHECK(in_material(mesh, Eigen::Vector2d(10.4, 2), 1e-9));
  CHECK_FALSE(in_material(mesh, Eigen::Vector2d(10.5, 2), 1e-3));
  // A node's own fill tolerance: 0.6 beyond the material's side at 10.4 is
  // not filled at fill_tol 0.25, filled at 0.75 on that node alone.
  beyond.nodes(0, 19) = 11.0;
  beyond.fill_tols.assign(20, 0.25);
  beyond.fill_tols[19] = 0.75;
  beyond.validate("test");
  CHECK(plan_zone_update(mesh, basis, beyond, id, h0, Eigen::VectorXd::Ones(20)).active);
  beyond.fill_tols[19] = 0.55;
  CHECK_FALSE(zone_filled(mesh, beyond, Eigen::VectorXd::Ones(20)));
  beyond.fill_tols.pop_back();
  CHECK_THROWS_WITH(beyond.validate("test"), Catch::Contains("fill_tols needs one value per zone node (20), got 19"));
  // A material node carried next to a zone node on the zone's edge (0.1
  // from it, within keep_out) goes with the nodes inside.
  Eigen::Matrix2Xd y = x;
  Eigen::Index m = -1;
  for (Eigen::Index a = 0; a < y.cols(); ++a)
    if (std::abs(y(0, a) - 2.4) < 1e-12 && y(1, a) == 2.0) m = a;
  REQUIRE(m >= 0);
  y(0, m) = 2.9;
  const IntegrationMesh<> ymesh(y);
  const MaxEntBasis<2> ybasis(y, ymesh.h());
  const ZoneUpdate zy = plan_zone_update(ymesh, ybasis, strip_zone(0.8), id, h0, Eigen::VectorXd::Ones(20), admissible);
  CHECK(std::count(zy.change.removed.begin(), zy.change.removed.end(), static_cast<int>(m)) == 1);
  CHECK(zy.change.removed.size() == 17);
  // A zone node outside its own region is refused with the node's place.
  EulerianZone bad = strip_zone(0.8);
  bad.nodes(0, 3) = 7.0;
  CHECK_THROWS_WITH(bad.validate("test"), Catch::Contains("node 3 at (7, 3) lies outside the zone"));
}

namespace {
// V1 (plane-strain compression between plates) on a 7 x 8 block, 10 x 12,
// with a 4 x 4 Eulerian zone over [2, 6] x [y0, y0 + 4], fixed in space or
// moving with the top plate (tool 1). The homogeneous field is linear, so
// the max-ent solution is exact on any cloud: the plate force stays exact
// and the block a rectangle while the zone's nodes come back to their
// places every step.
constexpr double zone_v1_V = 0.6, zone_v1_H0 = 12, zone_v1_W0 = 10;
Stepper<NortonHoff> zone_v1_block() {
  StepperParams prm;
  prm.dt = 1.0;
  prm.predictor = Predictor::material;
  prm.node_update = NodeUpdate::euler;
  prm.adapt.enabled = true;
  return Stepper<NortonHoff>(block_nodes(7, 8, zone_v1_W0, zone_v1_H0, false), NortonHoff(150.0, 0.2, 1e-8), prm);
}
EulerianZone zone_v1_zone(double y0, int tool) {
  EulerianZone zone;
  zone.tool = tool;
  zone.inside = [y0](const Eigen::Vector2d& p) { return p.x() >= 2 && p.x() <= 6 && p.y() >= y0 && p.y() <= y0 + 4; };
  zone.nodes.resize(2, 16);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) zone.nodes.col(4 * i + j) << 2 + 4.0 * i / 3, y0 + 4.0 * j / 3;
  return zone;
}
// Eight steps; the steps after the first whose solve had every zone node
// where the zone (moved with its tool) puts it.
int zone_v1_march(Stepper<NortonHoff>& s, const EulerianZone& zone) {
  const NortonHoff& mat = s.material();
  const double V = zone_v1_V, dt = s.parameters().dt;
  double W = zone_v1_W0, H = zone_v1_H0, max_force_error = 0;
  int in_place = 0;
  for (int k = 0; k < 8; ++k) {
    const double e = V / H, mu = mat.viscosity(2 * e / std::sqrt(3.0)).mu, F = 4 * mu * e * W;
    const Eigen::Vector2d d = zone.tool < 0 ? Eigen::Vector2d::Zero() : s.tools()[1].displacement();
    const auto& rec = s.step();
    max_force_error = std::max({max_force_error, std::abs(rec.tool_force[1].y() - F) / F,
                                std::abs(rec.tool_force[0].y() + F) / F});
    int found = 0;
    for (Eigen::Index t = 0; t < zone.nodes.cols(); ++t)
      for (Eigen::Index a = 0; a < s.nodes_solved().cols(); ++a)
        if ((s.nodes_solved().col(a) - zone.nodes.col(t) - d).norm() < 1e-12) {
          ++found;
          break;
        }
    if (k > 0 && rec.zone_active && found == 16) ++in_place;
    W *= 1 + e * dt;
    H -= V * dt;
    CHECK(s.nodes().row(0).maxCoeff() == Approx(W).epsilon(1e-8));
    CHECK(s.nodes().row(1).maxCoeff() == Approx(H).epsilon(1e-8));
    CHECK(s.nodes().row(0).minCoeff() == Approx(0).margin(1e-8));
  }
  CHECK(max_force_error < 1e-8);
  return in_place;
}
}  // namespace

TEST_CASE("V1 with an Eulerian zone: compression stays exact as the material flows through the zone",
          "[verification][stepper][zone]") {
  // The zone in the middle of the block: the material flows in from the
  // top, out at the sides and the bottom.
  Stepper<NortonHoff> s = zone_v1_block();
  add_plates(s, zone_v1_H0, zone_v1_V);
  const EulerianZone zone = zone_v1_zone(2, -1);
  s.set_eulerian_zone(zone);
  CHECK_THROWS_WITH(s.set_eulerian_zone(zone), Catch::Contains("has an Eulerian zone already"));
  CHECK(zone_v1_march(s, zone) == 7);
  // The zone's nodes are put back, not added: the count stays that of the block.
  CHECK(s.nodes().cols() >= 56 - 8);
  CHECK(s.nodes().cols() <= 56 + 16);
  CHECK(s.nodal_field("zone_node").maxCoeff() == 16);
}

TEST_CASE("Eulerian zone: slow outflow emitted ahead along its path; a zone translated", "[stepper][zone]") {
  // The block moved by 0.1 along x (a twelfth of a spacing, as behind a
  // cutting tool's tip): the zone's column from 6 is at 6.1, just out.
  Eigen::Matrix2Xd x = block_nodes(11, 5, 10, 4, false);
  Eigen::VectorXd id = Eigen::VectorXd::Zero(x.cols());
  for (Eigen::Index a = 0; a < x.cols(); ++a) {
    const double c = x(0, a);
    if (c >= 3 && c <= 6) id(a) = 5 * (c - 3) + x(1, a) + 1;
    x(0, a) += 0.1;
  }
  const IntegrationMesh<> mesh(x);
  const Eigen::VectorXd h0 = Eigen::VectorXd::Ones(x.cols());
  const MaxEntBasis<2> basis(x, mesh.h());
  // Where the step left them (emit_ahead 0): 0.1 from the zone's nodes.
  EulerianZone z = strip_zone(0.8);
  const ZoneUpdate here = plan_zone_update(mesh, basis, z, id, h0, Eigen::VectorXd::Ones(20));
  REQUIRE(here.emitted.size() == 5);
  for (Eigen::Index k = 0; k < 5; ++k) CHECK(here.emitted_at(0, k) == Approx(6.1));
  // emit_ahead 0.5: half a spacing downstream of their places, along their
  // displacement (+x), in the material and out of the zone (0.6 from the
  // material's column at 7.1, beyond an emit spacing of 0.5).
  z = strip_zone(0.5);
  z.emit_ahead = 0.5;
  z.validate("test");
  const ZoneUpdate ahead = plan_zone_update(mesh, basis, z, id, h0, Eigen::VectorXd::Ones(20));
  REQUIRE(ahead.emitted.size() == 5);
  for (Eigen::Index k = 0; k < 5; ++k) {
    CHECK(ahead.emitted_at(0, k) == Approx(6.5));
    CHECK(ahead.emitted_at(1, k) == Approx(x(1, ahead.emitted[static_cast<std::size_t>(k)])));
  }
  // An emitted node's data: the old cloud's interpolant where it goes (a
  // linear field exactly), not its zone place's half a spacing upstream.
  REQUIRE(ahead.emitted_weights.size() == 5);
  CHECK(ahead.emitted_fallbacks == 0);
  Eigen::MatrixXd field(2, x.cols());  // a linear field and a constant one
  for (Eigen::Index a = 0; a < x.cols(); ++a) field.col(a) << 1 + 2 * x(0, a) - 3 * x(1, a), 7.0;
  const Eigen::MatrixXd before = field;
  interpolate_emitted(ahead, field);
  for (std::size_t k = 0; k < 5; ++k) {
    const Eigen::Vector2d p = ahead.emitted_at.col(static_cast<Eigen::Index>(k));
    const int a = ahead.emitted[k];
    CHECK(field(0, a) == Approx(1 + 2 * p.x() - 3 * p.y()).margin(1e-10));
    CHECK(field(1, a) == Approx(7.0).margin(1e-12));
    CHECK(std::abs(before(0, a) - field(0, a)) > 0.5);  // half a spacing on: 2 * 0.4
  }
  for (Eigen::Index a = 0; a < x.cols(); ++a)
    if (std::find(ahead.emitted.begin(), ahead.emitted.end(), static_cast<int>(a)) == ahead.emitted.end())
      CHECK(field.col(a) == before.col(a));  // other nodes keep theirs
  // A zone node that leaves the region by a hair where it is not the
  // outflow (a slot in the region's top row, as behind a cutting tool's tip
  // where the machined surface rises a little): sent on along its path it
  // would land nearer the next zone node's place (6, 4) than its own, within
  // keep_out of it a step later. It goes, and comes back at its place.
  EulerianZone slot = z;
  slot.emit_ahead = 0.55;
  slot.inside = [](const Eigen::Vector2d& p) {
    const bool in_slot = p.y() > 3.5 && p.x() > 5.05 && p.x() < 5.95;
    return p.x() >= 3 - 1e-12 && p.x() <= 6 + 1e-12 && !in_slot;
  };
  slot.validate("test");
  const ZoneUpdate sz = plan_zone_update(mesh, basis, slot, id, h0, Eigen::VectorXd::Ones(20));
  REQUIRE(sz.emitted.size() == 5);  // the outflow column at 6.1 alone
  for (Eigen::Index k = 0; k < 5; ++k) CHECK(sz.emitted_at(0, k) == Approx(6.55));
  Eigen::Index hair = -1;
  for (Eigen::Index a = 0; a < x.cols(); ++a)
    if ((x.col(a) - Eigen::Vector2d(5.1, 4)).norm() < 1e-12) hair = a;
  REQUIRE(hair >= 0);
  CHECK(std::count(sz.change.removed.begin(), sz.change.removed.end(), static_cast<int>(hair)) == 1);
  // ... and not where that place is crowded: the material's column at 7.1
  // is 0.6 from 6.5, within an emit spacing of 0.7.
  EulerianZone crowded = z;
  crowded.emit_spacing = crowded.emit_surface_spacing = 0.7;
  CHECK(plan_zone_update(mesh, basis, crowded, id, h0, Eigen::VectorXd::Ones(20)).emitted.empty());
  z.emit_ahead = -1;
  CHECK_THROWS_WITH(z.validate("test"), Catch::Contains("emit_ahead must be >= 0"));
  // A zone translated: its nodes and its region move together.
  const EulerianZone moved = strip_zone(0.8).translated({1.5, -2});
  CHECK((moved.nodes.col(7) - strip_zone(0.8).nodes.col(7) - Eigen::Vector2d(1.5, -2)).norm() == 0.0);
  CHECK(moved.inside({7.4, 0}));
  CHECK_FALSE(moved.inside({4.4, 0}));
}

TEST_CASE("V1 with an Eulerian zone that moves with the top plate: compression stays exact",
          "[verification][stepper][zone]") {
  // The zone carried down by the plate (as a cutting tool's travels with
  // the tool), 2 below it: every step its nodes are where the plate has
  // taken them, and the homogeneous solution stays exact.
  Stepper<NortonHoff> s = zone_v1_block();
  const EulerianZone zone = zone_v1_zone(6, 1);
  CHECK_THROWS_WITH(s.set_eulerian_zone(zone), Catch::Contains("moves with tool 1 but the stepper has 0 tools"));
  add_plates(s, zone_v1_H0, zone_v1_V);
  s.set_eulerian_zone(zone);
  CHECK(zone_v1_march(s, zone) == 7);
}

TEST_CASE("V1 with rezoning: plane-strain compression to half height stays exact as nodes come and go",
          "[verification][stepper][rezoning]") {
  // The homogeneous field is linear, so the max-ent solution is exact on any
  // cloud: the force and the rectangle survive node removal and insertion.
  const double R0 = 10, H0 = 12, V = 0.06, dt = 1;
  const NortonHoff mat(150.0, 0.2, 1e-8);
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.dt = dt;
  prm.adapt.enabled = true;
  prm.adapt.min_ratio = 0.7;  // tight, so that a 2:1 compression rezones
  prm.adapt.max_ratio = 1.6;
  prm.node_update = NodeUpdate::euler;  // the shape check follows Eq. (18)'s path
  Stepper<NortonHoff> s(block_nodes(7, 8, R0, H0, false), mat, prm);
  add_plates(s, H0, V);
  double R = R0, H = H0, max_force_error = 0, max_shape_error = 0;
  int added = 0, removed = 0;
  for (int k = 0; k < 100; ++k) {
    const double e = V / H, d = 2 * e / std::sqrt(3.0);
    const double F = 4 * mat.viscosity(d).mu * e * R;
    const auto& rec = s.step();
    added += rec.nodes_added;
    removed += rec.nodes_removed;
    max_force_error = std::max({max_force_error, std::abs(rec.tool_force[1].y() - F) / F,
                                std::abs(rec.tool_force[1].x()) / F});
    // The solved configuration (the step start) is the R x H rectangle.
    max_shape_error = std::max(max_shape_error, std::abs(s.mesh().total_area() - R * H) / (R0 * H0));
    R *= 1 + e * dt;
    H -= V * dt;
    double xmax = 0, ymax = 0;
    for (Eigen::Index a = 0; a < s.nodes().cols(); ++a) {
      xmax = std::max(xmax, s.nodes()(0, a));
      ymax = std::max(ymax, s.nodes()(1, a));
      max_shape_error = std::max({max_shape_error, -s.nodes()(0, a) / R0, -s.nodes()(1, a) / R0});
    }
    max_shape_error = std::max({max_shape_error, std::abs(xmax - R) / R0, std::abs(ymax - H) / R0});
  }
  INFO("nodes added " << added << ", removed " << removed);
  CHECK(added > 0);
  CHECK(removed > 0);
  CHECK(max_force_error < 1e-8);
  CHECK(max_shape_error < 1e-8);
}

namespace {

// A contact law defined outside the library: sticking to a belt that runs
// along the tool at w relative to it (the tangential target v_tool . t + w).
struct Belt {
  double w = 0.0;
  std::string name() const { return "belt"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
    const Eigen::Vector2d t = c.tangent();
    out.push_back({t, tool.velocity().dot(t) + w, 1});
  }
};
static_assert(ContactLaw<Belt>);

// A traction law defined outside the library: the normal contact of the
// frictionless law plus a constant shear stress tau along the tool's tangent.
struct ConstantShear {
  double tau = 0.0;
  std::string name() const { return "constant shear"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
  }
  VelocityTraction traction(const ContactTractionPoint& q) const {
    return {tau * q.tangent(), Eigen::Matrix2d::Zero(), Eigen::Vector2d::Zero()};
  }
};
static_assert(TractionContactLaw<ConstantShear> && !TractionContactLaw<Belt>);

struct LawRun {
  StepRecord rec;
  double contact_length = 0.0;  // of the top plate's contact segments (both ends in contact)
  double max_tangential = 0.0, mean_tangential = 0.0;  // v . t on the top plate's contact nodes off the axis
  int contact_nodes = 0;
  std::string law;
};

// A plane-strain block (half width 8, height 6, symmetry at x = 0) pressed
// by a top plate (tool 1) carrying `law`; the bottom plate is frictionless.
std::unique_ptr<Stepper<NortonHoff>> block_press(AnyContactLaw law) {
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.dt = 0.5;
  auto s = std::make_unique<Stepper<NortonHoff>>(block_nodes(9, 7, 8, 6, false), NortonHoff(150.0, 0.2, 1e-7), prm);
  s->add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 100));
  RigidTool top = flat_plate("top", {0, 6}, {0, -1}, 100);
  top.set_velocity({0, -0.05});
  s->add_tool(std::move(top), std::move(law));
  s->add_velocity_condition({"axis", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
  return s;
}

// One step of block_press(law).
LawRun press_block(AnyContactLaw law) {
  const auto sim = block_press(std::move(law));
  auto& s = *sim;
  const Eigen::Vector2d t = s.tools()[1].closest({1, 7}).normal;  // the top plate's normal, +y
  LawRun p;
  p.rec = s.step();
  p.law = s.contact().law(1).name();
  const Eigen::Vector2d tangent(-t.y(), t.x());
  for (Eigen::Index a = 0; a < s.nodes_solved().cols(); ++a)
    // Off the symmetry axis, whose v_x = 0 comes first (a parallel row is not added).
    if (s.contact_flags()[static_cast<std::size_t>(a)] == 2 && s.nodes_solved()(0, a) > 1e-9) {
      const double vt = s.velocity().col(a).dot(tangent);
      p.max_tangential = std::max(p.max_tangential, std::abs(vt));
      p.mean_tangential += vt;
      ++p.contact_nodes;
    }
  p.mean_tangential /= std::max(p.contact_nodes, 1);
  for (const auto& seg : s.mesh().boundary_segments())
    if (s.contact_flags()[static_cast<std::size_t>(seg.a)] == 2 && s.contact_flags()[static_cast<std::size_t>(seg.b)] == 2)
      p.contact_length += seg.length;
  return p;
}

}  // namespace

TEST_CASE("contact laws: sticking holds the contact face, a law from outside the library plugs in",
          "[stepper][contact]") {
  const LawRun slip = press_block(Frictionless{});
  const LawRun stick = press_block(Sticking{});
  const LawRun belt = press_block(Belt{0.02});
  CHECK(slip.law == "frictionless");
  CHECK(stick.law == "sticking");
  CHECK(belt.law == "belt");
  REQUIRE(slip.contact_nodes >= 7);
  REQUIRE(stick.contact_nodes == slip.contact_nodes);
  // Frictionless: the face spreads with the block (v_x = e x, up to 0.05 / 6 * 8).
  CHECK(slip.max_tangential > 0.05);
  // Sticking: the face moves with the plate; the hat multipliers impose it on
  // average over each node's segments, so nodally to a few per cent.
  CHECK(stick.max_tangential < 0.05 * slip.max_tangential);
  // Friction raises the press force and pulls the plate outward (+x on the tool).
  const double F_slip = slip.rec.tool_force[1].y(), F_stick = stick.rec.tool_force[1].y();
  CHECK(F_stick > 1.05 * F_slip);
  CHECK(std::abs(slip.rec.tool_force[1].x()) < 1e-6 * F_slip);
  CHECK(stick.rec.tool_force[1].x() > 0.02 * F_stick);
  // The belt drags the face along at w.
  CHECK(belt.mean_tangential == Approx(0.02).epsilon(0.05));
}

TEST_CASE("contact laws: a traction law from outside the library acts on the contact segments",
          "[stepper][contact][friction]") {
  const LawRun slip = press_block(Frictionless{});
  // The top plate's normal is -y (into the workpiece), its tangent +x; tau < 0
  // drags the face toward the axis, as friction against the spreading does.
  const double tau = -20.0;  // about a third of the shear flow stress k here
  const LawRun shear = press_block(ConstantShear{tau});
  CHECK(shear.law == "constant shear");
  REQUIRE(shear.contact_length > 7.0);
  // The tool feels -int t: exactly -tau L along the tangent, since the basis
  // sums to one at each point.
  CHECK(shear.rec.tool_force[1].x() == Approx(-tau * shear.contact_length).epsilon(1e-9));
  // The face spreads less, and the press needs more force.
  CHECK(shear.mean_tangential < 0.8 * slip.mean_tangential);
  CHECK(shear.rec.tool_force[1].y() > 1.05 * slip.rec.tool_force[1].y());
}

namespace {
// A friction law's traction at q: at most `bound`, tangential, against the
// slip; dt/dv against central differences, dt/dk and dt/dp_n (= -dt/dlambda)
// exact steps (t is linear in k and in p_n on each branch).
template <class Law>
void check_friction_traction(const Law& law, const ContactTractionPoint& q, double bound) {
  const VelocityTraction vt = law.traction(q);
  CHECK(vt.t.norm() <= bound * (1 + 1e-14));
  CHECK(std::abs(vt.t.dot(q.normal)) < 1e-14 * q.k);  // tangential
  CHECK(vt.t.dot(q.slip()) <= 0.0);                   // opposes the slip
  for (int c = 0; c < 2; ++c) {
    const double h = 1e-7 * std::max(q.v.norm(), 1e-3);
    ContactTractionPoint p = q, m = q;
    p.v[c] += h;
    m.v[c] -= h;
    const Eigen::Vector2d fd = (law.traction(p).t - law.traction(m).t) / (2 * h);
    CHECK((fd - vt.dt_dv.col(c)).norm() <= 1e-6 * (vt.dt_dv.norm() + 1e-12));
  }
  ContactTractionPoint pk = q, pp = q;
  pk.k += 1.0;
  pp.p_n += 1.0;
  CHECK((law.traction(pk).t - vt.t - vt.dt_dk).norm() <= 1e-12 * vt.t.norm() + 1e-300);
  CHECK((law.traction(pp).t - vt.t + vt.dt_dlambda).norm() <= 1e-12 * vt.t.norm() + 1e-300);
}
// A contact point on a tilted tool moving down, with k = 50.
ContactTractionPoint tilted_point() {
  ContactTractionPoint q;
  q.normal = Eigen::Vector2d(0.6, -0.8);
  q.v_tool = Eigen::Vector2d(0.0, -0.05);
  q.k = 50.0;
  return q;
}
// A law with a zero coefficient gives the frictionless step.
void check_frictionless_limit(const LawRun& zero, const LawRun& slip) {
  CHECK(zero.rec.tool_force[1].y() == Approx(slip.rec.tool_force[1].y()).epsilon(1e-12));
  CHECK(zero.rec.tool_force[1].x() == 0.0);
  CHECK(std::abs(zero.mean_tangential - slip.mean_tangential) <= 1e-12 * slip.mean_tangential);
}
}  // namespace

TEST_CASE("Tresca friction: its traction's derivatives, the frictionless limit, the load rising with m",
          "[stepper][contact][friction]") {
  // The law alone: t = -m k (2/pi) atan(|v_s| / v0) v_s / |v_s|, against finite differences.
  const Tresca law(0.4, 0.01);
  ContactTractionPoint q = tilted_point();
  for (const Eigen::Vector2d& v : {Eigen::Vector2d(0.03, 0.01), Eigen::Vector2d(1e-4, -2e-4), Eigen::Vector2d(-2.0, 1.0)}) {
    q.v = v;
    check_friction_traction(law, q, law.m * q.k);
  }
  // Fast slip: the full friction stress m k.
  q.v = Eigen::Vector2d(0.8 * 100, 0.6 * 100 - 0.05);
  CHECK(law.traction(q).t.norm() == Approx(law.m * q.k).epsilon(2e-4));
  CHECK_THROWS_AS(Tresca(1.2, 0.01), Error);
  CHECK_THROWS_AS(Tresca(0.3, 0.0), Error);

  // In a step: m = 0 is the frictionless step; the press load and the drag
  // on the face rise with m, and m = 1 approaches sticking.
  const double v0 = 1e-3;  // 2 % of the plate speed
  const LawRun slip = press_block(Frictionless{});
  const LawRun zero = press_block(Tresca(0.0, v0));
  const LawRun stick = press_block(Sticking{});
  CHECK(zero.law == "tresca");
  check_frictionless_limit(zero, slip);
  double last_F = slip.rec.tool_force[1].y(), last_spread = slip.mean_tangential;
  for (double m : {0.2, 0.5, 1.0}) {
    CAPTURE(m);
    const LawRun r = press_block(Tresca(m, v0));
    const double F = r.rec.tool_force[1].y();
    CHECK(F > last_F);
    CHECK(r.mean_tangential < last_spread);
    CHECK(r.rec.tool_force[1].x() > 0);  // friction pulls the plate outward
    last_F = F;
    last_spread = r.mean_tangential;
  }
  // m = 1 with the shear stress capped at k: below sticking, within a few per cent.
  CHECK(last_F <= stick.rec.tool_force[1].y() * (1 + 1e-3));
  CHECK(last_F >= 0.95 * stick.rec.tool_force[1].y());
}

namespace {
// A law that records what its wrapped law reads and gives (the last sweep of
// a step is the post-processing at the converged solution).
struct Recorded {
  Coulomb law;
  std::shared_ptr<std::vector<std::pair<ContactTractionPoint, Eigen::Vector2d>>> log =
      std::make_shared<std::vector<std::pair<ContactTractionPoint, Eigen::Vector2d>>>();
  bool reads_pressure() const { return true; }
  std::string name() const { return "recorded coulomb"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt, std::vector<ContactCondition>& out) const {
    law.conditions(c, tool, dt, out);
  }
  VelocityTraction traction(const ContactTractionPoint& q) const {
    VelocityTraction vt = law.traction(q);
    log->emplace_back(q, vt.t);
    return vt;
  }
};
}  // namespace

TEST_CASE("Coulomb friction: its derivatives, the cap at k, mu = 0 frictionless, the load rising with mu",
          "[stepper][contact][friction]") {
  // The law alone: t = -min(mu p_n, k) (2/pi) atan(|v_s| / v0) v_s / |v_s|.
  const Coulomb law(0.2, 0.01);
  ContactTractionPoint q = tilted_point();
  for (double p_n : {100.0, 400.0}) {  // mu p_n below and above k
    q.p_n = p_n;
    for (const Eigen::Vector2d& v : {Eigen::Vector2d(0.03, 0.01), Eigen::Vector2d(-2.0, 1.0)}) {
      CAPTURE(p_n, v.transpose());
      q.v = v;
      check_friction_traction(law, q, std::min(law.mu * p_n, q.k));
      // Below the cap the stress follows p_n (dt/dlambda), at the cap k (dt/dk).
      const VelocityTraction vt = law.traction(q);
      CHECK((p_n * law.mu < q.k ? vt.dt_dk : vt.dt_dlambda).norm() == 0.0);
    }
  }
  q.p_n = -5.0;  // tensile: no friction
  CHECK(law.traction(q).t.norm() == 0.0);
  CHECK(reads_contact_pressure(law));
  CHECK(!reads_contact_pressure(Coulomb(0.0, 0.01)));  // mu = 0: no coupling at all
  CHECK(!reads_contact_pressure(Tresca(0.5, 0.01)));
  CHECK_THROWS_AS(Coulomb(-0.1, 0.01), Error);
  CHECK_THROWS_AS(Coulomb(0.1, 0.0), Error);

  // In a step: mu = 0 is the frictionless step; the load rises with mu and stays below sticking.
  const double v0 = 1e-3;
  const LawRun slip = press_block(Frictionless{});
  const LawRun zero = press_block(Coulomb(0.0, v0));
  const LawRun stick = press_block(Sticking{});
  CHECK(zero.law == "coulomb");
  check_frictionless_limit(zero, slip);
  double last_F = slip.rec.tool_force[1].y();
  for (double mu : {0.05, 0.1, 0.3}) {
    CAPTURE(mu);
    const LawRun r = press_block(Coulomb(mu, v0));
    const double F = r.rec.tool_force[1].y();
    CHECK(F > last_F);
    CHECK(F < stick.rec.tool_force[1].y());
    CHECK(r.rec.tool_force[1].x() > 0);
    last_F = F;
  }

  // At the converged solution: the friction stress never exceeds k, equals
  // mu p_n (times the smoothing) where the pressure is below k / mu, and both
  // regimes occur along the face for this mu (the pressure peaks at the axis).
  Recorded rec{Coulomb(0.1, v0)};
  const LawRun r = press_block(rec);
  REQUIRE(r.law == "recorded coulomb");
  const auto& log = *rec.log;
  // The last sweep: back from the end until a point repeats.
  std::size_t first = log.size();
  while (first > 0 && std::none_of(log.begin() + static_cast<std::ptrdiff_t>(first), log.end(), [&](const auto& e) {
           return (e.first.x - log[first - 1].first.x).norm() == 0.0;
         }))
    --first;
  REQUIRE(log.size() - first >= 2 * 6u);
  int sliding = 0, capped = 0;
  for (std::size_t i = first; i < log.size(); ++i) {
    const auto& [pt, t] = log[i];
    const double smooth = M_2_PI * std::atan(pt.slip().norm() / v0);
    CHECK(t.norm() <= pt.k * (1 + 1e-12));
    CHECK(pt.p_n > 0);
    if (0.1 * pt.p_n < pt.k) {
      CHECK(t.norm() == Approx(0.1 * pt.p_n * smooth).epsilon(1e-12));
      if (smooth > 0.95) ++sliding;
    } else {
      CHECK(t.norm() == Approx(pt.k * smooth).epsilon(1e-12));
      ++capped;
    }
  }
  CHECK(sliding > 0);
  INFO("Gauss points with mu p_n >= k: " << capped);
}

TEST_CASE("sticking upsetting (E1): the first-step force over the frictionless one converges below the slab estimate",
          "[stepper][contact][friction]") {
  // E1's billet (R 10, H 12, axisymmetric) between sticking plates, one step
  // from rest on grids nx x ny: F / F_frictionless, which Avitzur's slab
  // method bounds crudely from above by 1 + 2 m R / (3 sqrt(3) H) = 1.321
  // (m = 1); and the free side barrels.
  const double R0 = 10, H0 = 12, V = 0.06;
  const NortonHoff mat(150.0, 0.2, 1e-6 * V / H0);
  const double e = V / H0, F0 = 3 * mat.viscosity(e).mu * e * M_PI * R0 * R0;
  std::vector<double> ratio;
  for (const auto& [nx, ny] : {std::pair{6, 7}, std::pair{11, 13}, std::pair{21, 25}}) {
    StepperParams prm;
    prm.geometry = Geometry::axisymmetric;
    prm.dt = 1.0;
    Stepper<NortonHoff> s(block_nodes(nx, ny, R0, H0, false), mat, prm);
    add_plates(s, H0, V, Sticking{});
    const StepRecord rec = s.step();
    INFO(nx << " x " << ny << ": " << rec.substeps << " substeps " << rec.note);
    ratio.push_back(rec.tool_force[1].y() / F0);
    // The free side: v_r at mid-height well above v_r at the plate's edge.
    const auto& x = s.nodes_solved();
    const auto& v = s.velocity();
    const Eigen::Index mid = nx * (ny / 2) + nx - 1, corner = nx * ny - 1;
    REQUIRE(x(0, mid) == Approx(R0));
    REQUIRE(x(1, corner) == Approx(H0));
    CHECK(v(0, mid) - v(0, corner) > 0.5 * e * R0 / 2);
  }
  INFO("F / F_frictionless on 6 x 7, 11 x 13, 21 x 25: " << ratio[0] << ", " << ratio[1] << ", " << ratio[2]);
  CHECK(ratio[2] > 1.15);
  CHECK(ratio[2] < 1.321);
  // Converging: each refinement moves the ratio by less than half the last change.
  CHECK(std::abs(ratio[2] - ratio[1]) < 0.5 * std::abs(ratio[1] - ratio[0]));
  CHECK(std::abs(ratio[2] - ratio[1]) < 2e-3 * ratio[2]);
}

TEST_CASE("a stalled Newton hands back to Picard: sticking upsetting with the kept LU carried into every solve",
          "[stepper][contact][friction][solver]") {
  // E1's billet between sticking plates, 21 x 25, one step from rest, with
  // the kept LU tried at the start of every solve (kept_lu_skip_carry 1).
  // The resume after the active-set check then starts Newton where the dead
  // zone's viscosity (strain rate near d_min) lets it make only line-search
  // steps of 1/32: without the stall rule it spent its 60 iterations there
  // and the step was retried at dt/2. The step must be taken at once, with
  // the force of the default settings.
  const double R0 = 10, H0 = 12, V = 0.06;
  const NortonHoff mat(150.0, 0.2, 1e-6 * V / H0);
  std::vector<double> force;
  for (const int skip : {4, 1}) {
    StepperParams prm;
    prm.geometry = Geometry::axisymmetric;
    prm.dt = 1.0;
    prm.solver.kept_lu_skip_carry = skip;
    Stepper<NortonHoff> s(block_nodes(21, 25, R0, H0, false), mat, prm);
    add_plates(s, H0, V, Sticking{});
    const StepRecord rec = s.step();
    INFO("kept_lu_skip_carry " << skip << ": " << rec.substeps << " substeps " << rec.note);
    CHECK(rec.substeps == 1);
    force.push_back(rec.tool_force[1].y());
  }
  CHECK(force[1] == Approx(force[0]).epsilon(1e-6));
}

TEST_CASE("contact fields on the nodes: the pressure integrates to the press force, friction stress and slip",
          "[stepper][contact][friction]") {
  // Frictionless and Tresca: sum p_a int N_a ds over the top plate's contact
  // nodes is the plate force (plane strain, hat rows only); the friction stress
  // is m k-like under Tresca (between 0 and the largest k), zero without friction.
  for (const bool tresca : {false, true}) {
    CAPTURE(tresca);
    const auto sim = block_press(tresca ? AnyContactLaw(Tresca(0.5, 1e-3)) : AnyContactLaw(Frictionless{}));
    auto& s = *sim;
    const StepRecord rec = s.step();
    const auto& pn = s.nodal_field("contact_pressure");
    const auto& tau = s.nodal_field("friction_stress");
    const auto& slip = s.nodal_field("slip_velocity");
    // int N_a ds over the top plate's contact segments.
    Eigen::VectorXd len = Eigen::VectorXd::Zero(s.nodes_solved().cols());
    for (const auto& seg : s.mesh().boundary_segments())
      if (s.contact_flags()[static_cast<std::size_t>(seg.a)] == 2 && s.contact_flags()[static_cast<std::size_t>(seg.b)] == 2) {
        len[seg.a] += seg.length / 2;
        len[seg.b] += seg.length / 2;
      }
    double F = 0.0;
    int top_nodes = 0;
    for (Eigen::Index a = 0; a < s.nodes_solved().cols(); ++a) {
      const int flag = s.contact_flags()[static_cast<std::size_t>(a)];
      if (flag == 0) {
        CHECK(pn(0, a) == 0.0);
        CHECK(tau(0, a) == 0.0);
        CHECK(slip.col(a).norm() == 0.0);
        continue;
      }
      CHECK(pn(0, a) > 0);
      CHECK(std::abs(slip(1, a)) < 1e-12);  // along the plates
      if (flag != 2) continue;
      ++top_nodes;
      F += pn(0, a) * len[a];
      if (tresca)
        CHECK((tau(0, a) > 0 && tau(0, a) < 0.5 * 150.0));
      else
        CHECK(tau(0, a) == 0.0);
      if (s.nodes_solved()(0, a) > 1.0) CHECK(slip(0, a) > 0);  // the face spreads outward
    }
    REQUIRE(top_nodes >= 7);
    CHECK(F == Approx(rec.tool_force[1].y()).epsilon(1e-9));
  }
}

TEST_CASE("power balance: the press delivers the dissipation; friction's and the stabilization's shares",
          "[stepper][contact][friction]") {
  // V1 / V2: the homogeneous flow dissipates 2 mu D:D = 3 mu e^2 and nothing
  // else (div v = 0, grad p = 0); the top plate's load times its speed is all of it.
  for (const Geometry g : {Geometry::axisymmetric, Geometry::plane_strain}) {
    CAPTURE(g == Geometry::axisymmetric);
    StepperParams prm;
    prm.geometry = g;
    prm.dt = 1.0;
    const double R0 = 10, H0 = 12, V = 0.06;
    const NortonHoff mat(150.0, 0.2, 1e-8);
    Stepper<NortonHoff> s(block_nodes(7, 8, R0, H0, false), mat, prm);
    add_plates(s, H0, V);
    for (int k = 0; k < 4; ++k) {
      const StepRecord& r = s.step();
      CAPTURE(k, r.power.plastic, r.power.volumetric, r.power.constraints, r.tool_power);
      CHECK(r.tool_power == Approx(r.tool_force[1].y() * V).epsilon(1e-14));
      CHECK(r.power.constraints == Approx(r.tool_power).epsilon(1e-12));
      CHECK(r.power.tractions == 0.0);
      CHECK(r.power.plastic == Approx(r.tool_power).epsilon(1e-9));
      CHECK(std::abs(r.power.volumetric) <= 1e-9 * r.power.plastic);
    }
  }
  // A block pressed by a plate with Coulomb friction: the load's power is the
  // plastic, the friction and the stabilization's dissipation (the flow is
  // not homogeneous: grad p != 0).
  const StepRecord r = press_block(Coulomb(0.1, 1e-3)).rec;
  CAPTURE(r.power.plastic, r.power.volumetric, r.power.constraints, r.power.tractions, r.tool_power);
  CHECK(r.power.constraints == Approx(r.tool_power).epsilon(1e-12));
  CHECK(r.power.delivered() == Approx(r.power.dissipated()).epsilon(1e-8));
  CHECK(-r.power.tractions > 0.01 * r.tool_power);  // friction dissipates
  CHECK(r.power.volumetric > 1e-4 * r.power.plastic);
  CHECK(r.power.volumetric < 0.05 * r.power.plastic);
}

TEST_CASE("step control is a policy: a controller that never retries fails at the first attempt",
          "[stepper]") {
  struct OneTry {
    int substeps(int failures) const { return failures == 0 ? 1 : 0; }
  };
  static_assert(StepControl<OneTry> && StepControl<HalvingRetry>);
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.solver.max_iterations = 1;  // no solve can converge
  Stepper<NortonHoff, GmresSolver<>, OneTry> s(block_nodes(5, 5, 4, 4, false), NortonHoff(), prm);
  RigidTool top = flat_plate("top", {0, 4}, {0, -1}, 50);
  top.set_velocity({0, -0.1});
  s.add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 50));
  s.add_tool(top);
  s.add_velocity_condition({"symmetry", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
  try {
    s.step();
    FAIL("no exception");
  } catch (const Error& e) {
    const std::string what = e.what();
    CHECK_THAT(what, Catch::Contains("failed after 1 attempts") && Catch::Contains("no convergence"));
    CHECK_THAT(what, !Catch::Contains("dt/2"));
  }
  CHECK(s.steps_done() == 0);
  CHECK(HalvingRetry{2}.substeps(2) == 4);
  CHECK(HalvingRetry{2}.substeps(3) == 0);
}

TEST_CASE("nodal fields: a field the user registers travels with the material through rezoning and "
          "reaches the VTU",
          "[stepper][rezoning][results]") {
  // Homogeneous plane-strain compression (V1) with tight rezoning limits: a
  // material point moves as x = s x0, so a field holding each node's initial
  // x must stay x / s on every node, kept, removed around or inserted (an
  // inserted node gets the mean of its edge's ends, exact for a linear field).
  const double R0 = 10, H0 = 12, V = 0.06, dt = 1;
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.dt = dt;
  prm.adapt.enabled = true;
  prm.adapt.min_ratio = 0.7;
  prm.adapt.max_ratio = 1.6;
  Stepper<NortonHoff> s(block_nodes(7, 8, R0, H0, false), NortonHoff(150.0, 0.2, 1e-8), prm);
  add_plates(s, H0, V);
  s.add_nodal_field("x0", 1);
  s.nodal_field("x0") = s.nodes().row(0);
  CHECK_THROWS_AS(s.add_nodal_field("x0", 1), Error);
  CHECK_THROWS_WITH(s.nodal_field("temperature"), Catch::Contains("no nodal field 'temperature'"));
  const auto dir = std::filesystem::temp_directory_path() / "maxentflow_test_nodal_fields";
  std::filesystem::remove_all(dir);
  ResultsWriter out(dir);
  double max_error = 0;
  int added = 0, removed = 0;
  for (int k = 0; k < 100 && (added == 0 || removed == 0); ++k) {
    const auto& rec = s.step();
    added += rec.nodes_added;
    removed += rec.nodes_removed;
    const double stretch = s.nodes().row(0).maxCoeff() / R0;  // homogeneous: x = stretch x0
    const Eigen::MatrixXd& x0 = s.nodal_field("x0");
    REQUIRE(x0.cols() == s.nodes().cols());
    for (Eigen::Index a = 0; a < x0.cols(); ++a)
      max_error = std::max(max_error, std::abs(x0(0, a) - s.nodes()(0, a) / stretch) / R0);
    out.record(s, true);
  }
  INFO("nodes added " << added << ", removed " << removed);
  CHECK(added > 0);
  CHECK(removed > 0);
  CHECK(max_error < 1e-8);
  // The last VTU has the field, one value per node of the solved configuration.
  const int last = s.steps_done();
  char name[32];
  std::snprintf(name, sizeof name, "step_%04d.vtu", last);
  const std::string xml = slurp(dir / name);
  CHECK(xml.find("Name=\"x0\"") != std::string::npos);
  check_vtu(dir / name, static_cast<int>(s.nodes_solved().cols()));
  std::filesystem::remove_all(dir);
}

namespace {

// Axisymmetric frictionless upsetting to a 25 % stroke with steps of dt:
// the largest relative difference between the plate force and the force on
// the continuum path (R^2 H = R0^2 H0), and the largest volume change.
std::pair<double, double> upsetting_path_error(NodeUpdate update, double dt) {
  const double R0 = 10, H0 = 12, V = 0.06;
  const NortonHoff mat(150.0, 0.2, 1e-8);
  StepperParams prm;
  prm.geometry = Geometry::axisymmetric;
  prm.dt = dt;
  prm.node_update = update;
  Stepper<NortonHoff> s(block_nodes(7, 8, R0, H0, false), mat, prm);
  add_plates(s, H0, V);
  double force = 0, volume = 0;
  const int steps = static_cast<int>(std::lround(0.25 * H0 / V / dt));
  for (int k = 0; k < steps; ++k) {
    const double H = H0 - V * dt * k;  // the plate is exact: the solved configuration's height
    const double e = V / H, Rc2 = R0 * R0 * H0 / H;
    const double Fc = 3 * mat.viscosity(e).mu * e * M_PI * Rc2;
    const auto& rec = s.step();
    const double R = s.nodes_solved().row(0).maxCoeff();
    force = std::max(force, std::abs(rec.tool_force[1].y() - Fc) / Fc);
    volume = std::max(volume, std::abs(R * R * H / (R0 * R0 * H0) - 1));
  }
  return {force, volume};
}

}  // namespace

TEST_CASE("node update: Adams-Bashforth 2 follows the continuum path to second order, Eq. (18) to first",
          "[verification][stepper]") {
  const auto [ab_force, ab_volume] = upsetting_path_error(NodeUpdate::adams_bashforth2, 1.0);
  const auto [ab_force2, ab_volume2] = upsetting_path_error(NodeUpdate::adams_bashforth2, 2.0);
  const auto [eu_force, eu_volume] = upsetting_path_error(NodeUpdate::euler, 1.0);
  const auto [eu_force2, eu_volume2] = upsetting_path_error(NodeUpdate::euler, 2.0);
  INFO("AB2: force " << ab_force << " (dt 2: " << ab_force2 << "), volume " << ab_volume << "; Euler: force "
                     << eu_force << " (dt 2: " << eu_force2 << "), volume " << eu_volume);
  // E1's targets (dt = 1): force within 1e-4 of the continuum path, volume within 0.01 %.
  CHECK(ab_force < 1e-4);
  CHECK(ab_volume < 1e-4);
  CHECK(eu_force > 10 * ab_force);
  // Observed orders from dt = 2 to dt = 1: 2 and 1.
  CHECK(std::log2(ab_force2 / ab_force) > 1.8);
  CHECK(std::log2(eu_force2 / eu_force) == Approx(1.0).margin(0.2));
  CHECK(std::log2(ab_volume2 / ab_volume) > 1.8);
}

TEST_CASE("checkpoint: a stepper loaded from a saved state goes on bitwise as the one that saved it; a "
          "checkpoint that does not fit is refused and changes nothing",
          "[stepper][checkpoint]") {
  // Plane-strain compression with rezoning (nodes come and go) and a user field.
  const double R0 = 10, H0 = 12, V = 1;  // 7 steps to 42 % of the height
  StepperParams prm;
  prm.geometry = Geometry::plane_strain;
  prm.dt = 1;
  prm.adapt.enabled = true;
  prm.adapt.min_ratio = 0.7;
  prm.adapt.max_ratio = 1.6;
  auto make = [&](const std::string& top_name = "top") {
    auto s = std::make_unique<Stepper<NortonHoff>>(block_nodes(7, 8, R0, H0, false), NortonHoff(150.0, 0.2, 1e-8), prm);
    s->add_tool(flat_plate("bottom", {0, 0}, {0, 1}, 100));
    RigidTool top = flat_plate(top_name, {0, H0}, {0, -1}, 100);
    top.set_velocity({0, -V});
    s->add_tool(top);
    s->add_velocity_condition({"axis", on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0});
    s->add_nodal_field("x0", 1);
    s->nodal_field("x0") = s->nodes().row(0);
    return s;
  };
  auto a = make();
  for (int k = 0; k < 3; ++k) a->step();
  CheckpointOut out;
  a->save(out);
  const std::string bytes = out.bytes();
  for (int k = 0; k < 4; ++k) a->step();

  auto b = make();
  CheckpointIn in(bytes, "memory");
  b->load(in);
  in.expect_end();
  CHECK(b->steps_done() == 3);
  CHECK(b->history().size() == 3);
  CHECK_THROWS_WITH(b->mesh(), Catch::Contains("no step solved yet"));
  for (int k = 0; k < 4; ++k) b->step();
  CHECK(b->steps_done() == a->steps_done());
  CHECK(b->time() == a->time());
  REQUIRE(b->nodes().cols() == a->nodes().cols());
  CHECK(b->nodes() == a->nodes());  // bitwise
  CHECK(b->nodal_field("x0") == a->nodal_field("x0"));
  CHECK(b->effective_strain() == a->effective_strain());
  CHECK(b->tools()[1].displacement() == a->tools()[1].displacement());
  CHECK(b->history().back().tool_force[1] == a->history().back().tool_force[1]);
  CHECK(std::any_of(a->history().begin(), a->history().end(),
                    [](const StepRecord& r) { return r.nodes_added + r.nodes_removed > 0; }));

  SECTION("another set of tools or fields is refused, the stepper unchanged") {
    auto c = make("punch");
    const Eigen::Matrix2Xd x0 = c->nodes();
    CheckpointIn in2(bytes, "memory");
    CHECK_THROWS_WITH(c->load(in2), Catch::Contains("tool 'top' where this run has 'punch'"));
    CHECK(c->nodes() == x0);
    CHECK(c->steps_done() == 0);
    auto d = make();
    d->add_nodal_field("temperature", 1);
    CheckpointIn in3(bytes, "memory");
    CHECK_THROWS_WITH(d->load(in3), Catch::Contains("nodal fields, this run registers"));
    CHECK(d->steps_done() == 0);
  }
}

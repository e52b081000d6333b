// Rigid tools: closest points, normals and signed gaps against hand-computed values,
// the orientation convention (material on the left), motion, sampling, the helper
// geometries (cutting tool angles and edge radius tangency) and bad input.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <maxentflow/contact/rigid_tool.hpp>

using maxentflow::BoxSide;
using maxentflow::Error;
using maxentflow::RigidTool;
using maxentflow::ToolClosure;
using maxentflow::ToolPiece;
using maxentflow::ToolProjection;
using V2 = Eigen::Vector2d;

namespace {

constexpr double pi = std::numbers::pi;
constexpr double deg = pi / 180.0;
const double s2 = std::sqrt(2.0);

bool near(const V2& a, const V2& b, double tol = 1e-12) {
  return (a - b).norm() <= tol;
}

// Checks one projection against hand-computed point, normal and gap.
void check(const ToolProjection& p, const V2& point, const V2& normal, double gap,
           bool at_corner = false) {
  INFO("point " << p.point.transpose() << ", normal " << p.normal.transpose() << ", gap " << p.gap
                << ", at_corner " << p.at_corner);
  CHECK(near(p.point, point));
  CHECK(near(p.normal, normal));
  CHECK(p.gap == Approx(gap).margin(1e-12));
  CHECK(p.distance == Approx(std::abs(gap)).margin(1e-12));
  CHECK(p.at_corner == at_corner);
}

// Every projection: unit normal and x - point = gap * normal.
void check_consistent(const RigidTool& tool, const V2& x) {
  const auto p = tool.closest(x);
  INFO("x = " << x.transpose());
  CHECK(p.normal.norm() == Approx(1.0).epsilon(1e-14));
  CHECK(near(x - p.point, p.gap * p.normal, 1e-10));
  CHECK(tool.signed_distance(x) == Approx(p.gap).margin(1e-10));
  CHECK(tool.gap(x) == p.gap);
}

// Signed distance to the box centre c +- half with corners rounded by r (> 0 outside).
double rounded_box_sdf(const V2& x, const V2& c, const V2& half, double r) {
  const V2 q = (x - c).cwiseAbs() - (half - V2::Constant(r));
  return q.cwiseMax(0.0).norm() + std::min(std::max(q.x(), q.y()), 0.0) - r;
}

Eigen::Matrix2Xd points(std::initializer_list<V2> list) {
  Eigen::Matrix2Xd m(2, static_cast<Eigen::Index>(list.size()));
  Eigen::Index k = 0;
  for (const auto& p : list) m.col(k++) = p;
  return m;
}

}  // namespace

TEST_CASE("flat plate: both sides, beyond its ends, tilted", "[contact][tool]") {
  const auto plate = maxentflow::flat_plate("plate", V2(0, 0), V2(0, 2), 2.0);
  REQUIRE(plate.name() == "plate");
  REQUIRE(plate.pieces().size() == 1);
  CHECK(near(plate.pieces()[0].start, V2(-2, 0)));
  CHECK(near(plate.pieces()[0].end, V2(2, 0)));
  CHECK(plate.length() == Approx(4.0));

  check(plate.closest(V2(0.5, 1.5)), V2(0.5, 0), V2(0, 1), 1.5);
  // Penetration through a thin open tool: still the plate's normal side, gap < 0.
  check(plate.closest(V2(0.5, -0.3)), V2(0.5, 0), V2(0, 1), -0.3);
  CHECK(plate.signed_distance(V2(0.5, -0.3)) == Approx(-0.3));
  check(plate.closest(V2(1, 0)), V2(1, 0), V2(0, 1), 0.0);
  // Beyond the open end: the end point, normal along x - end, side from the plate's normal.
  check(plate.closest(V2(3, 1)), V2(2, 0), V2(1, 1) / s2, s2, true);
  check(plate.closest(V2(3, -1)), V2(2, 0), V2(-1, 1) / s2, -s2, true);
  check(plate.closest(V2(-3, 1)), V2(-2, 0), V2(-1, 1) / s2, s2, true);

  const auto tilted = maxentflow::flat_plate("tilted", V2(1, 1), V2(1, 1), 3.0);
  check(tilted.closest(V2(2, 2)), V2(1, 1), V2(1, 1) / s2, s2);
  check(tilted.closest(V2(0, 3)), V2(-0.5, 2.5), V2(1, 1) / s2, 1 / s2);
  check(tilted.closest(V2(0, 0)), V2(1, 1), V2(1, 1) / s2, -s2);
}

TEST_CASE("solid rectangle: faces, convex corners, inside points", "[contact][tool]") {
  const auto block = maxentflow::rectangle("block", V2(0, 0), V2(2, 1));
  REQUIRE(block.closed());
  REQUIRE(block.pieces().size() == 4);
  CHECK(block.length() == Approx(6.0));
  const auto corners = block.convex_corners();
  REQUIRE(corners.size() == 4);  // material outside: every corner points into it
  for (const V2& c : {V2(0, 0), V2(2, 0), V2(2, 1), V2(0, 1)})
    CHECK(std::count_if(corners.begin(), corners.end(), [&](const V2& q) { return near(q, c); }) == 1);

  check(block.closest(V2(1, 1.5)), V2(1, 1), V2(0, 1), 0.5);
  check(block.closest(V2(-0.5, 0.5)), V2(0, 0.5), V2(-1, 0), 0.5);
  check(block.closest(V2(1, -0.25)), V2(1, 0), V2(0, -1), 0.25);
  check(block.closest(V2(2.5, 0.5)), V2(2, 0.5), V2(1, 0), 0.5);
  // Convex corners: normal (x - vertex)/|x - vertex|.
  check(block.closest(V2(3, 2)), V2(2, 1), V2(1, 1) / s2, s2, true);
  check(block.closest(V2(-1, -2)), V2(0, 0), V2(-1, -2) / std::sqrt(5.0), std::sqrt(5.0), true);
  check(block.closest(V2(2.3, -0.4)), V2(2, 0), V2(0.6, -0.8), 0.5, true);
  // On the corner itself: the bisector of the two faces' normals, gap 0.
  check(block.closest(V2(2, 1)), V2(2, 1), V2(1, 1) / s2, 0.0, true);
  check(block.closest(V2(0, 0)), V2(0, 0), V2(-1, -1) / s2, 0.0, true);
  // Inside: nearest face, gap < 0.
  check(block.closest(V2(1.8, 0.7)), V2(2, 0.7), V2(1, 0), -0.2);
  check(block.closest(V2(0.5, 0.1)), V2(0.5, 0), V2(0, -1), -0.1);
  check(block.closest(V2(0.1, 0.8)), V2(0, 0.8), V2(-1, 0), -0.1);

  // Against the exact signed distance of a box on a grid (both sides, all corners).
  for (double x = -1.0; x <= 3.0; x += 0.07)
    for (double y = -1.0; y <= 2.0; y += 0.07) {
      const V2 p(x, y);
      INFO("x = " << p.transpose());
      CHECK(block.gap(p) == Approx(rounded_box_sdf(p, V2(1, 0.5), V2(1, 0.5), 0.0)).margin(1e-12));
      check_consistent(block, p);
    }
}

TEST_CASE("container: material inside, concave corners, open side", "[contact][tool]") {
  const auto box = maxentflow::container("box", V2(0, 0), V2(4, 3));
  REQUIRE_FALSE(box.closed());
  REQUIRE(box.pieces().size() == 3);
  CHECK(near(box.pieces()[0].start, V2(0, 3)));  // open top: left wall first
  CHECK(near(box.pieces()[2].end, V2(4, 3)));
  CHECK(box.convex_corners().empty());  // concave corners and open ends only
  // The two bottom corners, each with its two walls' normals (in, out along the tool).
  const auto concave = box.concave_corners();
  REQUIRE(concave.size() == 2);
  CHECK(near(concave[0].point, V2(0, 0)));
  CHECK(near(concave[0].n_in, V2(1, 0)));
  CHECK(near(concave[0].n_out, V2(0, 1)));
  CHECK(near(concave[1].point, V2(4, 0)));
  CHECK(near(concave[1].n_in, V2(0, 1)));
  CHECK(near(concave[1].n_out, V2(-1, 0)));

  check(box.closest(V2(1, 0.5)), V2(1, 0), V2(0, 1), 0.5);
  check(box.closest(V2(0.5, 2)), V2(0, 2), V2(1, 0), 0.5);
  check(box.closest(V2(3.5, 2)), V2(4, 2), V2(-1, 0), 0.5);
  check(box.closest(V2(1, -0.2)), V2(1, 0), V2(0, 1), -0.2);
  check(box.closest(V2(4.5, 1)), V2(4, 1), V2(-1, 0), -0.5);
  // Behind a concave corner (inside the tool): the vertex, gap < 0, normal into the box.
  check(box.closest(V2(-1, -1)), V2(0, 0), V2(1, 1) / s2, -s2, true);
  check(box.closest(V2(5, -2)), V2(4, 0), V2(-1, 2) / std::sqrt(5.0), -std::sqrt(5.0), true);
  check(box.closest(V2(0, 0)), V2(0, 0), V2(1, 1) / s2, 0.0, true);

  // Open on the right: top wall first, running -x; beyond the bottom wall's open end.
  const auto side = maxentflow::container("side", V2(0, 0), V2(4, 3), BoxSide::right);
  CHECK(near(side.pieces()[0].start, V2(4, 3)));
  check(side.closest(V2(2, 2.5)), V2(2, 3), V2(0, -1), 0.5);
  check(side.closest(V2(5, 0.5)), V2(4, 0), V2(1, 0.5) / std::sqrt(1.25), std::sqrt(1.25), true);
  check(side.closest(V2(5, -0.5)), V2(4, 0), V2(-1, 0.5) / std::sqrt(1.25), -std::sqrt(1.25), true);
}

TEST_CASE("arcs: convex edge radii and concave fillets", "[contact][tool]") {
  // 2 x 1 block with radius 0.5 corners: the arcs use up the short sides entirely.
  const auto punch = maxentflow::rectangle("punch", V2(0, 0), V2(2, 1), 0.5);
  REQUIRE(punch.pieces().size() == 6);
  int arcs = 0;
  for (const auto& p : punch.pieces()) {
    if (p.kind != ToolPiece::Kind::arc) continue;
    ++arcs;
    CHECK(p.radius == 0.5);
    CHECK(p.sweep == Approx(-pi / 2));  // clockwise: convex
  }
  CHECK(arcs == 4);
  CHECK(punch.length() == Approx(2.0 + pi));  // two unit segments and a full circle

  const V2 c(1.5, 0.5);  // top-right arc centre
  check(punch.closest(V2(2.5, 1.5)), c + 0.5 * V2(1, 1) / s2, V2(1, 1) / s2, s2 - 0.5);
  check(punch.closest(V2(1.7, 0.7)), c + 0.5 * V2(1, 1) / s2, V2(1, 1) / s2, 0.2 * s2 - 0.5);
  check(punch.closest(V2(2.5, 0.5)), V2(2, 0.5), V2(1, 0), 0.5);  // where two arcs meet
  check(punch.closest(V2(1, 1.25)), V2(1, 1), V2(0, 1), 0.25);
  check(punch.closest(V2(0.2, 0.5)), V2(0, 0.5), V2(-1, 0), -0.2);

  for (double x = -1.0; x <= 3.0; x += 0.07)
    for (double y = -1.0; y <= 2.0; y += 0.07) {
      const V2 p(x, y);
      INFO("x = " << p.transpose());
      CHECK(punch.gap(p) == Approx(rounded_box_sdf(p, V2(1, 0.5), V2(1, 0.5), 0.5)).margin(1e-12));
      check_consistent(punch, p);
    }

  // Concave fillet of radius 1 in a container's bottom-left corner, centre (1, 1).
  const auto cup = maxentflow::container("cup", V2(0, 0), V2(4, 3), BoxSide::top, 1.0);
  REQUIRE(cup.pieces().size() == 5);
  CHECK(cup.pieces()[1].kind == ToolPiece::Kind::arc);
  CHECK(cup.pieces()[1].sweep == Approx(pi / 2));  // counter-clockwise: concave
  const V2 f(1, 1);
  check(cup.closest(V2(0.5, 0.5)), f - V2(1, 1) / s2, V2(1, 1) / s2, 1 - 0.5 * s2);
  check(cup.closest(V2(-0.5, -0.5)), f - V2(1, 1) / s2, V2(1, 1) / s2, 1 - 1.5 * s2);
  check(cup.closest(V2(2, 0.5)), V2(2, 0), V2(0, 1), 0.5);
  check(cup.closest(V2(0.5, 2)), V2(0, 2), V2(1, 0), 0.5);

  // An explicit arc: a semicircular nose, clockwise from (-1, 0) over (0, 1) to (1, 0).
  const RigidTool nose("nose", {ToolPiece::arc(V2(0, 0), 1.0, pi, -pi)});
  check(nose.closest(V2(0, 3)), V2(0, 1), V2(0, 1), 2.0);
  check(nose.closest(V2(0, 0.5)), V2(0, 1), V2(0, 1), -0.5);
  check(nose.closest(V2(-2, 2)), V2(-1, 1) / s2, V2(-1, 1) / s2, 2 * s2 - 1);
  check(nose.closest(V2(2, -1)), V2(1, 0), V2(1, -1) / s2, s2, true);
  // Just past the open end: the end point, not the circle continued beyond the sweep.
  check(nose.closest(V2(2, -0.01)), V2(1, 0), V2(1, -0.01) / std::hypot(1, 0.01),
        std::hypot(1, 0.01), true);
  const double d = std::hypot(0.5, 0.1);
  check(nose.closest(V2(0.5, -0.1)), V2(1, 0), V2(0.5, 0.1) / d, -d, true);
}

TEST_CASE("moving tool: move(dt), translate, stroke", "[contact][tool]") {
  auto plate = maxentflow::flat_plate("top", V2(0, 0), V2(0, 1), 10.0);
  CHECK(plate.velocity().isZero());
  CHECK(plate.stroke() == 0.0);
  plate.set_velocity(V2(0, -1));
  plate.move(0.25);
  plate.move(0.25);
  CHECK(near(plate.displacement(), V2(0, -0.5)));
  CHECK(plate.stroke() == Approx(0.5));
  check(plate.closest(V2(0, -0.3)), V2(0, -0.5), V2(0, 1), 0.2);
  check(plate.closest(V2(3, -0.7)), V2(3, -0.5), V2(0, 1), -0.2);
  const auto line = plate.polyline(100.0);
  REQUIRE(line.cols() == 2);
  CHECK(near(line.col(0), V2(-10, -0.5)));
  CHECK(near(line.col(1), V2(10, -0.5)));
  CHECK(near(plate.pieces()[0].start, V2(-10, 0)));  // the body frame does not move

  plate.translate(V2(1, 0));
  CHECK(near(plate.displacement(), V2(1, -0.5)));
  CHECK(plate.stroke() == Approx(std::sqrt(1.25)));
  check(plate.closest(V2(12, 0.5)), V2(11, -0.5), V2(1, 1) / s2, s2, true);
  plate.move(-0.5);
  CHECK(near(plate.displacement(), V2(1, 0)));

  // Cases E3: 350 steps of 2e-5 at V = 1500 in -x cut 10.5.
  auto tool = maxentflow::cutting_tool("tool", V2(40.5, 11.7), 5, 7, 0.0, 4.0);
  tool.set_velocity(V2(-1500, 0));
  for (int i = 0; i < 350; ++i) tool.move(2e-5);
  CHECK(tool.displacement().x() == Approx(-10.5).epsilon(1e-12));
  CHECK(tool.displacement().y() == 0.0);
  CHECK(near(tool.closest(V2(30, 5)).point, V2(30, 11.7)));
}

TEST_CASE("polyline sampling", "[contact][tool]") {
  const auto plate = maxentflow::flat_plate("plate", V2(0, 0), V2(0, 1), 2.0);
  CHECK(plate.polyline(1.0).cols() == 5);
  CHECK(plate.polyline(0.9).cols() == 6);
  CHECK(plate.polyline(10.0).cols() == 2);

  const auto punch = maxentflow::rectangle("punch", V2(0, 0), V2(2, 1), 0.5);
  const double h = 0.05;
  const auto line = punch.polyline(h);
  Eigen::Index expected = 1;
  for (const auto& p : punch.pieces())
    expected += static_cast<Eigen::Index>(std::ceil(p.length() / h - 1e-9));
  CHECK(line.cols() == expected);
  CHECK(near(line.col(0), line.col(line.cols() - 1)));  // closed: first point repeated
  double longest = 0.0, off = 0.0;
  for (Eigen::Index k = 0; k < line.cols(); ++k) {
    if (k > 0) longest = std::max(longest, (line.col(k) - line.col(k - 1)).norm());
    off = std::max(off, std::abs(punch.signed_distance(line.col(k))));
  }
  CHECK(longest <= h * (1 + 1e-9));
  CHECK(longest > 0.5 * h);
  CHECK(off < 1e-12);
}

TEST_CASE("cutting tool: rake and clearance angles, edge radius tangency", "[contact][tool]") {
  const V2 tip(40.5, 11.7);
  const double a = 5 * deg, g = 7 * deg;
  const V2 rake(std::sin(a), std::cos(a)), flank(std::cos(g), std::sin(g));
  const V2 n_rake(-std::cos(a), std::sin(a)), n_flank(std::sin(g), -std::cos(g));

  SECTION("sharp") {
    const auto tool = maxentflow::cutting_tool(tip, 5, 7, 0.0, 4.0);
    CHECK(tool.name() == "cutting tool");
    const auto line = tool.polyline(100.0);
    REQUIRE(line.cols() == 3);
    CHECK(near(line.col(1), tip));
    const V2 r = line.col(2) - line.col(1), f = line.col(0) - line.col(1);
    CHECK(std::atan2(r.x(), r.y()) / deg == Approx(5.0).epsilon(1e-12));  // from the vertical
    CHECK(std::atan2(f.y(), f.x()) / deg == Approx(7.0).epsilon(1e-12));  // from the horizontal
    CHECK(r.norm() == Approx(4.0));
    CHECK(f.norm() == Approx(4.0));

    check(tool.closest(tip + 2 * rake + 0.3 * n_rake), tip + 2 * rake, n_rake, 0.3);
    check(tool.closest(tip + 2 * flank + 0.2 * n_flank), tip + 2 * flank, n_flank, 0.2);
    check(tool.closest(tip + V2(0, -1)), tip, V2(0, -1), 1.0, true);
    check(tool.closest(tip + V2(-1, 0)), tip, V2(-1, 0), 1.0, true);
    // Inside the wedge on its bisector (46 degrees from +x): gap -sin(39 deg) per unit.
    const auto in = tool.closest(tip + V2(std::cos(46 * deg), std::sin(46 * deg)));
    CHECK(in.gap == Approx(-std::sin(39 * deg)));
    CHECK_FALSE(in.at_corner);
  }

  SECTION("edge radius") {
    const double r = 0.15;
    const auto tool = maxentflow::cutting_tool("tool", tip, 5, 7, r, 4.0);
    const auto& P = tool.pieces();
    REQUIRE(P.size() == 3);
    REQUIRE(P[1].kind == ToolPiece::Kind::arc);
    CHECK(P[1].radius == r);
    CHECK(P[1].sweep == Approx(-(90 + 5 + 7) * deg));  // clockwise: a convex edge
    // The arc meets both faces at their ends with a continuous tangent.
    CHECK(near(P[0].end, P[1].start));
    CHECK(near(P[1].end, P[2].start));
    CHECK(near(P[0].tangent(1.0), P[1].tangent(0.0)));
    CHECK(near(P[1].tangent(1.0), P[2].tangent(0.0)));
    // The faces keep their lines and angles; the centre is r from both lines.
    CHECK(near(P[0].tangent(0.5), -flank));
    CHECK(near(P[2].tangent(0.5), rake));
    CHECK(near(P[0].start, tip + 4 * flank));
    CHECK(near(P[2].end, tip + 4 * rake));
    const V2 c = tip + r / std::sin(39 * deg) * V2(std::cos(46 * deg), std::sin(46 * deg));
    CHECK(near(P[1].center, c));
    CHECK(std::abs(maxentflow::detail::cross2(flank, c - tip)) == Approx(r));
    CHECK(std::abs(maxentflow::detail::cross2(rake, c - tip)) == Approx(r));

    // Angles measured on the sampled polyline: first and last chords.
    const auto line = tool.polyline(0.001);
    const Eigen::Index n = line.cols();
    const V2 f = line.col(0) - line.col(1), k = line.col(n - 1) - line.col(n - 2);
    CHECK(std::atan2(f.y(), f.x()) / deg == Approx(7.0).epsilon(1e-10));
    CHECK(std::atan2(k.x(), k.y()) / deg == Approx(5.0).epsilon(1e-10));
    // Tangent continuity on the samples: no chord turns by more than one arc step.
    double max_turn = 0.0;
    for (Eigen::Index i = 2; i < n; ++i) {
      const V2 u = line.col(i - 1) - line.col(i - 2), w = line.col(i) - line.col(i - 1);
      max_turn =
          std::max(max_turn, std::acos(std::clamp(u.dot(w) / (u.norm() * w.norm()), -1.0, 1.0)));
    }
    CHECK(max_turn < 0.001 / r * 1.01);
    // Lowest edge point: r (sin 46 / sin 39 - 1) above the sharp tip.
    const double lowest = line.row(1).minCoeff();
    CHECK(lowest ==
          Approx(tip.y() + r * (std::sin(46 * deg) / std::sin(39 * deg) - 1)).margin(1e-6));
    check(tool.closest(V2(c.x(), tip.y() - 1)), c - V2(0, r), V2(0, -1), c.y() - r - tip.y() + 1);
    check(tool.closest(c + V2(0, -0.05)), c - V2(0, r), V2(0, -1), -(r - 0.05));  // inside
  }
}

TEST_CASE("extrusion die: the paper's square die, edge radius, axisymmetric", "[contact][tool]") {
  const auto die = maxentflow::extrusion_die("die", V2(300, 150), V2(1, 0), 150, 30, 0, 300);
  REQUIRE(die.pieces().size() == 3);
  CHECK(near(die.pieces()[0].start, V2(330, 150)));
  CHECK(near(die.pieces()[2].end, V2(0, 300)));
  check(die.closest(V2(290, 200)), V2(300, 200), V2(-1, 0), 10);  // die face
  check(die.closest(V2(310, 140)), V2(310, 150), V2(0, -1), 10);  // die land
  check(die.closest(V2(150, 290)), V2(150, 300), V2(0, -1), 10);  // container wall
  check(die.closest(V2(290, 140)), V2(300, 150), V2(-1, -1) / s2, 10 * s2, true);
  check(die.closest(V2(305, 200)), V2(300, 200), V2(-1, 0), -5);
  check(die.closest(V2(150, 305)), V2(150, 300), V2(0, -1), -5);
  // Its one convex corner is the die corner (the land's end and the
  // face-wall corner are an open end and a concave corner); it moves with the die.
  auto moved = die;
  REQUIRE(die.convex_corners().size() == 1);
  CHECK(near(die.convex_corners()[0], V2(300, 150)));
  moved.translate(V2(2, -1));
  CHECK(near(moved.convex_corners()[0], V2(302, 149)));
  // The face-wall corner is its one concave corner: die face, then wall.
  REQUIRE(moved.concave_corners().size() == 1);
  CHECK(near(moved.concave_corners()[0].point, V2(302, 299)));
  CHECK(near(moved.concave_corners()[0].n_in, V2(-1, 0)));
  CHECK(near(moved.concave_corners()[0].n_out, V2(0, -1)));

  const auto round = maxentflow::extrusion_die("round", V2(300, 150), V2(1, 0), 150, 30, 10);
  REQUIRE(round.pieces().size() == 3);
  CHECK(round.convex_corners().empty());  // rounded: no sharp corner
  const V2 c(310, 160);
  check(round.closest(V2(290, 140)), c - 10 * V2(1, 1) / s2, V2(-1, -1) / s2, 20 * s2 - 10);
  check(round.closest(V2(290, 200)), V2(300, 200), V2(-1, 0), 10);

  // The back face (exit relief): product material just past the land's end,
  // slightly above it, is outside the die; without the relief it is "behind" the land.
  const auto relieved = maxentflow::extrusion_die("die", V2(300, 150), V2(1, 0), 150, 30, 0, 300, 150);
  REQUIRE(relieved.pieces().size() == 4);
  CHECK(near(relieved.pieces()[0].start, V2(330, 300)));
  check(relieved.closest(V2(336, 151)), V2(330, 151), V2(1, 0), 6);
  check(relieved.closest(V2(310, 140)), V2(310, 150), V2(0, -1), 10);
  CHECK(die.gap(V2(336, 151)) < 0);

  // Axisymmetric (r, z): extrusion in -z, axis r = 0 on the right of the direction.
  const auto axi = maxentflow::extrusion_die("axi", V2(5, 0), V2(0, -1), 5, 2);
  check(axi.closest(V2(7, 1)), V2(7, 0), V2(0, 1), 1);
  check(axi.closest(V2(4, -1)), V2(5, -1), V2(-1, 0), 1);
}

// Found by fuzz_rigid_tool: three collinear points 1e-14 apart, queried 6.56 away.
TEST_CASE("crosses: through a thin plate, not across a convex corner or along a face", "[contact][tool]") {
  RigidTool plate = maxentflow::rectangle("plate", {4.8, 0}, {5.2, 10});  // 0.4 thick
  CHECK(plate.crosses({4, 5}, {6, 5}));
  CHECK(plate.crosses({4.7, 2}, {5.3, 2.5}));  // 0.4 of the segment inside
  CHECK_FALSE(plate.crosses({4, 5}, {4.7, 5.1}));  // stops short
  CHECK_FALSE(plate.crosses({4.8, 2}, {4.8, 6}));  // along a face
  CHECK_FALSE(plate.crosses({4, 11}, {6, 11}));   // past its end
  plate.translate({0, 20});
  CHECK_FALSE(plate.crosses({4, 5}, {6, 5}));
  CHECK(plate.crosses({4, 25}, {6, 25}));
  CHECK_THROWS_AS(plate.crosses({4, 25}, {6, 25}, 1), Error);
  // A square die's corner (90 degrees) and E3's tool tip (102): a segment
  // that cuts the corner is the centroid rule's business, not a crossing.
  const RigidTool die = maxentflow::extrusion_die("die", {300, 150}, {1, 0}, 150, 30, 0, 300, 150);
  CHECK_FALSE(die.crosses({300, 155}, {305, 150}));
  CHECK(die.crosses({295, 200}, {335, 200}));  // through the die block: face to relief
  const RigidTool tool = maxentflow::cutting_tool({0, 0}, 5, 7, 0, 10);
  const double r = 5 * M_PI / 180, c = 7 * M_PI / 180;
  CHECK_FALSE(tool.crosses({std::sin(r) * 0.5, std::cos(r) * 0.5}, {std::cos(c) * 0.5, std::sin(c) * 0.5}));
}

// The nearest piece end is a smooth joint by round-off; the gap must still be the
// distance, with the normal along x - point.
TEST_CASE("smooth joint at round-off: |gap| = distance", "[contact][tool]") {
  const RigidTool tiny("tiny", points({V2(-6.2352941176470607, -6.2352941176470589),
                                       V2(-6.2352941176470589, -6.2352941176470589),
                                       V2(-6.2352941176470456, -6.2352941176470589)}));
  const V2 x(-6.2176513671840761, 0.32470785256009549);
  const auto p = tiny.closest(x);
  CHECK(p.gap == Approx(p.distance).epsilon(1e-14));
  CHECK(near(x - p.point, p.gap * p.normal, 1e-12));
  // A unit-length straight tool seen from 1e8 away beyond its end.
  const RigidTool straight("straight", points({V2(0, 0), V2(0.5, 0), V2(1, 0)}));
  for (const V2& q : {V2(1e8, 1e3), V2(1e8, -1e3), V2(-1e8, 3e7)}) {
    INFO("x = " << q.transpose());
    const auto r = straight.closest(q);
    CHECK(std::abs(r.gap) == Approx(r.distance).epsilon(1e-14));
    CHECK(r.normal.norm() == Approx(1.0).epsilon(1e-14));
  }
}

TEST_CASE("bad input throws maxentflow::Error", "[contact][tool]") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  using maxentflow::container;
  using maxentflow::cutting_tool;
  using maxentflow::extrusion_die;
  using maxentflow::flat_plate;
  using maxentflow::rectangle;

  // A query whose squared distance overflows (found by fuzz_rigid_tool).
  const RigidTool segment("segment", points({V2(0, 0), V2(1, 0)}));
  CHECK_THROWS_WITH(segment.closest(V2(1e300, -1e300)), Catch::Contains("too far"));
  CHECK_THROWS_AS(segment.gap(V2(nan, 0)), Error);
  CHECK(segment.closest(V2(1e150, -1e150)).gap < 0.0);

  // Points.
  CHECK_THROWS_AS(RigidTool("one", points({V2(0, 0)})), Error);
  CHECK_THROWS_AS(RigidTool("two", points({V2(0, 0), V2(1, 0)}), {}, ToolClosure::closed), Error);
  CHECK_THROWS_AS(RigidTool("nan", points({V2(0, 0), V2(nan, 1)})), Error);
  CHECK_THROWS_AS(RigidTool("fold", points({V2(0, 0), V2(2, 0), V2(1, 0)})), Error);
  try {
    RigidTool("repeat", points({V2(0, 0), V2(1, 0), V2(1, 0), V2(2, 1)}));
    FAIL("a repeated point must throw");
  } catch (const Error& e) {
    CHECK(e.where().find("repeat") != std::string::npos);
    CHECK(e.where().find("points 1 and 2") != std::string::npos);
  }
  // Corner radii.
  const auto L = points({V2(0, 0), V2(1, 0), V2(1, 1)});
  CHECK_THROWS_AS(RigidTool("neg", L, {0, -0.1, 0}), Error);
  CHECK_THROWS_AS(RigidTool("nanr", L, {0, nan, 0}), Error);
  CHECK_THROWS_AS(RigidTool("end", L, {0.1, 0, 0}), Error);
  CHECK_THROWS_AS(RigidTool("size", L, {0.1}), Error);
  CHECK_THROWS_AS(RigidTool("big", L, {0, 1.0 + 1e-6, 0}), Error);  // not tangent to both
  const RigidTool fits("fits", L, {0, 1.0, 0});  // uses up both segments: one arc
  REQUIRE(fits.pieces().size() == 1);
  CHECK(fits.pieces()[0].kind == ToolPiece::Kind::arc);
  check(fits.closest(V2(0.5, 0.5)), V2(0, 1) + V2(1, -1) / s2, V2(-1, 1) / s2, 1 - 0.5 * s2);

  // Pieces.
  CHECK_THROWS_AS(RigidTool("empty", std::vector<ToolPiece>{}), Error);
  CHECK_THROWS_AS(RigidTool("zero", {ToolPiece::segment(V2(1, 1), V2(1, 1))}), Error);
  CHECK_THROWS_AS(RigidTool("r0", {ToolPiece::arc(V2(0, 0), 0.0, 0, 1)}), Error);
  CHECK_THROWS_AS(RigidTool("r<0", {ToolPiece::arc(V2(0, 0), -1.0, 0, 1)}), Error);
  CHECK_THROWS_AS(RigidTool("sweep", {ToolPiece::arc(V2(0, 0), 1.0, 0, 7)}), Error);
  CHECK_THROWS_AS(RigidTool("gap", {ToolPiece::segment(V2(0, 0), V2(1, 0)),
                                    ToolPiece::segment(V2(1.1, 0), V2(2, 0))}),
                  Error);
  CHECK_THROWS_AS(
      RigidTool("open loop",
                {ToolPiece::segment(V2(0, 0), V2(1, 0)), ToolPiece::segment(V2(1, 0), V2(1, 1))},
                ToolClosure::closed),
      Error);
  auto bent = ToolPiece::arc(V2(0, 0), 1.0, 0, 1);
  bent.end += V2(0.1, 0);
  CHECK_THROWS_AS(RigidTool("bent", {bent}), Error);
  auto hole = ToolPiece::segment(V2(0, 0), V2(1, 0));
  hole.end.x() = nan;
  CHECK_THROWS_AS(RigidTool("hole", {hole}), Error);

  // Queries and motion.
  auto plate = flat_plate("plate", V2(0, 0), V2(0, 1), 1.0);
  CHECK_THROWS_AS(plate.polyline(0.0), Error);
  CHECK_THROWS_AS(plate.polyline(-1.0), Error);
  CHECK_THROWS_AS(plate.polyline(nan), Error);
  CHECK_THROWS_AS(plate.polyline(1e-12), Error);
  CHECK_THROWS_AS(plate.closest(V2(nan, 0)), Error);
  CHECK_THROWS_AS(plate.gap(V2(0, inf)), Error);
  CHECK_THROWS_AS(plate.move(nan), Error);
  CHECK_THROWS_AS(plate.set_velocity(V2(nan, 0)), Error);
  CHECK_THROWS_AS(plate.translate(V2(inf, 0)), Error);
  CHECK(plate.displacement().isZero());  // nothing moved

  // Helpers.
  CHECK_THROWS_AS(flat_plate("p", V2(0, 0), V2(0, 0), 1.0), Error);
  CHECK_THROWS_AS(flat_plate("p", V2(0, 0), V2(0, 1), 0.0), Error);
  CHECK_THROWS_AS(flat_plate("p", V2(nan, 0), V2(0, 1), 1.0), Error);
  CHECK_THROWS_AS(rectangle("r", V2(0, 0), V2(-1, 1)), Error);
  CHECK_THROWS_AS(rectangle("r", V2(0, 0), V2(2, 1), 0.6), Error);
  CHECK_THROWS_AS(container("c", V2(0, 0), V2(2, 0)), Error);
  CHECK_THROWS_AS(container("c", V2(0, 0), V2(2, 1), BoxSide::top, 1.5), Error);
  CHECK_THROWS_AS(extrusion_die("d", V2(300, 150), V2(1, 0), 150, 30, 40), Error);
  CHECK_THROWS_AS(extrusion_die("d", V2(300, 150), V2(0, 0), 150, 30), Error);
  CHECK_THROWS_AS(extrusion_die("d", V2(300, 150), V2(1, 0), 150, 0), Error);
  CHECK_THROWS_AS(cutting_tool("t", V2(0, 0), 50, 45, 0, 1), Error);  // no wedge left
  CHECK_THROWS_AS(cutting_tool("t", V2(0, 0), 5, 7, 10, 1), Error);   // radius too big
  CHECK_THROWS_AS(cutting_tool("t", V2(0, 0), nan, 7, 0, 1), Error);
  CHECK_THROWS_AS(cutting_tool("t", V2(0, 0), 5, 7, -0.1, 1), Error);
  CHECK_THROWS_AS(cutting_tool("t", V2(0, 0), 5, 7, 0, 0), Error);
}

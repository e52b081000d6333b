// maxentflow: rigid tools of 2-D forming simulations (plates, containers, dies,
// cutting tools), in plane strain (x, y) or axisymmetric (r, z) sections. A tool is
// a polyline of straight segments and circular arcs that translates rigidly; it
// answers the closest-point queries behind the contact gap g_n = (x_s - xbar) . n
// of the paper (Fig. 4), which the Lagrange-multiplier contact imposes.
//
// Orientation (every constructor and helper follows it): a tool is traversed so
// that the free space, where the workpiece lies, is on the LEFT of the direction of
// travel. The outward normal is the tangent turned +90 degrees, n = (-t_y, t_x): it
// points from the tool into the free space, where the gap is positive.
//  - A closed tool traversed clockwise is a solid block, material outside it; one
//    traversed counter-clockwise is a cavity enclosing the material.
//  - An open tool is solid on its right-hand side however thin it is, so a node that
//    crosses it gets a negative gap (penetration is detected, not mistaken for free
//    space on the far side).
//  - A right turn is a convex tool corner (it points into the material), a left turn
//    a concave one. Arcs: clockwise = convex edge radius (material outside the
//    circle), counter-clockwise = concave fillet (material on the centre's side).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

/// Whether the last point of a tool joins the first.
enum class ToolClosure { open, closed };

/// One piece of a tool in its body frame: a segment from `start` to `end`, or a
/// circular arc about `center` from polar angle `start_angle` through the signed
/// `sweep` (> 0 counter-clockwise). The outward normal is on the left of travel.
struct ToolPiece {
  enum class Kind { segment, arc };
  Kind kind = Kind::segment;
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // arc only
  double radius = 0.0;                               // arc only
  double start_angle = 0.0;                          // arc only
  double sweep = 0.0;                                // arc only

  static ToolPiece segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    ToolPiece p;
    p.start = a;
    p.end = b;
    return p;
  }

  static ToolPiece arc(const Eigen::Vector2d& center, double radius, double start_angle,
                       double sweep) {
    ToolPiece p;
    p.kind = Kind::arc;
    p.center = center;
    p.radius = radius;
    p.start_angle = start_angle;
    p.sweep = sweep;
    p.start = p.point(0.0);
    p.end = p.point(1.0);
    return p;
  }

  double length() const {
    return kind == Kind::segment ? (end - start).norm() : radius * std::abs(sweep);
  }

  /// Point at the fraction s in [0, 1] of the piece.
  Eigen::Vector2d point(double s) const {
    if (kind == Kind::segment) return start + s * (end - start);
    const double phi = start_angle + s * sweep;
    return center + radius * Eigen::Vector2d(std::cos(phi), std::sin(phi));
  }

  /// Unit tangent in the direction of travel at the fraction s.
  Eigen::Vector2d tangent(double s) const {
    if (kind == Kind::segment) return (end - start).normalized();
    const double phi = start_angle + s * sweep;
    const double turn = sweep > 0.0 ? 1.0 : -1.0;
    return turn * Eigen::Vector2d(-std::sin(phi), std::cos(phi));
  }

  /// Unit outward normal (the tangent turned +90 degrees) at the fraction s.
  Eigen::Vector2d normal(double s) const {
    const Eigen::Vector2d t = tangent(s);
    return {-t.y(), t.x()};
  }
};

/// Result of RigidTool::closest(x), in the tool's current position.
struct ToolProjection {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();   ///< closest tool point xbar
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();  ///< unit outward normal n there
  double gap = 0.0;        ///< (x - point) . normal: > 0 in free space, < 0 penetrating
  double distance = 0.0;   ///< |x - point| (= |gap|)
  int piece = -1;          ///< piece holding `point` (at a joint, one of the two)
  bool at_corner = false;  ///< `point` is a corner between pieces or an open end
};

namespace detail {

inline Eigen::Vector2d left_normal(const Eigen::Vector2d& t) {
  return {-t.y(), t.x()};
}

inline double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Below this angle (rad) two tangents count as one: no corner, or a fold-back.
inline constexpr double tool_angle_tolerance = 1e-8;

inline double bbox_diagonal(const Eigen::Matrix2Xd& p) {
  if (p.cols() == 0) return 0.0;
  return (p.rowwise().maxCoeff() - p.rowwise().minCoeff()).norm();
}

// Closest point of one piece to x (body frame); `end` is -1 for an interior point,
// 0 or 1 when the point is the piece's start or end (the joints need their own normal).
struct PieceFoot {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();
  double distance2 = 0.0;
  int end = -1;  ///< 0: the piece's start, 1: its end, -1: inside it
};

inline PieceFoot closest_on_piece(const ToolPiece& p, const Eigen::Vector2d& x) {
  PieceFoot f;
  if (p.kind == ToolPiece::Kind::segment) {
    const Eigen::Vector2d e = p.end - p.start;
    const double s = (x - p.start).dot(e) / e.squaredNorm();
    if (s <= 0.0) {
      f.point = p.start;
      f.end = 0;
    } else if (s >= 1.0) {
      f.point = p.end;
      f.end = 1;
    } else {
      f.point = p.start + s * e;
      f.end = -1;
    }
    f.normal = left_normal(e.normalized());
  } else {
    const Eigen::Vector2d r = x - p.center;
    const double two_pi = 2.0 * std::numbers::pi;
    const double turn = p.sweep > 0.0 ? 1.0 : -1.0;
    // Angle from the start in the direction of travel, in [0, 2 pi).
    double u = std::fmod(turn * (std::atan2(r.y(), r.x()) - p.start_angle), two_pi);
    if (u < 0.0) u += two_pi;
    if (u > 0.0 && u < std::abs(p.sweep)) {
      const double phi = p.start_angle + turn * u;
      const Eigen::Vector2d radial(std::cos(phi), std::sin(phi));
      f.point = p.center + p.radius * radial;
      f.normal = -turn * radial;
      f.end = -1;
    } else {
      // Outside the sweep: the nearer end (both ends are joints).
      const bool at_start = (x - p.start).squaredNorm() <= (x - p.end).squaredNorm();
      f.point = at_start ? p.start : p.end;
      f.normal = p.normal(at_start ? 0.0 : 1.0);
      f.end = at_start ? 0 : 1;
    }
  }
  f.distance2 = (x - f.point).squaredNorm();
  return f;
}

template <class Derived>
Eigen::Matrix2Xd as_points(const std::string& name, const Eigen::MatrixBase<Derived>& p) {
  static_assert(Derived::RowsAtCompileTime == 2 || Derived::RowsAtCompileTime == Eigen::Dynamic,
                "maxentflow: tool points are the columns of a 2-row matrix");
  require(p.rows() == 2, cat("tool points must be a 2-row matrix, got ", p.rows(), " rows"),
          cat("RigidTool '", name, "'"));
  return p;
}

// Segments through the points `v`, with a circular arc tangent to both neighbours at
// every vertex whose corner radius is > 0 (an edge radius or fillet).
inline std::vector<ToolPiece> fillet_polyline(const std::string& name, const Eigen::Matrix2Xd& v,
                                              const std::vector<double>& radii,
                                              ToolClosure closure) {
  const std::string where = cat("RigidTool '", name, "'");
  const bool closed = closure == ToolClosure::closed;
  const int m = static_cast<int>(v.cols());
  require(m >= 2, cat("a tool needs at least 2 points, got ", m), where);
  require(!closed || m >= 3, cat("a closed tool needs at least 3 points, got ", m), where);
  for (int j = 0; j < m; ++j)
    MAXENTFLOW_REQUIRE(v.col(j).allFinite(), "non-finite point coordinate",
                       cat(where, ", point ", j));
  MAXENTFLOW_REQUIRE(radii.empty() || radii.size() == static_cast<std::size_t>(m),
                     cat("got ", radii.size(), " corner radii for ", m, " points"), where);
  const double scale = bbox_diagonal(v);
  const int edges = closed ? m : m - 1;
  std::vector<Eigen::Vector2d> dir(static_cast<std::size_t>(edges));
  std::vector<double> len(static_cast<std::size_t>(edges));
  for (int e = 0; e < edges; ++e) {
    const Eigen::Vector2d d = v.col((e + 1) % m) - v.col(e);
    len[static_cast<std::size_t>(e)] = d.norm();
    MAXENTFLOW_REQUIRE(d.norm() > 1e-12 * scale, "zero-length segment (repeated point)",
                       cat(where, ", points ", e, " and ", (e + 1) % m));
    dir[static_cast<std::size_t>(e)] = d / d.norm();
  }

  // Per vertex: the fillet arc, if any, and how far it cuts into each neighbour.
  std::vector<ToolPiece> arc(static_cast<std::size_t>(m));
  std::vector<bool> has_arc(static_cast<std::size_t>(m), false);
  std::vector<double> cut(static_cast<std::size_t>(m), 0.0);
  for (int j = 0; j < m; ++j) {
    const auto uj = static_cast<std::size_t>(j);
    const double r = radii.empty() ? 0.0 : radii[uj];
    MAXENTFLOW_REQUIRE(std::isfinite(r) && r >= 0.0,
                       cat("corner radius must be finite and >= 0, got ", r),
                       cat(where, ", point ", j));
    const bool end_point = !closed && (j == 0 || j == m - 1);
    if (end_point) {
      MAXENTFLOW_REQUIRE(r == 0.0, cat("corner radius ", r, " at an open end"),
                         cat(where, ", point ", j));
      continue;
    }
    const Eigen::Vector2d& u1 = dir[static_cast<std::size_t>((j - 1 + edges) % edges)];
    const Eigen::Vector2d& u2 = dir[static_cast<std::size_t>(j % edges)];
    const double theta = std::atan2(cross2(u1, u2), u1.dot(u2));  // turn, > 0 left
    MAXENTFLOW_REQUIRE(std::numbers::pi - std::abs(theta) > tool_angle_tolerance,
                       "the polyline folds back on itself", cat(where, ", point ", j));
    if (r == 0.0 || std::abs(theta) <= tool_angle_tolerance) continue;
    // Tangent points at distance r tan(|theta|/2) from the vertex; the centre lies
    // r away from the first tangent point on the side the path turns to.
    cut[uj] = r * std::tan(0.5 * std::abs(theta));
    const Eigen::Vector2d p1 = v.col(j) - cut[uj] * u1;
    const Eigen::Vector2d c = p1 + (theta > 0.0 ? r : -r) * left_normal(u1);
    arc[uj] = ToolPiece::arc(c, r, std::atan2(p1.y() - c.y(), p1.x() - c.x()), theta);
    has_arc[uj] = true;
  }
  for (int e = 0; e < edges; ++e) {
    const int a = e, b = (e + 1) % m;
    const double need = cut[static_cast<std::size_t>(a)] + cut[static_cast<std::size_t>(b)];
    const double have = len[static_cast<std::size_t>(e)];
    MAXENTFLOW_REQUIRE(need <= have * (1.0 + 1e-12),
                       cat("corner radii too large: arcs tangent to the segment need ", need,
                           " of its length ", have),
                       cat(where, ", segment between points ", a, " and ", b));
  }

  std::vector<ToolPiece> pieces;
  for (int e = 0; e < edges; ++e) {
    const auto a = static_cast<std::size_t>(e), b = static_cast<std::size_t>((e + 1) % m);
    const Eigen::Vector2d from = has_arc[a] ? arc[a].end : Eigen::Vector2d(v.col(e));
    const Eigen::Vector2d to = has_arc[b] ? arc[b].start : Eigen::Vector2d(v.col((e + 1) % m));
    // Two arcs may use up a segment exactly: then they meet without one.
    if ((to - from).norm() > 1e-12 * scale) pieces.push_back(ToolPiece::segment(from, to));
    if (has_arc[b]) pieces.push_back(arc[b]);
  }
  return pieces;
}

}  // namespace detail

/// A named rigid tool: a polyline of segments and arcs, open or closed, given in a
/// body frame and translated rigidly by a displacement that advances with a constant
/// prescribed velocity. Queries (closest, gap, polyline) use the current position.
/// Self-intersecting polylines are not detected; keep open tools long enough that the
/// workpiece never flows around their ends.
class RigidTool {
 public:
  /// From pieces (each joined to the next; a closed tool's last piece joins the first).
  /// Pieces may meet at corners; arcs need not be tangent to their neighbours.
  RigidTool(std::string name, std::vector<ToolPiece> pieces,
            ToolClosure closure = ToolClosure::open)
      : name_(std::move(name)),
        pieces_(std::move(pieces)),
        closed_(closure == ToolClosure::closed) {
    init();
  }

  /// Through the points (columns), with an arc of radius corner_radii[j] tangent to both
  /// segments at point j (0 = sharp; empty = all sharp). A closed tool lists each point
  /// once. Throws if an arc does not fit on its segments (cannot be tangent to them).
  /// (A template so that a braced list of pieces always picks the constructor above.)
  template <class Derived>
  RigidTool(std::string name, const Eigen::MatrixBase<Derived>& points,
            const std::vector<double>& corner_radii = {}, ToolClosure closure = ToolClosure::open)
      : RigidTool(
            name,
            detail::fillet_polyline(name, detail::as_points(name, points), corner_radii, closure),
            closure) {}

  const std::string& name() const { return name_; }
  bool closed() const { return closed_; }
  /// Pieces in the body frame (add displacement() for the current position).
  const std::vector<ToolPiece>& pieces() const { return pieces_; }
  double length() const {
    double l = 0.0;
    for (const auto& p : pieces_) l += p.length();
    return l;
  }

  const Eigen::Vector2d& velocity() const { return velocity_; }
  void set_velocity(const Eigen::Vector2d& v) {
    require(v.allFinite(), "non-finite tool velocity", where("set_velocity"));
    velocity_ = v;
  }
  /// Current position of the body frame's origin (the rigid translation so far).
  const Eigen::Vector2d& displacement() const { return displacement_; }
  /// Advances the tool by one time step: displacement += velocity * dt.
  void move(double dt) {
    require(std::isfinite(dt), "non-finite time step", where("move"));
    displacement_ += velocity_ * dt;
  }
  void translate(const Eigen::Vector2d& u) {
    require(u.allFinite(), "non-finite translation", where("translate"));
    displacement_ += u;
  }
  /// Travel so far, |displacement|.
  double stroke() const { return displacement_.norm(); }
  /// The sharp convex corners (right turns between two pieces, pointing into
  /// the material: a square die's corner, a cutting tool's tip), where they are now.
  std::vector<Eigen::Vector2d> convex_corners() const {
    std::vector<Eigen::Vector2d> c;
    for (std::size_t j = 0; j < joints_.size(); ++j)
      if (joints_[j].convex) c.push_back(pieces_[j % pieces_.size()].start + displacement_);
    return c;
  }

  /// A sharp joint that turns away from the material (the material fills the
  /// angle: a container's wall meeting the die face), with the outward normals
  /// of the piece that ends there (n_in) and the one that starts there (n_out).
  struct ConcaveCorner {
    Eigen::Vector2d point, n_in, n_out;
  };
  std::vector<ConcaveCorner> concave_corners() const {
    std::vector<ConcaveCorner> c;
    const std::size_t n = pieces_.size();
    for (std::size_t j = 0; j < joints_.size(); ++j)
      if (joints_[j].concave)
        c.push_back({pieces_[j % n].start + displacement_, pieces_[(j + n - 1) % n].normal(1.0),
                     pieces_[j % n].normal(0.0)});
    return c;
  }

  /// Closest tool point to x, outward normal and signed gap. Inside a piece the normal
  /// is the piece's. At a joint or an open end the normal is (x - point)/|x - point|,
  /// turned to the free side: its sign follows the bisector n_in + n_out of the normals
  /// meeting there (at an open end, the end piece's normal), so points behind a thin
  /// tool get gap < 0. With x on the corner itself (within 1e-12 of the tool's size)
  /// the normal is that bisector and the gap 0.
  ToolProjection closest(const Eigen::Vector2d& x) const {
    MAXENTFLOW_REQUIRE(x.allFinite(), "non-finite query point",
                       detail::cat(where("closest"), ", x = (", x.x(), ", ", x.y(), ")"));
    const Eigen::Vector2d xb = x - displacement_;
    detail::PieceFoot best;
    best.distance2 = std::numeric_limits<double>::infinity();
    int best_piece = 0;
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
      const auto f = detail::closest_on_piece(pieces_[i], xb);
      if (f.distance2 < best.distance2) {
        best = f;
        best_piece = static_cast<int>(i);
      }
    }
    // Found by libFuzzer: a point so far away that every squared distance
    // overflows matched no piece (and indexed joints_ with garbage).
    MAXENTFLOW_REQUIRE(std::isfinite(best.distance2),
                       "the query point is too far from the tool (its distance overflows)",
                       detail::cat(where("closest"), ", x = (", x.x(), ", ", x.y(), ")"));
    ToolProjection r;
    r.piece = best_piece;
    const Eigen::Vector2d d = xb - best.point;
    r.distance = d.norm();
    Eigen::Vector2d n = best.normal;
    if (best.end >= 0) {
      const Joint& j = joints_[static_cast<std::size_t>(joint_index(best_piece, best.end))];
      r.at_corner = j.sharp;
      n = j.bisector;
      // Along d at a smooth joint too: there d is the bisector up to the 1e-8 angle
      // tolerance, but when pieces are at round-off against the distance (found by
      // fuzz_rigid_tool) the foot can land on a smooth joint with d far from it.
      if (r.distance > 1e-12 * scale_) n = (d.dot(j.bisector) >= 0.0 ? 1.0 : -1.0) * d / r.distance;
    }
    r.normal = n;
    r.gap = d.dot(n);
    r.point = best.point + displacement_;
    return r;
  }

  /// The signed gap (x - xbar) . n of closest(x).
  double gap(const Eigen::Vector2d& x) const { return closest(x).gap; }
  /// Whether the segment a-b passes through the tool from one side to another
  /// (a die plate or land thinner than the node spacing): a and b project onto
  /// parts of the tool that face away from each other (normals more than 120
  /// degrees apart) and one of `samples` - 1 points between them lies inside.
  /// A segment that only cuts a convex corner (normals 90 degrees apart at a
  /// square die's corner, 102 at E3's tool tip) does not cross.
  bool crosses(const Eigen::Vector2d& a, const Eigen::Vector2d& b, int samples = 16) const {
    MAXENTFLOW_REQUIRE(samples >= 2, detail::cat("samples must be >= 2, got ", samples), where("crosses"));
    const Eigen::Vector2d ab = a - displacement_, bb = b - displacement_;
    if ((ab.cwiseMax(bb).array() < lo_.array()).any() || (ab.cwiseMin(bb).array() > hi_.array()).any())
      return false;  // the segment's box misses the tool's
    const double L = (b - a).norm();
    const ToolProjection pa = closest(a), pb = closest(b);
    // Every point of the segment lies within L / 2 of an end.
    if (pa.distance > L && pb.distance > L) return false;
    if (pa.normal.dot(pb.normal) > -0.5) return false;
    for (int k = 1; k < samples; ++k)
      if (gap(a + (static_cast<double>(k) / samples) * (b - a)) < -1e-9 * L) return true;
    return false;
  }
  /// The distance to the tool, negative inside it (same sign as gap(x)).
  double signed_distance(const Eigen::Vector2d& x) const {
    const auto p = closest(x);
    return p.gap < 0.0 ? -p.distance : p.distance;
  }

  /// Points along the tool in its current position, no two consecutive ones farther
  /// apart than max_segment_length (up to round-off); pieces' ends are always included
  /// and a closed tool repeats its first point at the end.
  Eigen::Matrix2Xd polyline(double max_segment_length) const {
    const double h = max_segment_length;
    require(std::isfinite(h) && h > 0.0,
            detail::cat("max_segment_length must be finite and > 0, got ", h), where("polyline"));
    std::vector<Eigen::Index> count(pieces_.size());
    Eigen::Index total = 1;
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
      const double q = pieces_[i].length() / h;
      require(q <= 1e7, detail::cat("max_segment_length ", h, " is too small: ", q, " points"),
              where("polyline"));
      // Tolerate round-off in length/h so that an exact multiple gives no extra point.
      count[i] = std::max<Eigen::Index>(1, static_cast<Eigen::Index>(std::ceil(q - 1e-9)));
      total += count[i];
    }
    Eigen::Matrix2Xd out(2, total);
    out.col(0) = pieces_.front().start + displacement_;
    Eigen::Index k = 1;
    for (std::size_t i = 0; i < pieces_.size(); ++i)
      for (Eigen::Index s = 1; s <= count[i]; ++s)
        out.col(k++) = pieces_[i].point(static_cast<double>(s) / static_cast<double>(count[i])) +
                       displacement_;
    return out;
  }

 private:
  // Where two pieces meet, or an open end. `bisector`: the unit normal for x on the
  // joint and the side test beside it (normalized n_in + n_out; an end's own normal).
  struct Joint {
    Eigen::Vector2d bisector;
    bool sharp;  // corner or open end
    bool convex = false;  // a sharp corner pointing into the material (a right turn)
    bool concave = false;  // a sharp corner between two pieces turning away from it (a left turn)
  };

  std::string where(const char* method) const {
    return detail::cat("RigidTool '", name_, "', ", method);
  }

  int joint_index(int piece, int end) const {
    const int n = static_cast<int>(pieces_.size());
    return closed_ ? (piece + end) % n : piece + end;
  }

  void init() {
    const std::string at = detail::cat("RigidTool '", name_, "'");
    require(!pieces_.empty(), "a tool needs at least one piece", at);
    const auto n = pieces_.size();
    Eigen::Matrix2Xd extent(2, 4 * n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = pieces_[i];
      const auto c = static_cast<Eigen::Index>(4 * i);
      extent.col(c) = p.start;
      extent.col(c + 1) = p.end;
      const double r = p.kind == ToolPiece::Kind::arc ? p.radius : 0.0;
      extent.col(c + 2) = (p.kind == ToolPiece::Kind::arc ? p.center : p.start).array() - r;
      extent.col(c + 3) = (p.kind == ToolPiece::Kind::arc ? p.center : p.start).array() + r;
    }
    scale_ = extent.allFinite() ? detail::bbox_diagonal(extent) : 0.0;
    lo_ = extent.rowwise().minCoeff();
    hi_ = extent.rowwise().maxCoeff();
    const double tol = 1e-9 * scale_;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = pieces_[i];
      const std::string piece = detail::cat(at, ", piece ", i);
      MAXENTFLOW_REQUIRE(p.start.allFinite() && p.end.allFinite() && p.center.allFinite() &&
                             std::isfinite(p.radius) && std::isfinite(p.start_angle) &&
                             std::isfinite(p.sweep),
                         "non-finite piece data", piece);
      if (p.kind == ToolPiece::Kind::arc) {
        MAXENTFLOW_REQUIRE(p.radius > 0.0, detail::cat("arc radius must be > 0, got ", p.radius),
                           piece);
        MAXENTFLOW_REQUIRE(
            p.sweep != 0.0 && std::abs(p.sweep) <= 2.0 * std::numbers::pi,
            detail::cat("arc sweep must be in [-2 pi, 2 pi] and != 0, got ", p.sweep), piece);
        MAXENTFLOW_REQUIRE(
            (p.start - p.point(0.0)).norm() <= tol && (p.end - p.point(1.0)).norm() <= tol,
            "arc start/end do not match its centre, radius and angles", piece);
      }
      MAXENTFLOW_REQUIRE(p.length() > 1e-12 * scale_, "zero-length piece", piece);
    }
    const std::size_t links = closed_ ? n : n - 1;
    for (std::size_t i = 0; i < links; ++i) {
      const auto& a = pieces_[i];
      const auto& b = pieces_[(i + 1) % n];
      MAXENTFLOW_REQUIRE((a.end - b.start).norm() <= tol,
                         detail::cat("pieces do not meet: gap ", (a.end - b.start).norm()),
                         detail::cat(at, ", pieces ", i, " and ", (i + 1) % n));
    }

    const std::size_t joints = closed_ ? n : n + 1;
    joints_.resize(joints);
    for (std::size_t j = 0; j < joints; ++j) {
      Joint& J = joints_[j];
      const bool has_in = closed_ || j > 0;
      const bool has_out = closed_ || j < n;
      if (!has_in || !has_out) {
        J.bisector = has_out ? pieces_[j].normal(0.0) : pieces_[n - 1].normal(1.0);
        J.sharp = true;
        continue;
      }
      const ToolPiece& in = pieces_[(j + n - 1) % n];
      const ToolPiece& out = pieces_[j % n];
      const Eigen::Vector2d t_in = in.tangent(1.0), t_out = out.tangent(0.0);
      const double angle = std::atan2(detail::cross2(t_in, t_out), t_in.dot(t_out));
      MAXENTFLOW_REQUIRE(std::numbers::pi - std::abs(angle) > detail::tool_angle_tolerance,
                         "the tool folds back on itself",
                         detail::cat(at, ", pieces ", (j + n - 1) % n, " and ", j % n));
      J.bisector = (in.normal(1.0) + out.normal(0.0)).normalized();
      J.sharp = std::abs(angle) > detail::tool_angle_tolerance;
      J.convex = J.sharp && angle < 0.0;
      J.concave = J.sharp && angle > 0.0;
    }
  }

  std::string name_;
  std::vector<ToolPiece> pieces_;
  bool closed_ = false;
  std::vector<Joint> joints_;
  double scale_ = 0.0;  // bounding-box diagonal: sets the geometric tolerances
  Eigen::Vector2d lo_ = Eigen::Vector2d::Zero(), hi_ = Eigen::Vector2d::Zero();  // the box, at rest
  Eigen::Vector2d velocity_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d displacement_ = Eigen::Vector2d::Zero();
};

// ---------------------------------------------------------------------------------
// Common tools. All start at rest (set_velocity to drive them) with displacement 0.

/// A flat plate through `point`, facing `outward_normal` (need not be unit), extending
/// half_length to each side: e.g. the upsetting plates, a ram, a symmetry wall.
inline RigidTool flat_plate(std::string name, const Eigen::Vector2d& point,
                            const Eigen::Vector2d& outward_normal, double half_length) {
  const std::string at = detail::cat("flat_plate '", name, "'");
  require(point.allFinite() && outward_normal.allFinite() && std::isfinite(half_length),
          "non-finite argument", at);
  require(outward_normal.norm() > 0.0, "zero outward normal", at);
  require(half_length > 0.0, detail::cat("half_length must be > 0, got ", half_length), at);
  const Eigen::Vector2d n = outward_normal.normalized();
  const Eigen::Vector2d t(n.y(), -n.x());  // left of t is n
  Eigen::Matrix2Xd v(2, 2);
  v << point - half_length * t, point + half_length * t;
  return RigidTool(std::move(name), v);
}

/// A solid rectangular block [lower, upper] (closed, clockwise), material outside,
/// with all four corners rounded by corner_radius (0 = sharp): e.g. a punch.
inline RigidTool rectangle(std::string name, const Eigen::Vector2d& lower,
                           const Eigen::Vector2d& upper, double corner_radius = 0.0) {
  const std::string at = detail::cat("rectangle '", name, "'");
  require(lower.allFinite() && upper.allFinite(), "non-finite corner", at);
  require((upper.array() > lower.array()).all(), "upper must exceed lower in x and y", at);
  Eigen::Matrix2Xd v(2, 4);
  v << lower.x(), lower.x(), upper.x(), upper.x(),  //
      lower.y(), upper.y(), upper.y(), lower.y();
  return RigidTool(std::move(name), v, std::vector<double>(4, corner_radius), ToolClosure::closed);
}

/// Side of an axis-aligned box.
enum class BoxSide { bottom, right, top, left };

/// Three walls of the box [lower, upper], open on `open_side`, the material inside
/// (an open polyline, counter-clockwise): a container or closed-die cavity. The two
/// inner (concave) corners are rounded by corner_radius (0 = sharp).
inline RigidTool container(std::string name, const Eigen::Vector2d& lower,
                           const Eigen::Vector2d& upper, BoxSide open_side = BoxSide::top,
                           double corner_radius = 0.0) {
  const std::string at = detail::cat("container '", name, "'");
  require(lower.allFinite() && upper.allFinite(), "non-finite corner", at);
  require((upper.array() > lower.array()).all(), "upper must exceed lower in x and y", at);
  // Box corners counter-clockwise; side k runs from corner k to corner k + 1.
  const Eigen::Vector2d corner[4] = {lower, {upper.x(), lower.y()}, upper, {lower.x(), upper.y()}};
  const int k = static_cast<int>(open_side);
  Eigen::Matrix2Xd v(2, 4);
  for (int i = 0; i < 4; ++i) v.col(i) = corner[(k + 1 + i) % 4];
  return RigidTool(std::move(name), v, {0.0, corner_radius, corner_radius, 0.0});
}

/// A square extrusion die: the die land along `extrusion_direction` from `die_corner`
/// (land_length), the die face perpendicular to it from die_corner away from the axis
/// (face_height; the axis is on the right of the extrusion direction) and, if
/// container_length > 0, the container wall running back from the face's outer end.
/// corner_radius rounds the (convex) die corner. The paper's extrusion (cases E2):
/// extrusion_die("die", {300, 150}, {1, 0}, 150, 30, 0, 300, 150).
/// exit_relief > 0 adds the die's back face, from the land's end away from the
/// axis: without it the open end's normal is the land's, so product material
/// that rises a little past the land's end would count as inside the die.
///
///        container wall                                  (material on the left of
///     C <------------------ F                             travel: inside the die)
///                           ^ die face
///         billet  ->        |
///                           corner ------ L   die land
///     axis ---------------------------------------------
inline RigidTool extrusion_die(std::string name, const Eigen::Vector2d& die_corner,
                               const Eigen::Vector2d& extrusion_direction, double face_height,
                               double land_length, double corner_radius = 0.0,
                               double container_length = 0.0, double exit_relief = 0.0) {
  const std::string at = detail::cat("extrusion_die '", name, "'");
  require(die_corner.allFinite() && extrusion_direction.allFinite() && std::isfinite(face_height) &&
              std::isfinite(land_length) && std::isfinite(container_length),
          "non-finite argument", at);
  require(extrusion_direction.norm() > 0.0, "zero extrusion direction", at);
  require(
      face_height > 0.0 && land_length > 0.0,
      detail::cat("face_height and land_length must be > 0, got ", face_height, ", ", land_length),
      at);
  require(container_length >= 0.0 && exit_relief >= 0.0,
          detail::cat("container_length and exit_relief must be >= 0, got ", container_length, ", ",
                      exit_relief),
          at);
  const Eigen::Vector2d e = extrusion_direction.normalized();
  const Eigen::Vector2d away = detail::left_normal(e);  // from the axis toward the container
  const Eigen::Vector2d face_top = die_corner + face_height * away;
  const bool wall = container_length > 0.0, relief = exit_relief > 0.0;
  Eigen::Matrix2Xd v(2, 3 + (wall ? 1 : 0) + (relief ? 1 : 0));
  int k = 0;
  if (relief) v.col(k++) = die_corner + land_length * e + exit_relief * away;
  v.col(k++) = die_corner + land_length * e;
  const int corner = k;
  v.col(k++) = die_corner;
  v.col(k++) = face_top;
  if (wall) v.col(k++) = face_top - container_length * e;
  std::vector<double> radii(static_cast<std::size_t>(v.cols()), 0.0);
  radii[static_cast<std::size_t>(corner)] = corner_radius;
  return RigidTool(std::move(name), v, radii);
}

/// Orthogonal cutting tool (cases E3): it moves in -x into a workpiece on its left,
/// whose top lies above the tip (uncut chip thickness = top - tip.y).
///
///                rake face, leans back by the rake angle alpha from the vertical;
///          |    /   outward normal (-cos alpha, sin alpha) faces the chip
///          |a  /
///   chip   |  /       tool
///   <- V   | /
///          |/ ____----  flank (clearance) face, rises by the clearance angle gamma
///   -------o--- - - - - from the horizontal; normal (sin gamma, -cos gamma) faces
///   work  tip           the machined surface y = tip.y
///
/// `tip` is the sharp tip where the two faces meet, each `length` long from it. An
/// edge_radius r > 0 rounds it with an arc tangent to both faces; the lowest point of
/// the edge then lies r (sin(45 + (gamma - alpha)/2) / sin(45 - (alpha + gamma)/2) - 1)
/// above tip.y (degrees; clearance >= 0). Wedge angle 90 - alpha - gamma must be > 0.
/// The polyline runs flank end -> tip -> rake end (material on the left).
inline RigidTool cutting_tool(std::string name, const Eigen::Vector2d& tip, double rake_angle_deg,
                              double clearance_angle_deg, double edge_radius, double length) {
  const std::string at = detail::cat("cutting_tool '", name, "'");
  require(tip.allFinite() && std::isfinite(rake_angle_deg) && std::isfinite(clearance_angle_deg) &&
              std::isfinite(edge_radius) && std::isfinite(length),
          "non-finite argument", at);
  require(std::abs(rake_angle_deg) < 90.0 && std::abs(clearance_angle_deg) < 90.0,
          detail::cat("rake and clearance angles must lie in (-90, 90) degrees, got ",
                      rake_angle_deg, ", ", clearance_angle_deg),
          at);
  const double wedge = 90.0 - rake_angle_deg - clearance_angle_deg;
  require(wedge > 0.0 && wedge < 180.0,
          detail::cat("wedge angle 90 - rake - clearance must lie in (0, 180), got ", wedge), at);
  require(length > 0.0, detail::cat("face length must be > 0, got ", length), at);
  const double deg = std::numbers::pi / 180.0;
  const double a = rake_angle_deg * deg, g = clearance_angle_deg * deg;
  Eigen::Matrix2Xd v(2, 3);
  v.col(0) = tip + length * Eigen::Vector2d(std::cos(g), std::sin(g));  // flank end
  v.col(1) = tip;
  v.col(2) = tip + length * Eigen::Vector2d(std::sin(a), std::cos(a));  // rake end
  return RigidTool(std::move(name), v, {0.0, edge_radius, 0.0});
}

/// cutting_tool named "cutting tool".
inline RigidTool cutting_tool(const Eigen::Vector2d& tip, double rake_angle_deg,
                              double clearance_angle_deg, double edge_radius, double length) {
  return cutting_tool("cutting tool", tip, rake_angle_deg, clearance_angle_deg, edge_radius,
                      length);
}

}  // namespace maxentflow

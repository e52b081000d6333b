// maxentflow: an Eulerian zone of the node cloud, for steady processes
// (extrusion, drawing, rolling): a region fixed to the tools where the nodes
// do not travel with the material but are put back at the same places at the
// start of every step, the arbitrary Lagrangian-Eulerian (ALE) idea of FEM
// forming codes. A Norton-Hoff flow carries no state that a node must keep
// (the flow stress depends on the strain rate only), so the zone changes the
// discretization, not the model: the flow through a die is then solved on the
// same cloud every step. Where the Lagrangian cloud is rezoned as it passes a
// die corner, every node removed, inserted or leaving the die land changes the
// discrete solution there by the discretization error, and E2's press load
// jumps by 2.7 % rms from step to step; with the zone the jumps are gone
// (docs/method.md, section 11).
//
// What a rezoning with the zone does, at the start of each step once the
// material fills the zone:
//  - every node inside the zone goes (the zone's own nodes after their move,
//    and the material's that flowed in), and a material node next to a zone
//    node (within keep_out of its spacing);
//  - a zone node that the step carried out of the zone (its outflow side, the
//    product leaving a die land) stays in the material where no node outside
//    the zone is closer than emit_spacing (on the material's boundary
//    emit_surface_spacing) times its spacing and it is in no tool; else it
//    goes:
//    the material leaving the zone gets nodes at about the zone's spacing;
//    an emitted node's data is the old cloud's interpolant where it goes;
//  - a zone node whose emission point lies nearer another zone node's place
//    than its own goes (it left the region by a hair across a side the flow
//    only grazes, and would be within keep_out of that node a step later);
//  - the zone's nodes come back at their places, their data (velocity and
//    pressure coefficients as the next solve's start, effective strain and
//    the fields the nodes carry) the old cloud's max-ent interpolant there.
// The node rezoning (node_adaptivity.hpp) then works outside the zone only.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/stepper/node_adaptivity.hpp>

namespace maxentflow {

/// A region fixed in space, or to a moving tool, whose nodes stay where they
/// are put (see above).
struct EulerianZone {
  /// True inside the zone or on its boundary.
  std::function<bool(const Eigen::Vector2d&)> inside;
  /// The zone's nodes (all inside it): a cloud for the material that fills
  /// the zone, with nodes on the tool faces that bound it.
  Eigen::Matrix2Xd nodes;
  /// A zone node carried out of the zone stays in the material where no node
  /// outside the zone is closer than this times its spacing h0.
  double emit_spacing = 0.8;
  /// The same for a zone node carried out on the material's boundary (the
  /// product's surface): smaller, so that a column's surface node does not
  /// go while the one below it stays and the alpha-shape cuts a notch down
  /// to it (axisymmetric E2: 0.6 h deep next to the land's end, with the
  /// graded grid's rows closer there than its columns).
  double emit_surface_spacing = 0.4;
  /// Where the material leaves the zone slowly (a zone node carried out by
  /// less than emit_ahead times its spacing in a step), a zone node that
  /// stays in the material is emitted emit_ahead of its spacing downstream
  /// of its place, along its own displacement (0: where the step left it).
  /// The material behind a cutting tool's tip leaves at a twelfth of a
  /// spacing a step: a node emitted where it lies sits next to the zone's
  /// node that comes back (keep_out removes it the next step, so nothing
  /// is ever emitted, and a node that close would leave the basis two
  /// nearly equal functions). In steady flow the emitted node's data is
  /// what the flow carries along its path there.
  double emit_ahead = 0.0;
  /// The zone starts once every zone node lies in the material or within
  /// fill_tol times its spacing of the material's boundary.
  double fill_tol = 0.25;
  /// A material node outside the zone closer than this times a zone node's
  /// spacing to it goes when the zone's nodes are put back.
  double keep_out = 0.25;
  /// Per zone node (or empty: fill_tol for all), that node's fill_tol: e.g.
  /// larger on a die land's face, where a Lagrangian product on a fine cloud
  /// runs a fraction of a spacing below the land (the zone then puts it back
  /// on the land once).
  std::vector<double> fill_tols;
  /// The tool the zone moves with (its index in the stepper; -1: fixed in
  /// space): `inside` and `nodes` are then given where the tool starts (its
  /// displacement zero) and translate with it, e.g. the region round a
  /// cutting tool's tip, where the flow is steady in the tool's frame.
  int tool = -1;
  double fill_tol_of(Eigen::Index t) const {
    return fill_tols.empty() ? fill_tol : fill_tols[static_cast<std::size_t>(t)];
  }

  /// The zone translated by d (its nodes and its region).
  EulerianZone translated(const Eigen::Vector2d& d) const {
    EulerianZone z = *this;
    z.nodes.colwise() += d;
    z.inside = [f = inside, d](const Eigen::Vector2d& p) { return f(p - d); };
    return z;
  }

  void validate(const std::string& where) const {
    require(static_cast<bool>(inside), "an EulerianZone needs its region (inside)", where);
    require(nodes.cols() >= 3 && nodes.allFinite(),
            detail::cat("an EulerianZone needs at least 3 finite nodes, got ", nodes.cols()), where);
    for (Eigen::Index t = 0; t < nodes.cols(); ++t)
      require(inside(nodes.col(t)),
              detail::cat("EulerianZone node ", t, " at (", nodes(0, t), ", ", nodes(1, t), ") lies outside the zone"),
              where);
    require(std::isfinite(emit_spacing) && emit_spacing > 0,
            detail::cat("EulerianZone emit_spacing must be > 0, got ", emit_spacing), where);
    require(std::isfinite(fill_tol) && fill_tol >= 0, detail::cat("EulerianZone fill_tol must be >= 0, got ", fill_tol),
            where);
    require(fill_tols.empty() || static_cast<Eigen::Index>(fill_tols.size()) == nodes.cols(),
            detail::cat("EulerianZone fill_tols needs one value per zone node (", nodes.cols(), "), got ",
                        fill_tols.size()),
            where);
    for (std::size_t t = 0; t < fill_tols.size(); ++t)
      require(std::isfinite(fill_tols[t]) && fill_tols[t] >= 0,
              detail::cat("EulerianZone fill_tols[", t, "] must be >= 0, got ", fill_tols[t]), where);
    require(tool >= -1, detail::cat("EulerianZone tool must be a tool's index or -1, got ", tool), where);
    require(std::isfinite(emit_ahead) && emit_ahead >= 0,
            detail::cat("EulerianZone emit_ahead must be >= 0, got ", emit_ahead), where);
    require(std::isfinite(emit_surface_spacing) && emit_surface_spacing > 0,
            detail::cat("EulerianZone emit_surface_spacing must be > 0, got ", emit_surface_spacing), where);
    require(std::isfinite(keep_out) && keep_out >= 0 && keep_out < std::min(emit_spacing, emit_surface_spacing),
            detail::cat("EulerianZone keep_out must lie in [0, min(emit_spacing, emit_surface_spacing)), got ",
                        keep_out),
            where);
  }
};

/// One rezoning by an EulerianZone.
struct ZoneUpdate {
  bool active = false;       ///< the material fills the zone (else nothing changes)
  NodeAdaptation change;     ///< removed: old nodes; inserted: the zone's nodes, in order, with weights
  std::vector<int> emitted;  ///< old zone nodes that stay in the material, outside the zone
  Eigen::Matrix2Xd emitted_at;  ///< where each emitted node goes (EulerianZone::emit_ahead)
  /// Per emitted node, the old cloud's basis at emitted_at, (old node, value)
  /// (empty where the basis failed: the node keeps its own data).
  std::vector<std::vector<std::pair<int, double>>> emitted_weights;
  int fallbacks = 0;         ///< zone nodes whose data is the nearest old node's (the basis failed there)
  int emitted_fallbacks = 0;  ///< emitted nodes that keep their own data (the basis failed there)
};

/// Sets each emitted node's column of a per-node field (one column per old
/// node) to the old cloud's interpolant where the node goes; where the basis
/// failed (no weights) the node keeps its own.
inline void interpolate_emitted(const ZoneUpdate& z, Eigen::MatrixXd& field) {
  Eigen::MatrixXd moved = Eigen::MatrixXd::Zero(field.rows(), static_cast<Eigen::Index>(z.emitted.size()));
  for (std::size_t k = 0; k < z.emitted.size(); ++k)
    for (const auto& [b, w] : z.emitted_weights[k]) moved.col(static_cast<Eigen::Index>(k)) += w * field.col(b);
  for (std::size_t k = 0; k < z.emitted.size(); ++k)
    if (!z.emitted_weights[k].empty()) field.col(z.emitted[k]) = moved.col(static_cast<Eigen::Index>(k));
}

/// Whether p lies in the region the mesh's boundary loops enclose (even-odd
/// rule), or within tol of a boundary segment.
template <class Mesh>
bool in_material(const Mesh& mesh, const Eigen::Vector2d& p, double tol) {
  const auto& x = mesh.nodes();
  bool in = false;
  for (const auto& seg : mesh.boundary_segments()) {
    const Eigen::Vector2d a = x.col(seg.a), b = x.col(seg.b), d = b - a;
    const double t = std::clamp((p - a).dot(d) / std::max(d.squaredNorm(), 1e-300), 0.0, 1.0);
    if ((a + t * d - p).squaredNorm() <= tol * tol) return true;
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < a.x() + (p.y() - a.y()) / (b.y() - a.y()) * d.x()) in = !in;
  }
  return in;
}

/// Whether the material (the region of the mesh's boundary loops) fills the
/// zone: every zone node in it or within its fill_tol times its spacing
/// h0_zone of its boundary.
template <class Mesh>
bool zone_filled(const Mesh& mesh, const EulerianZone& zone, const Eigen::VectorXd& h0_zone) {
  for (Eigen::Index t = 0; t < zone.nodes.cols(); ++t)
    if (!in_material(mesh, zone.nodes.col(t), zone.fill_tol_of(t) * h0_zone(t))) return false;
  return true;
}

/// The basis's nonzero values at p as (node, value), or none where it fails
/// there (p outside the cloud's hull).
template <class Basis>
std::vector<std::pair<int, double>> weights_at(const Basis& basis, const Eigen::Vector2d& p) {
  std::vector<std::pair<int, double>> w;
  try {
    const auto v = basis.evaluate(p, false);
    for (std::size_t j = 0; j < v.node.size(); ++j)
      if (v.p[j] != 0.0) w.emplace_back(v.node[j], v.p[j]);
  } catch (const Error&) {
    w.clear();  // the caller falls back to a node's own data and counts it
  }
  return w;
}

/// Plans the zone's rezoning of the cloud of `mesh`: zone_id(a) is the zone
/// node that old node a is, plus one (0: a material node), h0 the old nodes'
/// target spacing and h0_zone the zone nodes'. `basis` is a max-ent basis of
/// the old cloud (values at the zone's nodes weight their data);
/// `admissible(x)` is false inside a tool (a zone node the step pushed into
/// a tool goes back to its place).
template <class Mesh, class Basis>
ZoneUpdate plan_zone_update(const Mesh& mesh, const Basis& basis, const EulerianZone& zone,
                            const Eigen::VectorXd& zone_id, const Eigen::VectorXd& h0,
                            const Eigen::VectorXd& h0_zone,
                            const std::function<bool(const Eigen::Vector2d&)>& admissible = {}) {
  const std::string where = "plan_zone_update";
  const auto& x = mesh.nodes();
  const Eigen::Index n = x.cols(), T = zone.nodes.cols();
  require(zone_id.size() == n && h0.size() == n && h0_zone.size() == T,
          detail::cat("zone ids (", zone_id.size(), ") and h0 (", h0.size(), ") need one value per node (", n,
                      "), h0_zone one per zone node (", h0_zone.size(), " for ", T, ")"),
          where);
  ZoneUpdate out;
  if (!zone_filled(mesh, zone, h0_zone)) return out;
  out.active = true;
  // Old nodes inside the zone go; zone nodes carried out are the outflow.
  std::vector<char> inside(static_cast<std::size_t>(n), 0);
  std::vector<int> outside;  // material nodes outside the zone, then the emitted
  std::vector<int> candidates;
  for (Eigen::Index a = 0; a < n; ++a) {
    inside[static_cast<std::size_t>(a)] = zone.inside(x.col(a)) ? 1 : 0;
    if (inside[static_cast<std::size_t>(a)]) continue;
    (zone_id(a) > 0 ? candidates : outside).push_back(static_cast<int>(a));
  }
  std::vector<char> gone(inside.begin(), inside.end());
  // A material node outside the zone but next to a zone node (the flow can
  // carry one onto a zone node on the zone's boundary) goes: the zone's node
  // takes its place.
  std::erase_if(outside, [&](int a) {
    bool near = false;
    for (Eigen::Index t = 0; t < T && !near; ++t)
      near = (zone.nodes.col(t) - x.col(a)).norm() < zone.keep_out * h0_zone(t);
    if (near) gone[static_cast<std::size_t>(a)] = 1;
    return near;
  });
  std::vector<char> on_boundary(static_cast<std::size_t>(n), 0);
  for (int a : mesh.boundary_nodes()) on_boundary[static_cast<std::size_t>(a)] = 1;
  std::vector<Eigen::Vector2d> at;  // where each emitted node goes
  const auto placed = [&](int a) {
    const auto e = std::find(out.emitted.begin(), out.emitted.end(), a);
    return e == out.emitted.end() ? Eigen::Vector2d(x.col(a)) : at[static_cast<std::size_t>(e - out.emitted.begin())];
  };
  for (int c : candidates) {
    const double r =
        (on_boundary[static_cast<std::size_t>(c)] ? zone.emit_surface_spacing : zone.emit_spacing) * h0(c);
    Eigen::Vector2d p = x.col(c);
    const Eigen::Vector2d home = zone.nodes.col(static_cast<Eigen::Index>(zone_id(c)) - 1), d = p - home;
    bool crowded = false;
    if (d.norm() < zone.emit_ahead * h0(c)) {
      // Slow outflow: on along its path, still in the material and out of the zone.
      p = home + zone.emit_ahead * h0(c) * d / std::max(d.norm(), 1e-300);
      crowded = d.norm() == 0.0 || zone.inside(p) || !in_material(mesh, p, zone.fill_tol * h0(c));
    }
    crowded = crowded || (admissible && !admissible(p));  // in a tool: put back, never carried on
    // Nearer another zone node's place than its own: still in the zone's
    // cloud (a node that left the region by a hair across a side the flow
    // only grazes), and within keep_out of that node a step or two later.
    for (Eigen::Index t = 0; t < T && !crowded; ++t)
      crowded = (zone.nodes.col(t) - p).squaredNorm() < (home - p).squaredNorm();
    for (std::size_t k = 0; k < outside.size() && !crowded; ++k)
      crowded = (placed(outside[k]) - p).squaredNorm() < r * r;
    if (crowded) {
      gone[static_cast<std::size_t>(c)] = 1;
    } else {
      outside.push_back(c);
      out.emitted.push_back(c);
      at.push_back(p);
    }
  }
  out.emitted_at.resize(2, static_cast<Eigen::Index>(at.size()));
  for (std::size_t k = 0; k < at.size(); ++k) out.emitted_at.col(static_cast<Eigen::Index>(k)) = at[k];
  out.emitted_weights.resize(at.size());
  for (std::size_t k = 0; k < at.size(); ++k) {
    out.emitted_weights[k] = weights_at(basis, at[k]);
    if (out.emitted_weights[k].empty()) ++out.emitted_fallbacks;
  }
  for (Eigen::Index a = 0; a < n; ++a)
    if (gone[static_cast<std::size_t>(a)]) out.change.removed.push_back(static_cast<int>(a));
  // The zone's nodes, their data the old cloud's interpolant.
  out.change.inserted = zone.nodes;
  out.change.parents.resize(static_cast<std::size_t>(T));
  out.change.weights.resize(static_cast<std::size_t>(T));
  for (Eigen::Index t = 0; t < T; ++t) {
    const Eigen::Vector2d p = zone.nodes.col(t);
    const auto k = static_cast<std::size_t>(t);
    out.change.weights[k] = weights_at(basis, p);
    if (!out.change.weights[k].empty()) {
      const auto top = std::max_element(out.change.weights[k].begin(), out.change.weights[k].end(),
                                        [](const auto& a, const auto& b) { return a.second < b.second; });
      out.change.parents[k] = {top->first, top->first};
    } else {
      // Counted and reported by the caller: the nearest node's data instead.
      ++out.fallbacks;
      Eigen::Index nearest = 0;
      (x.colwise() - p).colwise().squaredNorm().minCoeff(&nearest);
      out.change.parents[k] = {static_cast<int>(nearest), static_cast<int>(nearest)};
    }
  }
  return out;
}

}  // namespace maxentflow

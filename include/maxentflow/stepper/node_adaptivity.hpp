// maxentflow: Lagrangian node rezoning. The updated-Lagrangian motion
// (Eq. 18) carries the node cloud with the material's stretch, and the
// paper's own cutting run degrades from the "uneven node distribution produced
// by the flow" (section "Orthogonal cutting"). At the end of an extrusion
// stroke the billet next to the ram is compressed about 4:1 along the ram and
// stretched 4:1 across it; at about 10:1 the alpha-shape can no longer tell
// that anisotropic cloud from a gap and the basis supports (beta = gamma / h_a^2,
// one h_a for both directions) span many nodes one way and one node the other.
//
// The rezoning keeps kept-mesh edges between min_ratio and max_ratio times a
// target spacing h0 (the first configuration's h_a, carried by the nodes):
//  - an edge shorter than min_ratio h0 loses one end: an interior edge an
//    interior end, a boundary edge an end where the boundary turns by less
//    than max_turn (a straight tool face, the axis), never a corner; the
//    removed node's neighbours are locked for this pass so no hole opens;
//  - an edge longer than max_ratio h0 gets a node at its middle (a boundary
//    edge only where the side is straight at one end at least), unless that
//    point is inside a tool or closer than half its h0 to a node (the
//    diagonals of a stretched cell would otherwise put two nodes side by
//    side) or, for an interior edge, to the boundary (a flat triangle there
//    would be cut: a notch). Boundary edges go first; a single unlocked
//    interior node that blocks a boundary edge's middle is removed instead
//    (the middle replaces it on the side).
// A new node's data (velocity and pressure coefficients as the next solve's
// start, effective strain, h0) is the mean of its edge's ends: the linear
// interpolant along the edge. The defaults leave a 50 % reduction (2:1
// stretch) alone.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>

namespace maxentflow {

struct NodeAdaptivityParams {
  bool enabled = false;
  /// Keep a node on each convex tool corner the material wraps (a square
  /// die's corner): without one the boundary cuts the corner, the alpha-shape
  /// bridges it with a triangle inside the tool, and the node above the corner
  /// turns interior, loses its contact row and flows into the tool.
  bool corner_nodes = true;
  double min_ratio = 0.35;   ///< remove an end of a kept edge shorter than this * h0
  /// ... or shorter than this times its ends' mean nodal spacing h_a (the
  /// basis's own, IntegrationMesh::h()): a cloud squeezed one way and
  /// stretched the other (about 5:1 next to an extrusion ram late in the
  /// stroke) has nodes so close, for the support they share, that their
  /// basis functions nearly coincide; their coefficients are then poorly
  /// determined and Picard's increments never settle (docs/method.md,
  /// section 12). 0: off.
  double min_spacing_ratio = 0.3;
  double max_ratio = 2.5;    ///< split a kept edge longer than this * h0
  double max_turn_deg = 20;  ///< boundary nodes are removed only where the boundary turns less
};

/// One rezoning: nodes removed and nodes inserted at edge middles.
struct NodeAdaptation {
  std::vector<int> removed;                  ///< old indices, ascending
  std::vector<std::array<int, 2>> parents;   ///< ends (old indices) of each split edge
  Eigen::Matrix2Xd inserted;                 ///< positions of the new nodes
  /// Where a new node's data is not its parents' mean: old nodes and weights
  /// (e.g. the old cloud's basis at its position, an EulerianZone's node).
  /// Empty, or one list per new node (an empty list: the parents' mean).
  std::vector<std::vector<std::pair<int, double>>> weights;

  bool empty() const { return removed.empty() && parents.empty(); }
  int added() const { return static_cast<int>(parents.size()); }

  /// Old index -> new index (-1: removed); new nodes follow the kept ones.
  std::vector<int> old_to_new(Eigen::Index n_old) const {
    std::vector<int> map(static_cast<std::size_t>(n_old), 0);
    for (int a : removed) map[static_cast<std::size_t>(a)] = -1;
    int k = 0;
    for (auto& m : map) m = m < 0 ? -1 : k++;
    return map;
  }

  /// Per-node data (one column per node, any number of rows) on the new
  /// cloud: kept columns in order, then the mean of each new node's parents.
  template <class Derived>
  Eigen::Matrix<typename Derived::Scalar, Derived::RowsAtCompileTime, Eigen::Dynamic> transfer(
      const Eigen::MatrixBase<Derived>& f) const {
    const std::vector<int> map = old_to_new(f.cols());
    const Eigen::Index kept = f.cols() - static_cast<Eigen::Index>(removed.size());
    Eigen::Matrix<typename Derived::Scalar, Derived::RowsAtCompileTime, Eigen::Dynamic> g(
        f.rows(), kept + added());
    for (Eigen::Index a = 0; a < f.cols(); ++a)
      if (map[static_cast<std::size_t>(a)] >= 0) g.col(map[static_cast<std::size_t>(a)]) = f.col(a);
    for (int i = 0; i < added(); ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (k < weights.size() && !weights[k].empty()) {
        g.col(kept + i).setZero();
        for (const auto& [a, w] : weights[k]) g.col(kept + i) += w * f.col(a);
      } else {
        g.col(kept + i) = (f.col(parents[k][0]) + f.col(parents[k][1])) / 2;
      }
    }
    return g;
  }
  /// The same for a vector with k consecutive entries per node.
  Eigen::VectorXd transfer_interleaved(const Eigen::VectorXd& f, int k) const {
    const Eigen::Map<const Eigen::MatrixXd> m(f.data(), k, f.size() / k);
    const Eigen::MatrixXd g = transfer(m);
    return Eigen::Map<const Eigen::VectorXd>(g.data(), g.size());
  }
  /// New node positions.
  Eigen::Matrix2Xd positions(const Eigen::Matrix2Xd& x) const {
    const std::vector<int> map = old_to_new(x.cols());
    Eigen::Matrix2Xd y(2, x.cols() - static_cast<Eigen::Index>(removed.size()) + added());
    for (Eigen::Index a = 0; a < x.cols(); ++a)
      if (map[static_cast<std::size_t>(a)] >= 0) y.col(map[static_cast<std::size_t>(a)]) = x.col(a);
    y.rightCols(added()) = inserted;
    return y;
  }
};

/// Plans a rezoning of the mesh's nodes for target spacing h0 (one per node).
/// `admissible(x)` is false where no node may be put (inside a tool).
template <class Mesh>
NodeAdaptation plan_node_adaptation(const Mesh& mesh, const Eigen::VectorXd& h0,
                                    const NodeAdaptivityParams& prm,
                                    const std::function<bool(const Eigen::Vector2d&)>& admissible = {}) {
  const std::string where = "plan_node_adaptation";
  const auto& x = mesh.nodes();
  const Eigen::Index n = x.cols();
  require(h0.size() == n, detail::cat("h0 has ", h0.size(), " entries for ", n, " nodes"), where);
  require(prm.min_spacing_ratio >= 0 && prm.min_spacing_ratio < 1,
          detail::cat("need 0 <= min_spacing_ratio < 1, got ", prm.min_spacing_ratio), where);
  require(prm.min_ratio > 0 && prm.max_ratio > 2 * prm.min_ratio,
          detail::cat("need 0 < min_ratio (", prm.min_ratio, ") and max_ratio (", prm.max_ratio,
                      ") > 2 min_ratio, or a split edge's halves would be removed again"),
          where);
  const auto N = static_cast<std::size_t>(n);
  NodeAdaptation out;

  // Boundary turning angle per node (nodes on several loops, pinches: corners).
  const double pi = std::acos(-1.0);
  std::vector<double> turn(N, 0.0);
  std::vector<int> loops_at(N, 0);
  for (const auto& loop : mesh.boundary_loops()) {
    const std::size_t m = loop.nodes.size();
    for (std::size_t i = 0; i < m; ++i) {
      const int a = loop.nodes[i];
      const Eigen::Vector2d u = x.col(a) - x.col(loop.nodes[(i + m - 1) % m]);
      const Eigen::Vector2d w = x.col(loop.nodes[(i + 1) % m]) - x.col(a);
      turn[static_cast<std::size_t>(a)] = std::abs(std::atan2(u.x() * w.y() - u.y() * w.x(), u.dot(w)));
      ++loops_at[static_cast<std::size_t>(a)];
    }
  }
  const double max_turn = prm.max_turn_deg * pi / 180.0;
  auto removable = [&](int a) {
    const auto i = static_cast<std::size_t>(a);
    if (!mesh.is_boundary_node(a)) return true;
    return loops_at[i] == 1 && turn[i] < max_turn;
  };

  const auto& edges = mesh.edges();
  std::vector<std::vector<int>> adjacent(N);
  for (const auto& e : edges) {
    adjacent[static_cast<std::size_t>(e.a)].push_back(e.b);
    adjacent[static_cast<std::size_t>(e.b)].push_back(e.a);
  }
  auto ratio = [&](const MeshEdge& e) {
    return (x.col(e.b) - x.col(e.a)).norm() / (0.5 * (h0[e.a] + h0[e.b]));
  };
  // shortness[k] < 1: edge k is short, against h0 or against the basis's spacing.
  const Eigen::VectorXd& ha = mesh.h();
  std::vector<double> r(edges.size()), shortness(edges.size());
  for (std::size_t k = 0; k < edges.size(); ++k) {
    r[k] = ratio(edges[k]);
    const double len = (x.col(edges[k].b) - x.col(edges[k].a)).norm();
    shortness[k] = r[k] / prm.min_ratio;
    if (prm.min_spacing_ratio > 0)
      shortness[k] = std::min(shortness[k], len / (prm.min_spacing_ratio * 0.5 * (ha[edges[k].a] + ha[edges[k].b])));
  }
  std::vector<std::size_t> order(edges.size());
  std::iota(order.begin(), order.end(), std::size_t{0});

  // Removal, shortest edges first.
  std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return shortness[i] < shortness[j]; });
  std::vector<char> locked(N, 0), gone(N, 0);
  for (std::size_t k : order) {
    if (shortness[k] >= 1.0) break;
    const int a = edges[k].a, b = edges[k].b;
    // A boundary node goes only for a short boundary edge (crowding along the
    // side); crowding across it takes the interior node, or nothing.
    const bool along = edges[k].is_boundary();
    auto can = [&](int c) {
      return !locked[static_cast<std::size_t>(c)] && (!mesh.is_boundary_node(c) || (along && removable(c)));
    };
    int victim = -1;
    if (can(a) && can(b)) {
      // The straighter end goes; of two alike, the clearly more crowded
      // (h_a smaller by 2 %): the other may have a gap on its far side, which
      // would only grow. Not on round-off: a regular cloud keeps one pattern.
      const double ta = turn[static_cast<std::size_t>(a)], tb = turn[static_cast<std::size_t>(b)];
      const bool crowded_b = ha[b] < 0.98 * ha[a];
      victim = ta < tb ? a : (tb < ta ? b : (crowded_b ? b : a));
    } else if (can(a)) {
      victim = a;
    } else if (can(b)) {
      victim = b;
    }
    if (victim < 0) continue;
    gone[static_cast<std::size_t>(victim)] = locked[static_cast<std::size_t>(victim)] = 1;
    for (int c : adjacent[static_cast<std::size_t>(victim)]) locked[static_cast<std::size_t>(c)] = 1;
  }

  // Insertion, longest edges first, with a bucket grid for the distance check.
  // Boundary edges first: a stretched cell's diagonal would otherwise put its
  // node half a cell inside, next to the side's middle, and block it.
  std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
    const bool bi = edges[i].is_boundary(), bj = edges[j].is_boundary();
    return bi != bj ? bi : r[i] > r[j];
  });
  std::vector<double> sorted_h0(h0.data(), h0.data() + n);
  std::nth_element(sorted_h0.begin(), sorted_h0.begin() + n / 2, sorted_h0.end());
  const double cell = std::max(sorted_h0[static_cast<std::size_t>(n / 2)], 1e-300);
  auto key = [&](const Eigen::Vector2d& p) {
    return std::array<long long, 2>{static_cast<long long>(std::floor(p.x() / cell)),
                                    static_cast<long long>(std::floor(p.y() / cell))};
  };
  struct KeyHash {
    std::size_t operator()(const std::array<long long, 2>& k) const {
      return std::hash<long long>()(k[0] * 73856093LL ^ k[1] * 19349663LL);
    }
  };
  struct Entry {
    Eigen::Vector2d x;
    int node;  // old index, -1: inserted
  };
  std::unordered_map<std::array<long long, 2>, std::vector<Entry>, KeyHash> grid;
  for (Eigen::Index a = 0; a < n; ++a)
    if (!gone[static_cast<std::size_t>(a)]) grid[key(x.col(a))].push_back({x.col(a), static_cast<int>(a)});
  // Nodes within `radius` of p: -2 none, the old index if exactly one old node, else -1.
  auto blocker = [&](const Eigen::Vector2d& p, double radius) {
    const auto c = key(p);
    const auto reach = static_cast<long long>(std::ceil(radius / cell));
    int found = -2;
    for (long long i = c[0] - reach; i <= c[0] + reach; ++i)
      for (long long j = c[1] - reach; j <= c[1] + reach; ++j) {
        const auto it = grid.find({i, j});
        if (it == grid.end()) continue;
        for (const auto& q : it->second)
          if ((q.x - p).squaredNorm() < radius * radius) {
            if (found != -2 || q.node < 0) return -1;
            found = q.node;
          }
      }
    return found;
  };
  // Boundary segments by the cells their bounding boxes cover: a node put
  // closer than half a spacing to a side would make a flat triangle there,
  // which the alpha cut drops (a notch in the material).
  std::unordered_map<std::array<long long, 2>, std::vector<int>, KeyHash> sides;
  const auto& segments = mesh.boundary_segments();
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const auto lo = key(x.col(segments[i].a).cwiseMin(x.col(segments[i].b)));
    const auto hi = key(x.col(segments[i].a).cwiseMax(x.col(segments[i].b)));
    for (long long u = lo[0]; u <= hi[0]; ++u)
      for (long long v = lo[1]; v <= hi[1]; ++v) sides[{u, v}].push_back(static_cast<int>(i));
  }
  auto off_sides = [&](const Eigen::Vector2d& p, double radius) {
    const auto c = key(p);
    const auto reach = static_cast<long long>(std::ceil(radius / cell));
    for (long long i = c[0] - reach; i <= c[0] + reach; ++i)
      for (long long j = c[1] - reach; j <= c[1] + reach; ++j) {
        const auto it = sides.find({i, j});
        if (it == sides.end()) continue;
        for (int k : it->second) {
          const Eigen::Vector2d a = x.col(segments[static_cast<std::size_t>(k)].a);
          const Eigen::Vector2d d = x.col(segments[static_cast<std::size_t>(k)].b) - a;
          const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
          if ((a + t * d - p).squaredNorm() < radius * radius) return false;
        }
      }
    return true;
  };
  std::vector<Eigen::Vector2d> added;
  for (std::size_t k : order) {
    if (r[k] <= prm.max_ratio) continue;
    const int a = edges[k].a, b = edges[k].b;
    if (gone[static_cast<std::size_t>(a)] || gone[static_cast<std::size_t>(b)]) continue;
    if (edges[k].is_boundary() && !(removable(a) || removable(b))) continue;  // off a curved side
    const Eigen::Vector2d m = 0.5 * (x.col(a) + x.col(b));
    const double hm = 0.5 * (h0[a] + h0[b]);
    if (admissible && !admissible(m)) continue;
    const int near = blocker(m, 0.5 * hm);
    if (edges[k].is_boundary() && near >= 0 && !mesh.is_boundary_node(near) &&
        !locked[static_cast<std::size_t>(near)]) {
      // An interior node next to the side's middle (it got there with the
      // flow) would leave a flat triangle the alpha cut drops: it moves onto
      // the side, i.e. it goes and the middle comes.
      gone[static_cast<std::size_t>(near)] = locked[static_cast<std::size_t>(near)] = 1;
      for (int c : adjacent[static_cast<std::size_t>(near)]) locked[static_cast<std::size_t>(c)] = 1;
      auto& bucket = grid[key(x.col(near))];
      bucket.erase(std::find_if(bucket.begin(), bucket.end(), [&](const Entry& e) { return e.node == near; }));
    } else if (near != -2) {
      continue;
    }
    if (!edges[k].is_boundary() && !off_sides(m, 0.5 * hm)) continue;
    grid[key(m)].push_back({m, -1});
    added.push_back(m);
    out.parents.push_back({a, b});
  }
  for (Eigen::Index a = 0; a < n; ++a)
    if (gone[static_cast<std::size_t>(a)]) out.removed.push_back(static_cast<int>(a));
  out.inserted.resize(2, static_cast<Eigen::Index>(added.size()));
  for (std::size_t i = 0; i < added.size(); ++i) out.inserted.col(static_cast<Eigen::Index>(i)) = added[i];
  return out;
}

/// Adds to `a` a node on each corner in `corners` (convex tool corners) that
/// lies within half a spacing of a boundary segment of `mesh` and has no node
/// (kept or new) within min_ratio h0 of it; its data is its segment ends' mean.
template <class Mesh>
void add_corner_nodes(const Mesh& mesh, const Eigen::VectorXd& h0, const NodeAdaptivityParams& prm,
                      const std::vector<Eigen::Vector2d>& corners, NodeAdaptation& a) {
  const auto& x = mesh.nodes();
  std::vector<char> gone(static_cast<std::size_t>(x.cols()), 0);
  for (int r : a.removed) gone[static_cast<std::size_t>(r)] = 1;
  for (const Eigen::Vector2d& c : corners) {
    bool crowded = false;
    for (Eigen::Index k = 0; k < x.cols() && !crowded; ++k)
      crowded = !gone[static_cast<std::size_t>(k)] && (x.col(k) - c).norm() < prm.min_ratio * h0[k];
    for (std::size_t i = 0; i < a.parents.size() && !crowded; ++i)
      crowded = (a.inserted.col(static_cast<Eigen::Index>(i)) - c).norm() <
                prm.min_ratio * 0.5 * (h0[a.parents[i][0]] + h0[a.parents[i][1]]);
    if (crowded) continue;
    double best = std::numeric_limits<double>::infinity();
    std::array<int, 2> ends{-1, -1};
    for (const auto& seg : mesh.boundary_segments()) {
      if (gone[static_cast<std::size_t>(seg.a)] || gone[static_cast<std::size_t>(seg.b)]) continue;
      const Eigen::Vector2d p = x.col(seg.a), q = x.col(seg.b);
      const double t = std::clamp((c - p).dot(q - p) / (q - p).squaredNorm(), 0.0, 1.0);
      const double d = (p + t * (q - p) - c).norm();
      if (d <= 0.5 * 0.5 * (mesh.h()(seg.a) + mesh.h()(seg.b)) && d < best) {
        best = d;
        ends = {seg.a, seg.b};
      }
    }
    if (ends[0] < 0) continue;
    a.parents.push_back(ends);
    a.inserted.conservativeResize(2, a.inserted.cols() + 1);
    a.inserted.col(a.inserted.cols() - 1) = c;
  }
}

}  // namespace maxentflow

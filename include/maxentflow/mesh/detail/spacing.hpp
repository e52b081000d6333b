// maxentflow internals: edges of a triangulation and the natural-neighbour
// spacing h_a on them (paper, section "The stabilized viscoplastic formulation",
// the algorithm after Eq. (14)); shared by nodal_spacing() and IntegrationMesh.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

/// Relative tolerance below which a Voronoi edge (2-D) or facet (3-D) counts as
/// degenerate: circumcentres closer than this times the edge length coincide.
inline constexpr double voronoi_tolerance = 1e-8;

/// An edge of a triangulation: from node `a` to node `b`, with triangle `left`
/// on its left (the edge runs counter-clockwise in it) and triangle `right`
/// on its right, or -1 on a boundary.
struct MeshEdge {
  int a = -1;
  int b = -1;
  int left = -1;
  int right = -1;
  bool is_boundary() const { return right < 0; }
};

namespace detail {

/// Circumcentre of the triangle (p, q, r), computed relative to p.
inline Eigen::Vector2d circumcentre(const Eigen::Vector2d& p, const Eigen::Vector2d& q,
                                    const Eigen::Vector2d& r) {
  const Eigen::Vector2d d = q - p, e = r - p;
  const double den = 2.0 * (d.x() * e.y() - d.y() * e.x());
  const double dd = d.squaredNorm(), ee = e.squaredNorm();
  return p + Eigen::Vector2d((e.y() * dd - d.y() * ee) / den, (d.x() * ee - e.x() * dd) / den);
}

/// Signed area of the triangle (p, q, r): positive when counter-clockwise.
inline double signed_area(const Eigen::Vector2d& p, const Eigen::Vector2d& q,
                          const Eigen::Vector2d& r) {
  return 0.5 * ((q.x() - p.x()) * (r.y() - p.y()) - (q.y() - p.y()) * (r.x() - p.x()));
}

/// Throws unless every triangle has three distinct node indices in [0, n).
inline void require_valid_triangles(const std::vector<std::array<int, 3>>& tri, Eigen::Index n,
                                    const std::string& where) {
  for (std::size_t t = 0; t < tri.size(); ++t) {
    const auto& v = tri[t];
    for (int a : v)
      if (a < 0 || a >= n)
        throw Error(cat("triangle ", t, " refers to node ", a, ", outside [0, ", n, ")"),
                    cat(where, ", triangle ", t));
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0])
      throw Error(cat("triangle ", t, " repeats a node (", v[0], ", ", v[1], ", ", v[2], ")"),
                  cat(where, ", triangle ", t));
  }
}

/// Unique edges of a triangle list (any orientation) by sorting its half-edges,
/// O(T log T). The edge runs as in its `left` triangle. Throws if an edge has
/// more than two triangles.
inline void triangulation_edges(const std::vector<std::array<int, 3>>& tri,
                                std::vector<MeshEdge>& edges, const std::string& where) {
  struct Half {
    int lo, hi, t, from;
  };
  std::vector<Half> half;
  half.reserve(3 * tri.size());
  for (std::size_t t = 0; t < tri.size(); ++t)
    for (std::size_t i = 0; i < 3; ++i) {
      const int a = tri[t][i], b = tri[t][(i + 1) % 3];
      half.push_back({std::min(a, b), std::max(a, b), static_cast<int>(t), a});
    }
  std::sort(half.begin(), half.end(), [](const Half& x, const Half& y) {
    return x.lo != y.lo ? x.lo < y.lo : x.hi != y.hi ? x.hi < y.hi : x.t < y.t;
  });
  edges.clear();
  edges.reserve(half.size() / 2 + tri.size() + 2);
  for (std::size_t k = 0; k < half.size();) {
    std::size_t m = k + 1;
    while (m < half.size() && half[m].lo == half[k].lo && half[m].hi == half[k].hi) ++m;
    if (m - k > 2)
      throw Error(cat("edge (", half[k].lo, ", ", half[k].hi, ") is shared by ", m - k,
                      " triangles (at most 2 in a triangulation)"),
                  cat(where, ", triangles ", half[k].t, ", ", half[k + 1].t, ", ", half[k + 2].t));
    const Half& h = half[k];
    const int other = h.from == h.lo ? h.hi : h.lo;
    edges.push_back({h.from, other, h.t, m - k == 2 ? half[k + 1].t : -1});
    k = m;
  }
}

/// Unique edges from a neighbour array (`nbr[t][i]` across the edge opposite
/// local vertex i, -1 for none), O(T): each edge once, running as in `left`.
inline void edges_from_neighbours(const std::vector<std::array<int, 3>>& tri,
                                  const std::vector<std::array<int, 3>>& nbr,
                                  std::vector<MeshEdge>& edges) {
  edges.clear();
  edges.reserve(2 * tri.size() + 2);
  for (std::size_t t = 0; t < tri.size(); ++t)
    for (std::size_t i = 0; i < 3; ++i) {
      const int n = nbr[t][i];
      if (n < 0 || static_cast<int>(t) < n)
        edges.push_back({tri[t][(i + 1) % 3], tri[t][(i + 2) % 3], static_cast<int>(t), n});
    }
}

/// Per-triangle circumcentres, one column per triangle.
inline void circumcentres(const Eigen::Matrix2Xd& nodes, const std::vector<std::array<int, 3>>& tri,
                          Eigen::Matrix2Xd& cc) {
  cc.resize(2, static_cast<Eigen::Index>(tri.size()));
  for (std::size_t t = 0; t < tri.size(); ++t)
    cc.col(static_cast<Eigen::Index>(t)) =
        circumcentre(nodes.col(tri[t][0]), nodes.col(tri[t][1]), nodes.col(tri[t][2]));
}

/// h_a = mean distance from node a to its natural neighbours: the ends of its
/// edges, except an interior edge whose two triangles share the circumcentre
/// to within `tol` times the edge length (a zero-length Voronoi edge, e.g. the
/// diagonal of a regular grid's square). Boundary edges always count.
/// `count[a]` gets the number of edges of node a (0: the node is in no triangle,
/// h_a = 0). A node whose edges are all excluded (impossible in a valid
/// Delaunay mesh) falls back to the mean over all its edges.
inline void natural_neighbour_spacing(const Eigen::Matrix2Xd& nodes,
                                      const std::vector<MeshEdge>& edges,
                                      const Eigen::Matrix2Xd& cc, double tol, Eigen::VectorXd& h,
                                      std::vector<int>& count) {
  const auto n = nodes.cols();
  h.setZero(n);
  count.assign(static_cast<std::size_t>(n), 0);
  std::vector<int> natural(static_cast<std::size_t>(n), 0);
  Eigen::VectorXd all = Eigen::VectorXd::Zero(n);
  for (const MeshEdge& e : edges) {
    const double len = (nodes.col(e.b) - nodes.col(e.a)).norm();
    all[e.a] += len;
    all[e.b] += len;
    ++count[static_cast<std::size_t>(e.a)];
    ++count[static_cast<std::size_t>(e.b)];
    if (e.right >= 0 && (cc.col(e.left) - cc.col(e.right)).norm() <= tol * len) continue;
    h[e.a] += len;
    h[e.b] += len;
    ++natural[static_cast<std::size_t>(e.a)];
    ++natural[static_cast<std::size_t>(e.b)];
  }
  for (Eigen::Index a = 0; a < n; ++a) {
    const auto k = static_cast<std::size_t>(a);
    if (natural[k] > 0)
      h[a] /= natural[k];
    else if (count[k] > 0)
      h[a] = all[a] / count[k];
  }
}

/// Names the nodes in no triangle (at most 10 of them) for an error message.
inline std::string list_nodes(const std::vector<int>& count, int& how_many) {
  std::string s;
  how_many = 0;
  for (std::size_t a = 0; a < count.size(); ++a)
    if (count[a] == 0) {
      if (how_many < 10) s += (how_many ? ", " : "") + std::to_string(a);
      ++how_many;
    }
  if (how_many > 10) s += ", ...";
  return s;
}

}  // namespace detail
}  // namespace maxentflow

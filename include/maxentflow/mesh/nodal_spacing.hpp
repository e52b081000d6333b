// maxentflow: nodal spacing h_a, the mean distance from node a to its natural
// neighbours (paper, the algorithm after Eq. (14)); it sets the locality
// beta_a = gamma / h_a^2 of the max-ent basis and rho in tau = Cs rho^2 / mu.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross

#include <maxentflow/core/error.hpp>
#include <maxentflow/mesh/detail/delaunay_2.hpp>
#include <maxentflow/mesh/detail/spacing.hpp>

namespace maxentflow {

/// The unique edges of a triangle list (sorted half-edges, O(T log T)).
/// Throws if an edge has more than two triangles or a triangle is malformed.
inline std::vector<MeshEdge> triangulation_edges(const std::vector<std::array<int, 3>>& triangles,
                                                 Eigen::Index n_nodes) {
  detail::require_valid_triangles(triangles, n_nodes, "triangulation_edges");
  std::vector<MeshEdge> edges;
  detail::triangulation_edges(triangles, edges, "triangulation_edges");
  return edges;
}

/// h_a on a given triangulation: the mean distance from a to its natural
/// neighbours, i.e. the ends of its edges without the interior edges whose two
/// triangles share the circumcentre (zero-length Voronoi edges such as the
/// diagonals of a regular grid), so that h_a is the grid spacing on a regular
/// grid. Boundary edges always count. Throws naming the nodes in no triangle.
inline Eigen::VectorXd nodal_spacing(const Eigen::Matrix2Xd& nodes,
                                     const std::vector<std::array<int, 3>>& triangles) {
  const std::string where = "nodal_spacing";
  detail::require_finite_nodes(nodes, where);
  detail::require_valid_triangles(triangles, nodes.cols(), where);
  std::vector<MeshEdge> edges;
  detail::triangulation_edges(triangles, edges, where);
  Eigen::Matrix2Xd cc;
  detail::circumcentres(nodes, triangles, cc);
  Eigen::VectorXd h;
  std::vector<int> count;
  detail::natural_neighbour_spacing(nodes, edges, cc, voronoi_tolerance, h, count);
  int missing = 0;
  const std::string list = detail::list_nodes(count, missing);
  if (missing > 0)
    throw Error(detail::cat(missing, " node(s) in no triangle: ", list), where + ", nodes " + list);
  return h;
}

namespace detail {

inline Eigen::VectorXd delaunay_spacing_1(const Eigen::Matrix<double, 1, Eigen::Dynamic>& x) {
  const std::string where = "delaunay_spacing<1>";
  const auto n = x.cols();
  if (n < 2) throw Error(cat("need at least 2 nodes, got ", n), where);
  require_finite_nodes(x, where);
  std::vector<int> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int i, int j) { return x[i] < x[j] || (x[i] == x[j] && i < j); });
  Eigen::VectorXd h(n);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const int a = order[k];
    double sum = 0.0;
    int m = 0;
    if (k > 0) {
      const int b = order[k - 1];
      if (x[a] == x[b])
        throw Error(cat("coincident nodes ", b, " and ", a, " at ", x[a]),
                    cat(where, ", nodes ", b, " and ", a));
      sum += x[a] - x[b];
      ++m;
    }
    if (k + 1 < order.size()) {
      sum += x[order[k + 1]] - x[a];
      ++m;
    }
    h[a] = sum / m;
  }
  return h;
}

inline Eigen::VectorXd delaunay_spacing_2(const Eigen::Matrix2Xd& nodes) {
  Delaunay2 dt;
  delaunay_2(nodes, dt, "delaunay_spacing<2>");
  std::vector<MeshEdge> edges;
  edges_from_neighbours(dt.tri, dt.nbr, edges);
  Eigen::Matrix2Xd cc;
  circumcentres(nodes, dt.tri, cc);
  Eigen::VectorXd h;
  std::vector<int> count;
  natural_neighbour_spacing(nodes, edges, cc, voronoi_tolerance, h, count);
  return h;
}

// 3-D: the Voronoi facet dual to an edge is the polygon through the
// circumcentres of the cells around the edge, closed at infinity by two rays
// along the outward normals of the hull facets when the edge is on the convex
// hull. It has zero area when those circumcentres are collinear (e.g. the face
// diagonal between two cubes of a grid: two points) or coincide (a body
// diagonal: one point) and, on the hull, the rays run along that same line.
// Then the ends of the edge are not natural neighbours.
inline Eigen::VectorXd delaunay_spacing_3(const Eigen::Matrix3Xd& nodes) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Vb = CGAL::Triangulation_vertex_base_with_info_3<int, K>;
  using Cb = CGAL::Triangulation_cell_base_with_info_3<int, K,
                                                       CGAL::Delaunay_triangulation_cell_base_3<K>>;
  using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
  using Dt = CGAL::Delaunay_triangulation_3<K, Tds>;
  const std::string where = "delaunay_spacing<3>";
  const auto n = nodes.cols();
  if (n < 4) throw Error(cat("need at least 4 nodes, got ", n), where);
  require_finite_nodes(nodes, where);

  std::vector<std::pair<K::Point_3, int>> pts;
  pts.reserve(static_cast<std::size_t>(n));
  for (Eigen::Index a = 0; a < n; ++a)
    pts.emplace_back(K::Point_3(nodes(0, a), nodes(1, a), nodes(2, a)), static_cast<int>(a));
  Dt dt(pts.begin(), pts.end());
  if (static_cast<Eigen::Index>(dt.number_of_vertices()) != n) require_distinct_nodes(nodes, where);
  if (dt.dimension() < 3)
    throw Error(cat("all ", n, " nodes are coplanar: no 3-D triangulation"), where);

  const auto vec = [](const K::Point_3& p) { return Eigen::Vector3d(p.x(), p.y(), p.z()); };
  std::vector<Eigen::Vector3d> cc;
  cc.reserve(dt.number_of_finite_cells());
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c) {
    c->info() = static_cast<int>(cc.size());
    cc.push_back(vec(K::Construct_circumcenter_3()(c->vertex(0)->point(), c->vertex(1)->point(),
                                                   c->vertex(2)->point(), c->vertex(3)->point())));
  }

  Eigen::VectorXd h = Eigen::VectorXd::Zero(n);
  std::vector<int> count(static_cast<std::size_t>(n), 0);
  std::vector<Eigen::Vector3d> ring;  // circumcentres around the edge, in order
  std::vector<Eigen::Vector3d> rays;  // outward normals of hull facets
  for (auto e = dt.finite_edges_begin(); e != dt.finite_edges_end(); ++e) {
    const auto va = e->first->vertex(e->second), vb = e->first->vertex(e->third);
    const Eigen::Vector3d d = vec(vb->point()) - vec(va->point());
    const double len = d.norm();
    const double tol = voronoi_tolerance * len;
    ring.clear();
    rays.clear();
    auto circ = dt.incident_cells(*e);
    const auto done = circ;
    do {
      if (dt.is_infinite(circ)) {
        const int k = circ->index(dt.infinite_vertex());
        const Eigen::Vector3d p0 = vec(circ->vertex((k + 1) & 3)->point());
        const Eigen::Vector3d p1 = vec(circ->vertex((k + 2) & 3)->point());
        const Eigen::Vector3d p2 = vec(circ->vertex((k + 3) & 3)->point());
        rays.push_back((p1 - p0).cross(p2 - p0).normalized());
      } else {
        ring.push_back(cc[static_cast<std::size_t>(circ->info())]);
      }
    } while (++circ != done);
    bool degenerate;
    if (rays.empty()) {
      // Bounded facet: its (vector) area, projected on the edge direction.
      Eigen::Vector3d area = Eigen::Vector3d::Zero();
      for (std::size_t i = 1; i + 1 < ring.size(); ++i)
        area += (ring[i] - ring[0]).cross(ring[i + 1] - ring[0]);
      degenerate = std::abs(0.5 * area.dot(d / len)) <= tol * len;
    } else {
      // Unbounded: zero area iff the rays are parallel and every circumcentre
      // lies on one line along them.
      degenerate = rays.size() == 2 && rays[0].cross(rays[1]).norm() <= voronoi_tolerance;
      for (std::size_t i = 1; degenerate && i < ring.size(); ++i)
        degenerate = (ring[i] - ring[0]).cross(rays[0]).norm() <= tol;
    }
    if (degenerate) continue;
    const int a = va->info(), b = vb->info();
    h[a] += len;
    h[b] += len;
    ++count[static_cast<std::size_t>(a)];
    ++count[static_cast<std::size_t>(b)];
  }
  for (Eigen::Index a = 0; a < n; ++a)
    if (count[static_cast<std::size_t>(a)] > 0) h[a] /= count[static_cast<std::size_t>(a)];
  return h;
}

}  // namespace detail

/// h_a on the Delaunay triangulation of all nodes, Dim = 1 (neighbours in
/// sorted order), 2 (CGAL Delaunay, then the rule of nodal_spacing()) or
/// 3 (CGAL Delaunay_triangulation_3, excluding edges whose Voronoi facet has
/// zero area: its circumcentres coincide or are collinear, e.g. a grid's face
/// and body diagonals). Throws on coincident nodes (naming both), non-finite coordinates and
/// nodes that span no Dim-dimensional simplex.
template <int Dim>
Eigen::VectorXd delaunay_spacing(const Eigen::Matrix<double, Dim, Eigen::Dynamic>& nodes) {
  static_assert(Dim >= 1 && Dim <= 3, "maxentflow: delaunay_spacing is for Dim = 1, 2, 3");
  if constexpr (Dim == 1)
    return detail::delaunay_spacing_1(nodes);
  else if constexpr (Dim == 2)
    return detail::delaunay_spacing_2(nodes);
  else
    return detail::delaunay_spacing_3(nodes);
}

}  // namespace maxentflow

// maxentflow: nodal spacing h_a of 3-D node clouds (CGAL's 3-D Delaunay),
// delaunay_spacing<3>; the 1-D and 2-D cases are in nodal_spacing.hpp.
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross

#include <maxentflow/core/error.hpp>
#include <maxentflow/mesh/detail/spacing.hpp>
#include <maxentflow/mesh/nodal_spacing.hpp>

namespace maxentflow::detail {

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

template <>
struct DelaunaySpacing<3> {
  static Eigen::VectorXd of(const Eigen::Matrix3Xd& x) { return delaunay_spacing_3(x); }
};

}  // namespace maxentflow::detail

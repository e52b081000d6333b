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

#include <Eigen/Core>

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

// delaunay_spacing<Dim>'s implementation for each dimension; Dim = 3 lives in
// nodal_spacing_3.hpp so that 1-D and 2-D users do not compile CGAL's 3-D
// Delaunay.
template <int Dim>
struct DelaunaySpacing {
  static_assert(Dim != Dim, "maxentflow: for Dim = 3 include <maxentflow/mesh/nodal_spacing_3.hpp>");
};
template <>
struct DelaunaySpacing<1> {
  static Eigen::VectorXd of(const Eigen::Matrix<double, 1, Eigen::Dynamic>& x) { return delaunay_spacing_1(x); }
};
template <>
struct DelaunaySpacing<2> {
  static Eigen::VectorXd of(const Eigen::Matrix2Xd& x) { return delaunay_spacing_2(x); }
};

}  // namespace detail

/// h_a on the Delaunay triangulation of all nodes, Dim = 1 (neighbours in
/// sorted order), 2 (CGAL Delaunay, then the rule of nodal_spacing()) or
/// 3 (CGAL Delaunay_triangulation_3, excluding edges whose Voronoi facet has
/// zero area: its circumcentres coincide or are collinear, e.g. a grid's face
/// and body diagonals; include nodal_spacing_3.hpp). Throws on coincident nodes (naming both), non-finite coordinates and
/// nodes that span no Dim-dimensional simplex.
template <int Dim>
Eigen::VectorXd delaunay_spacing(const Eigen::Matrix<double, Dim, Eigen::Dynamic>& nodes) {
  static_assert(Dim >= 1 && Dim <= 3, "maxentflow: delaunay_spacing is for Dim = 1, 2, 3");
  return detail::DelaunaySpacing<Dim>::of(nodes);
}

}  // namespace maxentflow

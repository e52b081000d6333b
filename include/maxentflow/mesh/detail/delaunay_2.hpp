// maxentflow internals: the 2-D Delaunay triangulation of a node cloud (CGAL),
// flattened into index arrays, with the input checks every mesh builder needs.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <Eigen/Core>

#include <maxentflow/core/error.hpp>

namespace maxentflow::detail {

/// Throws unless every column of `nodes` is finite (names the first bad node).
template <class Derived>
void require_finite_nodes(const Eigen::MatrixBase<Derived>& nodes, const std::string& where) {
  for (Eigen::Index a = 0; a < nodes.cols(); ++a)
    if (!nodes.col(a).allFinite())
      throw Error(cat("node ", a, " has a non-finite coordinate (", nodes.col(a).transpose(), ")"),
                  cat(where, ", node ", a));
}

/// Throws naming two coincident nodes, if any (lexicographic sort, O(N log N)).
template <class Derived>
void require_distinct_nodes(const Eigen::MatrixBase<Derived>& nodes, const std::string& where) {
  std::vector<int> order(static_cast<std::size_t>(nodes.cols()));
  std::iota(order.begin(), order.end(), 0);
  const auto less = [&](int i, int j) {
    for (Eigen::Index d = 0; d < nodes.rows(); ++d) {
      if (nodes(d, i) < nodes(d, j)) return true;
      if (nodes(d, j) < nodes(d, i)) return false;
    }
    return i < j;
  };
  std::sort(order.begin(), order.end(), less);
  for (std::size_t k = 1; k < order.size(); ++k) {
    const int i = order[k - 1], j = order[k];
    if (nodes.col(i) == nodes.col(j))
      throw Error(cat("coincident nodes ", i, " and ", j, " at (", nodes.col(i).transpose(), ")"),
                  cat(where, ", nodes ", i, " and ", j));
  }
}

/// CGAL types of the 2-D triangulation: node index on vertices, face index on faces.
struct Cgal2 {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
  using Fb = CGAL::Triangulation_face_base_with_info_2<int, K>;
  using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
  using Delaunay = CGAL::Delaunay_triangulation_2<K, Tds>;
  using Point = K::Point_2;
};

/// The Delaunay triangulation as arrays. `tri[t]` is counter-clockwise;
/// `nbr[t][i]` is the triangle across the edge opposite local vertex i
/// (from tri[t][i+1] to tri[t][i+2]), -1 outside the convex hull.
struct Delaunay2 {
  std::vector<std::array<int, 3>> tri;
  std::vector<std::array<int, 3>> nbr;
  std::vector<std::pair<Cgal2::Point, int>> scratch;  // reused input buffer
};

/// Triangulates `nodes` (checks: >= 3 nodes, finite, distinct, not collinear).
inline void delaunay_2(const Eigen::Matrix2Xd& nodes, Delaunay2& out, const std::string& where) {
  const auto n = nodes.cols();
  if (n < 3) throw Error(cat("need at least 3 nodes, got ", n), where);
  require_finite_nodes(nodes, where);

  out.scratch.clear();
  out.scratch.reserve(static_cast<std::size_t>(n));
  for (Eigen::Index a = 0; a < n; ++a)
    out.scratch.emplace_back(Cgal2::Point(nodes(0, a), nodes(1, a)), static_cast<int>(a));
  Cgal2::Delaunay dt;
  dt.insert(out.scratch.begin(), out.scratch.end());  // spatially sorted insertion

  // CGAL merges equal points silently: find the pair only when one went missing.
  if (static_cast<Eigen::Index>(dt.number_of_vertices()) != n) require_distinct_nodes(nodes, where);
  if (dt.dimension() < 2)
    throw Error(cat("all ", n, " nodes are collinear: no 2-D triangulation"), where);

  int count = 0;
  for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) f->info() = count++;
  out.tri.resize(static_cast<std::size_t>(count));
  out.nbr.resize(static_cast<std::size_t>(count));
  for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
    auto& t = out.tri[static_cast<std::size_t>(f->info())];
    auto& g = out.nbr[static_cast<std::size_t>(f->info())];
    for (int i = 0; i < 3; ++i) {
      t[static_cast<std::size_t>(i)] = f->vertex(i)->info();
      const auto h = f->neighbor(i);
      g[static_cast<std::size_t>(i)] = dt.is_infinite(h) ? -1 : h->info();
    }
  }
}

}  // namespace maxentflow::detail

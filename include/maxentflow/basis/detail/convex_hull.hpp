// maxentflow: convex hulls as half-spaces, for the weak Kronecker-delta property
// of max-ent bases on hull facets.
#pragma once

#include <maxentflow/core/error.hpp>

#include <Eigen/Core>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_2.h>
#include <CGAL/convex_hull_3.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numeric>
#include <vector>

namespace maxentflow::detail {

/// One facet of a convex hull: points inside satisfy n . x <= c (n unit, outward).
/// [lo, hi] bounds the facet's vertices (to find the facet from a point quickly).
template <int D>
struct HalfSpace {
  Eigen::Matrix<double, D, 1> n;
  double c = 0;
  Eigen::Matrix<double, D, 1> lo, hi;
};

/// 1-D hull: the two end points.
inline std::vector<HalfSpace<1>> hull_halfspaces(const Eigen::Matrix<double, 1, Eigen::Dynamic>& x,
                                                 double = 0.0) {
  const double lo = x.minCoeff(), hi = x.maxCoeff();
  HalfSpace<1> left, right;
  left.n(0) = -1;
  left.c = -lo;
  left.lo(0) = left.hi(0) = lo;
  right.n(0) = 1;
  right.c = hi;
  right.lo(0) = right.hi(0) = hi;
  return {left, right};
}

/// 2-D hull with CGAL's exact orientation predicates (a monotone chain with a
/// tolerance loses true corners when round-off jitters collinear points, as it
/// does after a few updated-Lagrangian steps). Then a vertex within `merge_tol`
/// (a distance) of the line through its neighbours is dropped, so that each
/// nearly straight side is one facet.
inline std::vector<HalfSpace<2>> hull_halfspaces(const Eigen::Matrix<double, 2, Eigen::Dynamic>& x,
                                                 double merge_tol = 0.0) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  std::vector<K::Point_2> pts;
  pts.reserve(static_cast<std::size_t>(x.cols()));
  for (Eigen::Index i = 0; i < x.cols(); ++i) pts.emplace_back(x(0, i), x(1, i));
  std::vector<K::Point_2> out;
  CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(out));  // counter-clockwise
  std::vector<Eigen::Vector2d> v;
  for (const auto& p : out) v.emplace_back(p.x(), p.y());
  // A vertex is dropped only if it and every vertex dropped between its kept
  // neighbours stay within merge_tol of the facet that replaces them: merges
  // that cascade along a jittered straight side would otherwise leave dropped
  // vertices (and points on their segments) outside the hull by more than that.
  const std::size_t nv = v.size();
  std::vector<char> kept(nv, 1);
  auto near_line = [&](std::size_t a, std::size_t c) {
    const Eigen::Vector2d e = v[c] - v[a];
    const double len = e.norm();
    if (!(len > 0)) return false;
    for (std::size_t j = (a + 1) % nv; j != c; j = (j + 1) % nv)
      if (std::abs(e.x() * (v[j].y() - v[a].y()) - e.y() * (v[j].x() - v[a].x())) / len > merge_tol)
        return false;
    return true;
  };
  std::size_t left = nv;
  for (bool changed = true; changed && left > 3;) {
    changed = false;
    for (std::size_t i = 0; i < nv && left > 3; ++i) {
      if (!kept[i]) continue;
      std::size_t a = (i + nv - 1) % nv, c = (i + 1) % nv;
      while (!kept[a]) a = (a + nv - 1) % nv;
      while (!kept[c]) c = (c + 1) % nv;
      if (near_line(a, c)) {
        kept[i] = 0;
        --left;
        changed = true;
      }
    }
  }
  std::vector<Eigen::Vector2d> h;
  for (std::size_t i = 0; i < nv; ++i)
    if (kept[i]) h.push_back(v[i]);
  std::vector<HalfSpace<2>> hs;
  for (std::size_t i = 0; i < h.size(); ++i) {
    const Eigen::Vector2d a = h[i], b = h[(i + 1) % h.size()];
    const Eigen::Vector2d e = b - a;
    const double len = e.norm();
    if (len == 0) continue;
    HalfSpace<2> f;
    f.n = Eigen::Vector2d(e(1), -e(0)) / len;  // counter-clockwise hull: outward is right
    f.c = f.n.dot(a);
    f.lo = a.cwiseMin(b);
    f.hi = a.cwiseMax(b);
    hs.push_back(f);
  }
  return hs;
}

/// 3-D hull through CGAL; coplanar triangles give one facet each (duplicates are
/// harmless: a point on a face lies on all of them).
inline std::vector<HalfSpace<3>> hull_halfspaces(const Eigen::Matrix<double, 3, Eigen::Dynamic>& x,
                                                 double = 0.0) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using P = K::Point_3;
  std::vector<P> pts;
  pts.reserve(static_cast<std::size_t>(x.cols()));
  for (Eigen::Index i = 0; i < x.cols(); ++i) pts.emplace_back(x(0, i), x(1, i), x(2, i));
  CGAL::Surface_mesh<P> sm;
  CGAL::convex_hull_3(pts.begin(), pts.end(), sm);
  std::vector<HalfSpace<3>> hs;
  for (auto f : sm.faces()) {
    std::vector<Eigen::Vector3d> v;
    for (auto vd : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      const P& p = sm.point(vd);
      v.emplace_back(p.x(), p.y(), p.z());
    }
    if (v.size() < 3) continue;
    Eigen::Vector3d nrm = (v[1] - v[0]).cross(v[2] - v[0]);
    const double len = nrm.norm();
    if (len == 0) continue;
    HalfSpace<3> h;
    h.n = nrm / len;  // CGAL orients hull faces outward (counter-clockwise seen from outside)
    h.c = h.n.dot(v[0]);
    h.lo = h.hi = v[0];
    for (const auto& q : v) {
      h.lo = h.lo.cwiseMin(q);
      h.hi = h.hi.cwiseMax(q);
    }
    hs.push_back(h);
  }
  return hs;
}

/// An orthonormal basis of the plane normal to n (rows), for restricting a basis
/// to a hull facet.
template <int D>
Eigen::Matrix<double, D - 1, D> tangent_frame(const Eigen::Matrix<double, D, 1>& n) {
  Eigen::Matrix<double, D - 1, D> T;
  if constexpr (D == 2) {
    T << -n(1), n(0);
  } else if constexpr (D == 3) {
    Eigen::Vector3d a = std::abs(n(0)) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    Eigen::Vector3d t1 = (a - n.dot(a) * n).normalized();
    Eigen::Vector3d t2 = n.cross(t1);
    T.row(0) = t1.transpose();
    T.row(1) = t2.transpose();
  }
  return T;
}

}  // namespace maxentflow::detail

// maxentflow: quadrature rules on the integration cells (triangles) and their
// edges (segments). The paper integrates with "standard Gauss quadrature
// methods within the triangles" (section "Numerical examples", preamble); the
// edge rules serve the consistency correction of docs/cases.md V1 and boundary terms.
#pragma once

#include <array>
#include <cmath>
#include <vector>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

/// Symmetric rule on a triangle: barycentric abscissas, weights summing to 1
/// (multiply by the triangle's area), exact for polynomials up to `degree`.
struct TriangleRule {
  std::vector<std::array<double, 3>> bary;
  std::vector<double> weight;
  int degree = 0;
  int size() const { return static_cast<int>(weight.size()); }
};

/// Rule on the segment t in [0, 1]: weights summing to 1 (multiply by the
/// length), exact for polynomials up to `degree`.
struct SegmentRule {
  std::vector<double> t;
  std::vector<double> weight;
  int degree = 0;
  int size() const { return static_cast<int>(weight.size()); }
};

namespace detail {

// Orbits of the symmetry group of the triangle: the centroid, the 3 points
// (a, a, 1-2a), and the 6 points of (a, b, 1-a-b).
inline void add_orbit_centroid(TriangleRule& r, double w) {
  r.bary.push_back({1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0});
  r.weight.push_back(w);
}

inline void add_orbit_21(TriangleRule& r, double a, double w) {
  const double b = 1.0 - 2.0 * a;
  r.bary.push_back({a, a, b});
  r.bary.push_back({a, b, a});
  r.bary.push_back({b, a, a});
  r.weight.insert(r.weight.end(), 3, w);
}

inline void add_orbit_111(TriangleRule& r, double a, double b, double w) {
  const double c = 1.0 - a - b;
  r.bary.push_back({a, b, c});
  r.bary.push_back({a, c, b});
  r.bary.push_back({b, a, c});
  r.bary.push_back({b, c, a});
  r.bary.push_back({c, a, b});
  r.bary.push_back({c, b, a});
  r.weight.insert(r.weight.end(), 6, w);
}

// Dunavant (1985) rules. The orbit parameters were re-derived by Gauss-Newton
// on the moment equations in 40-digit arithmetic (residual < 1e-40) and are
// stored rounded to 22 digits; the tests check every monomial to 1e-14.
inline TriangleRule make_triangle_rule(int points) {
  TriangleRule r;
  switch (points) {
    case 1:
      r.degree = 1;
      add_orbit_centroid(r, 1.0);
      break;
    case 3:
      r.degree = 2;
      add_orbit_21(r, 1.0 / 6.0, 1.0 / 3.0);
      break;
    case 6:
      r.degree = 4;
      add_orbit_21(r, 0.4459484909159648863183293, 0.2233815896780114656950070);
      add_orbit_21(r, 0.09157621350977074345957146, 0.1099517436553218676383263);
      break;
    case 7:
      // Closed form: a = (6 -+ sqrt 15)/21, w = (155 -+ sqrt 15)/1200.
      r.degree = 5;
      add_orbit_centroid(r, 0.225);
      add_orbit_21(r, 0.4701420641051150897704412, 0.1323941527885061807376494);
      add_orbit_21(r, 0.1012865073234563388009874, 0.1259391805448271525956839);
      break;
    case 12:
      r.degree = 6;
      add_orbit_21(r, 0.2492867451709104212916386, 0.1167862757263793660252896);
      add_orbit_21(r, 0.06308901449150222834033160, 0.05084490637020681692093681);
      add_orbit_111(r, 0.05314504984481694735324967, 0.3103524510337844054166077,
                    0.08285107561837357519355346);
      break;
    default:
      throw Error(cat("no triangle rule with ", points, " points (have 1, 3, 6, 7, 12)"),
                  "make_triangle_rule");
  }
  return r;
}

// Gauss-Legendre on [0, 1]: Newton on P_n from the Chebyshev-like guess
// cos(pi (i + 3/4) / (n + 1/2)), derivative from the three-term recurrence.
inline SegmentRule make_segment_rule(int n) {
  SegmentRule r;
  r.degree = 2 * n - 1;
  r.t.resize(static_cast<std::size_t>(n));
  r.weight.resize(static_cast<std::size_t>(n));
  const double pi = 3.14159265358979323846;
  // P_n(x) and P_{n-1}(x) by the three-term recurrence.
  const auto legendre = [n](double x, double& pn, double& pnm1) {
    double p0 = 1.0, p1 = x;
    for (int k = 2; k <= n; ++k) {
      const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    pn = p1;
    pnm1 = p0;
  };
  for (int i = 0; i < n; ++i) {
    double x = std::cos(pi * (i + 0.75) / (n + 0.5));
    double pn = 0.0, pnm1 = 0.0;
    for (int it = 0; it < 100; ++it) {
      legendre(x, pn, pnm1);
      const double dx = pn / (n * (x * pn - pnm1) / (x * x - 1.0));
      x -= dx;
      if (std::abs(dx) <= 1e-16) break;
    }
    legendre(x, pn, pnm1);
    const double dp = n * (x * pn - pnm1) / (x * x - 1.0);
    const auto j = static_cast<std::size_t>(n - 1 - i);  // ascending t
    r.t[j] = 0.5 * (1.0 + x);
    r.weight[j] = 1.0 / ((1.0 - x * x) * dp * dp);  // 2/((1-x^2) P_n'^2), halved for [0, 1]
  }
  return r;
}

}  // namespace detail

/// The Dunavant rule with `points` in {1, 3, 6, 7, 12} (degrees 1, 2, 4, 5, 6).
inline const TriangleRule& triangle_rule(int points) {
  static const std::array<TriangleRule, 5> rules = {
      detail::make_triangle_rule(1), detail::make_triangle_rule(3), detail::make_triangle_rule(6),
      detail::make_triangle_rule(7), detail::make_triangle_rule(12)};
  switch (points) {
    case 1:
      return rules[0];
    case 3:
      return rules[1];
    case 6:
      return rules[2];
    case 7:
      return rules[3];
    case 12:
      return rules[4];
    default:
      throw Error(detail::cat("no triangle rule with ", points, " points (have 1, 3, 6, 7, 12)"),
                  "triangle_rule");
  }
}

/// Gauss-Legendre with `points` in 1..8 (degree 2 points - 1) on t in [0, 1].
inline const SegmentRule& segment_rule(int points) {
  static const std::array<SegmentRule, 8> rules = [] {
    std::array<SegmentRule, 8> r;
    for (int n = 1; n <= 8; ++n) r[static_cast<std::size_t>(n - 1)] = detail::make_segment_rule(n);
    return r;
  }();
  if (points < 1 || points > 8)
    throw Error(detail::cat("no segment rule with ", points, " points (have 1..8)"),
                "segment_rule");
  return rules[static_cast<std::size_t>(points - 1)];
}

}  // namespace maxentflow

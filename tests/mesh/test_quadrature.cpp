// Quadrature rules: exactness up to the stated degree, failure one degree up.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <vector>

#include <maxentflow/mesh/quadrature.hpp>

using maxentflow::Error;
using maxentflow::SegmentRule;
using maxentflow::TriangleRule;

namespace {

double factorial(int n) {
  double f = 1.0;
  for (int k = 2; k <= n; ++k) f *= k;
  return f;
}

// Polynomial in barycentric coordinates: coefficient of l1^a l2^b l3^c at c[a][b][c].
using Poly = std::vector<std::vector<std::vector<double>>>;

Poly poly_one(int d) {
  Poly p(
      static_cast<std::size_t>(d + 1),
      std::vector<std::vector<double>>(static_cast<std::size_t>(d + 1),
                                       std::vector<double>(static_cast<std::size_t>(d + 1), 0.0)));
  p[0][0][0] = 1.0;
  return p;
}

// p *= (v0 l1 + v1 l2 + v2 l3)
Poly poly_times_linear(const Poly& p, const std::array<double, 3>& v) {
  const auto n = p.size();
  Poly q = poly_one(static_cast<int>(n) - 1);
  q[0][0][0] = 0.0;
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = 0; a + b < n; ++b)
      for (std::size_t c = 0; a + b + c < n; ++c) {
        const double x = p[a][b][c];
        if (x == 0.0) continue;
        if (a + b + c + 1 >= n) continue;
        q[a + 1][b][c] += x * v[0];
        q[a][b + 1][c] += x * v[1];
        q[a][b][c + 1] += x * v[2];
      }
  return q;
}

// Exact integral of x^i y^j over the triangle with vertices P (columns), via
// x = sum x_k l_k and int_T l1^a l2^b l3^c = 2 |T| a! b! c! / (a+b+c+2)!.
double exact_monomial(const std::array<std::array<double, 2>, 3>& P, int i, int j) {
  const int d = i + j;
  Poly p = poly_one(d);
  const std::array<double, 3> xs = {P[0][0], P[1][0], P[2][0]};
  const std::array<double, 3> ys = {P[0][1], P[1][1], P[2][1]};
  for (int k = 0; k < i; ++k) p = poly_times_linear(p, xs);
  for (int k = 0; k < j; ++k) p = poly_times_linear(p, ys);
  const double area = 0.5 * std::abs((P[1][0] - P[0][0]) * (P[2][1] - P[0][1]) -
                                     (P[1][1] - P[0][1]) * (P[2][0] - P[0][0]));
  double s = 0.0;
  for (int a = 0; a <= d; ++a)
    for (int b = 0; a + b <= d; ++b)
      for (int c = 0; a + b + c <= d; ++c)
        s += p[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)]
              [static_cast<std::size_t>(c)] *
             2.0 * area * factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 2);
  return s;
}

double rule_monomial(const TriangleRule& r, const std::array<std::array<double, 2>, 3>& P, int i,
                     int j) {
  const double area = 0.5 * std::abs((P[1][0] - P[0][0]) * (P[2][1] - P[0][1]) -
                                     (P[1][1] - P[0][1]) * (P[2][0] - P[0][0]));
  double s = 0.0;
  for (std::size_t q = 0; q < r.weight.size(); ++q) {
    const auto& b = r.bary[q];
    const double x = b[0] * P[0][0] + b[1] * P[1][0] + b[2] * P[2][0];
    const double y = b[0] * P[0][1] + b[1] * P[1][1] + b[2] * P[2][1];
    s += area * r.weight[q] * std::pow(x, i) * std::pow(y, j);
  }
  return s;
}

// Largest error over monomials of total degree `d`, relative to the largest
// exact monomial integral of that degree (scale of the problem).
double max_error_at_degree(const TriangleRule& r, const std::array<std::array<double, 2>, 3>& P,
                           int d) {
  double err = 0.0, scale = 0.0;
  for (int i = 0; i <= d; ++i) {
    const double exact = exact_monomial(P, i, d - i);
    err = std::max(err, std::abs(rule_monomial(r, P, i, d - i) - exact));
    scale = std::max(scale, std::abs(exact));
  }
  return err / scale;
}

const std::array<std::array<double, 2>, 3> reference = {{{0.0, 0.0}, {1.0, 0.0}, {0.0, 1.0}}};
const std::array<std::array<double, 2>, 3> skewed = {{{0.3, -0.2}, {2.1, 0.4}, {-0.5, 1.7}}};

}  // namespace

TEST_CASE("triangle rules: weights sum to 1, points inside, symmetric", "[quadrature]") {
  for (int n : {1, 3, 6, 7, 12}) {
    CAPTURE(n);
    const TriangleRule& r = maxentflow::triangle_rule(n);
    REQUIRE(r.size() == n);
    REQUIRE(r.bary.size() == r.weight.size());
    double sum = 0.0;
    for (std::size_t q = 0; q < r.weight.size(); ++q) {
      sum += r.weight[q];
      CHECK(r.weight[q] > 0.0);
      CHECK(std::abs(r.bary[q][0] + r.bary[q][1] + r.bary[q][2] - 1.0) < 1e-15);
      for (double b : r.bary[q]) CHECK((b > 0.0 && b < 1.0));
    }
    CHECK(std::abs(sum - 1.0) < 1e-15);
  }
  CHECK(maxentflow::triangle_rule(1).degree == 1);
  CHECK(maxentflow::triangle_rule(3).degree == 2);
  CHECK(maxentflow::triangle_rule(6).degree == 4);
  CHECK(maxentflow::triangle_rule(7).degree == 5);
  CHECK(maxentflow::triangle_rule(12).degree == 6);
}

TEST_CASE("7-point rule matches its closed form to the last bit", "[quadrature]") {
  const TriangleRule& r = maxentflow::triangle_rule(7);
  const double s15 = std::sqrt(15.0);
  // Orbit order: centroid, a = (6 + sqrt15)/21 (3 points), a = (6 - sqrt15)/21 (3 points).
  CHECK(r.weight[0] == 0.225);
  CHECK(r.bary[1][0] == Approx((6.0 + s15) / 21.0).epsilon(2e-16));
  CHECK(r.weight[1] == Approx((155.0 + s15) / 1200.0).epsilon(2e-16));
  CHECK(r.bary[4][0] == Approx((6.0 - s15) / 21.0).epsilon(2e-16));
  CHECK(r.weight[4] == Approx((155.0 - s15) / 1200.0).epsilon(2e-16));
}

TEST_CASE("triangle rules integrate every monomial up to their degree exactly", "[quadrature]") {
  for (int n : {1, 3, 6, 7, 12}) {
    const TriangleRule& r = maxentflow::triangle_rule(n);
    for (const auto* P : {&reference, &skewed}) {
      for (int d = 0; d <= r.degree; ++d) {
        CAPTURE(n, d, P == &reference);
        CHECK(max_error_at_degree(r, *P, d) < 1e-14);
      }
      // ...and not one degree more: the stated degree is the true one.
      CAPTURE(n);
      CHECK(max_error_at_degree(r, *P, r.degree + 1) > 1e-9);
    }
  }
}

TEST_CASE("segment rules: Gauss-Legendre of n points is exact to degree 2n-1", "[quadrature]") {
  for (int n = 1; n <= 8; ++n) {
    CAPTURE(n);
    const SegmentRule& r = maxentflow::segment_rule(n);
    REQUIRE(r.size() == n);
    CHECK(r.degree == 2 * n - 1);
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i), m = static_cast<std::size_t>(n - 1 - i);
      sum += r.weight[k];
      CHECK(r.t[k] > 0.0);
      CHECK(r.t[k] < 1.0);
      if (i > 0) CHECK(r.t[k] > r.t[k - 1]);
      CHECK(std::abs(r.t[k] + r.t[m] - 1.0) < 1e-15);  // symmetric about 1/2
      CHECK(std::abs(r.weight[k] - r.weight[m]) < 1e-15);
    }
    CHECK(std::abs(sum - 1.0) < 1e-15);
    for (int p = 0; p <= 2 * n; ++p) {
      double s = 0.0;
      for (int i = 0; i < n; ++i)
        s += r.weight[static_cast<std::size_t>(i)] * std::pow(r.t[static_cast<std::size_t>(i)], p);
      CAPTURE(p);
      if (p <= 2 * n - 1)
        CHECK(std::abs(s - 1.0 / (p + 1)) < 1e-15);
      else
        CHECK(std::abs(s - 1.0 / (p + 1)) > 1e-12);  // degree 2n fails (8 points: 3.6e-10)
    }
  }
  // Known values: 2 points at (1 -+ 1/sqrt3)/2.
  CHECK(maxentflow::segment_rule(2).t[0] == Approx(0.5 - 0.5 / std::sqrt(3.0)).epsilon(1e-15));
  CHECK(maxentflow::segment_rule(3).weight[1] == Approx(4.0 / 9.0).epsilon(1e-15));
}

TEST_CASE("unsupported rule sizes throw Error", "[quadrature]") {
  for (int n : {0, 2, 4, 5, 13, -1}) {
    CAPTURE(n);
    try {
      maxentflow::triangle_rule(n);
      FAIL("no throw");
    } catch (const Error& e) {
      CHECK(e.description().find(std::to_string(n) + " points") != std::string::npos);
      CHECK(e.where() == "triangle_rule");
    }
  }
  for (int n : {0, 9, -3}) {
    CAPTURE(n);
    CHECK_THROWS_AS(maxentflow::segment_rule(n), Error);
  }
}

// Verification V1 and V2 (docs/cases.md): homogeneous plane-strain compression
// and axisymmetric upsetting are reproduced to round-off on one configuration.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "../support/flow_problems.hpp"

using namespace maxentflow;
using maxentflow::test::block_nodes;
using maxentflow::test::FlowProblem;

namespace {

struct Homogeneous {
  double max_v_error = 0, max_p_error = 0, force_error = 0;
  SolveReport report;
};

// Half billet [0, Wh] x [0, H] (or r in [0, R]), symmetry / axis on x = 0,
// bottom plate fixed, top plate at -V; frictionless.
Homogeneous solve_homogeneous(Geometry g, double n, bool perturbed, bool consistent = true) {
  const double Wh = 10, H = 12, V = 0.06, e = V / H;
  const NortonHoff mat(150.0, n, 1e-8);
  FlowDiscretization::params dp;
  dp.consistent_integration = consistent;
  FlowProblem<NortonHoff> P(block_nodes(11, 13, Wh, H, perturbed), g, mat, 1.6, {}, dp);
  const double tol = 1e-9;
  P.velocity(on_line({0, 0}, {1, 0}, tol), {1, 0}, 0.0, g == Geometry::axisymmetric ? "axis" : "symmetry");
  P.velocity(on_line({0, 0}, {0, 1}, tol), {0, 1}, 0.0, "bottom");
  P.velocity(on_line({0, H}, {0, 1}, tol), {0, 1}, -V, "top");
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  Homogeneous out;
  out.report = solver.solve(*P.system, X);
  const bool axi = g == Geometry::axisymmetric;
  const double d = axi ? e : 2 * e / std::sqrt(3.0);
  const double mu = mat.viscosity(d).mu;
  const double p = axi ? mu * e : 2 * mu * e;
  const double F = axi ? 3 * mu * e * M_PI * Wh * Wh : 4 * mu * e * Wh;
  const auto& x = P.mesh.nodes();
  for (int a = 0; a < x.cols(); ++a) {
    const double vx = axi ? e * x(0, a) / 2 : e * x(0, a), vy = -e * x(1, a);
    out.max_v_error = std::max({out.max_v_error, std::abs(X[3 * a] - vx) / V, std::abs(X[3 * a + 1] - vy) / V});
    out.max_p_error = std::max(out.max_p_error, std::abs(X[3 * a + 2] - p) / p);
  }
  const Eigen::Vector2d top = P.system->reaction("top", X), bottom = P.system->reaction("bottom", X);
  out.force_error = std::max(std::abs(top.y() - F) / F, std::abs(bottom.y() + F) / F);
  return out;
}

}  // namespace

TEST_CASE("V1: homogeneous plane-strain compression is exact", "[verification][flow]") {
  for (double n : {0.2, 1.0})
    for (bool perturbed : {false, true}) {
      CAPTURE(n, perturbed);
      const auto r = solve_homogeneous(Geometry::plane_strain, n, perturbed);
      INFO(r.report.log());
      CHECK(r.max_v_error < 1e-8);
      CHECK(r.max_p_error < 1e-8);
      CHECK(r.force_error < 1e-8);
    }
}

TEST_CASE("V2: homogeneous axisymmetric upsetting is exact", "[verification][flow]") {
  for (double n : {0.2, 1.0})
    for (bool perturbed : {false, true}) {
      CAPTURE(n, perturbed);
      const auto r = solve_homogeneous(Geometry::axisymmetric, n, perturbed);
      INFO(r.report.log());
      CHECK(r.max_v_error < 1e-8);
      CHECK(r.max_p_error < 1e-8);
      CHECK(r.force_error < 1e-8);
    }
}

TEST_CASE("plain Gauss quadrature fails the patch test that consistent integration passes",
          "[flow]") {
  const auto plain = solve_homogeneous(Geometry::plane_strain, 1.0, true, false);
  const auto consistent = solve_homogeneous(Geometry::plane_strain, 1.0, true, true);
  WARN("V1 perturbed, n = 1: plain Gauss velocity error " << plain.max_v_error << ", pressure "
       << plain.max_p_error << ", force " << plain.force_error << "; consistent "
       << consistent.max_v_error << ", " << consistent.max_p_error << ", " << consistent.force_error);
  CHECK(plain.max_v_error > 1e3 * consistent.max_v_error);
  CHECK(consistent.max_v_error < 1e-8);
}

TEST_CASE("the discretization keeps the edge basis of boundary edges only, as evaluated", "[flow]") {
  FlowProblem<NortonHoff> P(block_nodes(11, 13, 10, 12, true), Geometry::plane_strain, NortonHoff(150.0, 0.2, 1e-8));
  const auto& tab = P.disc.edge_basis();
  const int ne = P.disc.points_per_edge();
  const auto fresh = P.basis->evaluate(P.disc.edge_points(), false);
  REQUIRE(tab.size() == fresh.size());
  std::vector<char> boundary(P.mesh.edges().size(), 0);
  for (const auto& seg : P.mesh.boundary_segments()) boundary[static_cast<std::size_t>(seg.edge)] = 1;
  int interior_with_entries = 0, boundary_different = 0, boundary_points = 0;
  for (int i = 0; i < tab.size(); ++i) {
    if (!boundary[static_cast<std::size_t>(i / ne)]) {
      interior_with_entries += tab.count(i) > 0 ? 1 : 0;
      continue;
    }
    ++boundary_points;
    const auto n0 = tab.nodes(i), n1 = fresh.nodes(i);
    const auto v0 = tab.values(i), v1 = fresh.values(i);
    if (!std::equal(n0.begin(), n0.end(), n1.begin(), n1.end()) || !std::equal(v0.begin(), v0.end(), v1.begin(), v1.end()))
      ++boundary_different;
  }
  CHECK(boundary_points == static_cast<int>(P.mesh.boundary_segments().size()) * ne);
  CHECK(interior_with_entries == 0);
  CHECK(boundary_different == 0);
  CHECK(tab.entries() < fresh.entries() / 2);  // the memory went
}

TEST_CASE("node ranks: a spatial order, so that two threads share few cells", "[flow]") {
  // A wide block numbered along x first: halving the node indices cuts it
  // along its long side, halving the ranks across it.
  FlowProblem<NortonHoff> P(block_nodes(33, 9, 32, 8, true), Geometry::plane_strain, NortonHoff(150.0, 0.2, 1e-8));
  const FlowDiscretization& d = P.disc;
  const int N = d.number_of_nodes();
  std::vector<int> seen(static_cast<std::size_t>(N), 0);
  for (int a = 0; a < N; ++a) ++seen[static_cast<std::size_t>(d.rank(a))];
  CHECK(std::all_of(seen.begin(), seen.end(), [](int k) { return k == 1; }));  // a permutation
  // The lower half of the ranks lies left of the upper half.
  double left = -1e300, right = 1e300;
  for (int a = 0; a < N; ++a)
    (d.rank(a) < N / 2 ? left : right) = d.rank(a) < N / 2 ? std::max(left, P.mesh.nodes()(0, a))
                                                            : std::min(right, P.mesh.nodes()(0, a));
  CHECK(left <= right);
  int by_rank = 0, by_index = 0;
  for (int t = 0; t < d.cells(); ++t) {
    const auto u = d.nodes(t);
    int lo = N, hi = -1;
    for (const int a : u) lo = std::min(lo, d.rank(a)), hi = std::max(hi, d.rank(a));
    CHECK(d.min_rank(t) == lo);
    CHECK(d.max_rank(t) == hi);
    by_rank += lo < N / 2 && hi >= N / 2 ? 1 : 0;
    by_index += u.front() < N / 2 && u.back() >= N / 2 ? 1 : 0;
  }
  CAPTURE(by_rank, by_index, d.cells());
  CHECK(by_rank < by_index / 2);
}

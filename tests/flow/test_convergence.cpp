// Verification V3 (power-law channel flow) and V4 (Stokes manufactured
// solution): errors and observed convergence rates on refined clouds.
#include <catch2/catch.hpp>

#include <cmath>
#include <sstream>
#include <vector>

#include "../support/flow_problems.hpp"

using namespace maxentflow;
using maxentflow::test::block_nodes;
using maxentflow::test::FlowProblem;

namespace {

// Relative L2 error of a field at the Gauss points: field(X, t, q) vs exact(x).
template <class Material, class Discrete, class Exact>
double l2_error(const FlowProblem<Material>& P, Discrete discrete, Exact exact) {
  double e2 = 0, u2 = 0;
  const auto& d = P.disc;
  for (int t = 0; t < d.cells(); ++t)
    for (int q = 0; q < d.points_per_cell(); ++q) {
      const int g = t * d.points_per_cell() + q;
      const double uh = discrete(t, q), u = exact(d.points().col(g));
      e2 += d.weight(g) * (uh - u) * (uh - u);
      u2 += d.weight(g) * u * u;
    }
  return std::sqrt(e2 / u2);
}

template <class Material>
double interpolate(const FlowProblem<Material>& P, const Eigen::VectorXd& X, int t, int q, int c) {
  const auto u = P.disc.nodes(t);
  const double* p = P.disc.values(t, q);
  double s = 0;
  for (std::size_t i = 0; i < u.size(); ++i) s += p[i] * X[3 * u[i] + c];
  return s;
}

double rate(double e0, double e1, double h0, double h1) { return std::log(e0 / e1) / std::log(h0 / h1); }

struct Channel {
  double h, error;
  int iterations;
};

// V3: x in [0, 2b], y in [-b, b], no-slip walls, ends v_y = 0, body force (G, 0).
Channel channel(double n, int ny) {
  const double b = 1.0, G = 3.0, mu0 = 2.0;
  Eigen::Matrix2Xd x = block_nodes(ny, ny, 2 * b, 2 * b, false);
  x.row(1).array() -= b;
  const NortonHoff mat(mu0, n, 1e-7);
  FlowProblem<NortonHoff> P(x, Geometry::plane_strain, mat);
  const double tol = 1e-9;
  for (double yw : {-b, b}) {
    P.velocity(on_line({0, yw}, {0, 1}, tol), {1, 0}, 0.0, "wall x");
    P.velocity(on_line({0, yw}, {0, 1}, tol), {0, 1}, 0.0, "wall y");
  }
  for (double xe : {0.0, 2 * b}) P.velocity(on_line({xe, 0}, {1, 0}, tol), {0, 1}, 0.0, "ends");
  P.system->assembler().set_body_force(Eigen::Vector2d(G, 0));
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  const auto rep = solver.solve(*P.system, X);
  const double k = (n + 1) / n;
  auto exact = [&](const Eigen::Vector2d& p) {
    return n / (n + 1) * std::pow(G / mu0, 1 / n) * (std::pow(b, k) - std::pow(std::abs(p.y()), k));
  };
  const double e = l2_error(P, [&](int t, int q) { return interpolate(P, X, t, q, 0); }, exact);
  return {2 * b / (ny - 1), e, rep.iterations()};
}

}  // namespace

TEST_CASE("V3: power-law channel flow converges", "[verification][flow]") {
  for (double n : {1.0, 0.5}) {
    std::vector<Channel> r;
    for (int ny : {5, 9, 17, 33}) r.push_back(channel(n, ny));
    std::ostringstream os;
    os << "V3 n = " << n << ":";
    for (std::size_t i = 0; i < r.size(); ++i) {
      os << "  h " << r[i].h << " L2 " << r[i].error << " (" << r[i].iterations << " it)";
      if (i) os << " rate " << rate(r[i - 1].error, r[i].error, r[i - 1].h, r[i].h);
    }
    WARN(os.str());
    const double last = rate(r[2].error, r[3].error, r[2].h, r[3].h);
    if (n == 1.0) {
      CHECK(last >= 1.5);
      CHECK(r.back().error < 1e-2);
    } else {
      CHECK(last >= 1.0);
      CHECK(r.back().error < 3e-2);
    }
  }
}

namespace {

struct Stokes {
  double h, v_error, p_error, oscillation;
};

// V4 on the unit square, mu = 1, v = 0 on the boundary, mean pressure 0.
Stokes stokes(int n, double Cs) {
  const double pi = M_PI;
  StabilizationParams sp;
  sp.Cs = Cs;
  FlowProblem<Newtonian> P(block_nodes(n, n, 1, 1, false), Geometry::plane_strain, Newtonian{1.0}, 1.6, sp);
  auto vx = [&](const Eigen::Vector2d& x) { return std::pow(std::sin(pi * x.x()), 2) * std::sin(2 * pi * x.y()); };
  auto vy = [&](const Eigen::Vector2d& x) { return -std::sin(2 * pi * x.x()) * std::pow(std::sin(pi * x.y()), 2); };
  auto pe = [&](const Eigen::Vector2d& x) { return std::cos(pi * x.x()) * std::cos(pi * x.y()); };
  P.system->assembler().set_body_force([&](const Eigen::Vector2d& x) {
    const double X = x.x(), Y = x.y(), p2 = pi * pi;
    const double lap_x = 2 * p2 * std::cos(2 * pi * X) * std::sin(2 * pi * Y) -
                         4 * p2 * std::pow(std::sin(pi * X), 2) * std::sin(2 * pi * Y);
    const double lap_y = 4 * p2 * std::sin(2 * pi * X) * std::pow(std::sin(pi * Y), 2) -
                         2 * p2 * std::sin(2 * pi * X) * std::cos(2 * pi * Y);
    return Eigen::Vector2d(-lap_x - pi * std::sin(pi * X) * std::cos(pi * Y),
                           -lap_y - pi * std::cos(pi * X) * std::sin(pi * Y));
  });
  auto all = [](const Eigen::Vector2d&, const Eigen::Vector2d&) { return true; };
  P.velocity(all, {1, 0}, 0.0, "wall x");
  P.velocity(all, {0, 1}, 0.0, "wall y");
  P.constraints().add_pressure_mean(P.disc, 0.0);
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  solver.solve(*P.system, X);
  Stokes s;
  s.h = 1.0 / (n - 1);
  s.v_error = l2_error(P, [&](int t, int q) { return interpolate(P, X, t, q, 0); }, vx);
  const double ey = l2_error(P, [&](int t, int q) { return interpolate(P, X, t, q, 1); }, vy);
  s.v_error = std::hypot(s.v_error, ey) / std::sqrt(2.0);
  s.p_error = l2_error(P, [&](int t, int q) { return interpolate(P, X, t, q, 2); }, pe);
  // Node-to-node pressure jumps beyond the exact ones, over the mesh edges,
  // relative to the exact jumps: O(h) when smooth, O(1) or worse when it oscillates.
  double jump2 = 0, exact2 = 0;
  const auto& x = P.mesh.nodes();
  for (const auto& e : P.mesh.edges()) {
    const double dh = X[3 * e.a + 2] - X[3 * e.b + 2], de = pe(x.col(e.a)) - pe(x.col(e.b));
    jump2 += (dh - de) * (dh - de);
    exact2 += de * de;
  }
  s.oscillation = std::sqrt(jump2 / exact2);
  return s;
}

}  // namespace

TEST_CASE("V4: Stokes manufactured solution converges; stabilization removes oscillation",
          "[verification][flow]") {
  std::vector<Stokes> r;
  for (int n : {9, 17, 33}) r.push_back(stokes(n, 0.5));
  std::ostringstream os;
  os << "V4 Cs = 0.5:";
  for (std::size_t i = 0; i < r.size(); ++i) {
    os << "  h " << r[i].h << " v " << r[i].v_error << " p " << r[i].p_error << " osc " << r[i].oscillation;
    if (i)
      os << " rates v " << rate(r[i - 1].v_error, r[i].v_error, r[i - 1].h, r[i].h) << " p "
         << rate(r[i - 1].p_error, r[i].p_error, r[i - 1].h, r[i].h);
  }
  const Stokes bare = stokes(17, 0.0);
  os << "\nV4 Cs = 0, h " << bare.h << ": v " << bare.v_error << " p " << bare.p_error << " osc "
     << bare.oscillation;
  WARN(os.str());
  CHECK(rate(r[1].v_error, r[2].v_error, r[1].h, r[2].h) >= 1.5);
  CHECK(rate(r[1].p_error, r[2].p_error, r[1].h, r[2].h) >= 1.5);
  CHECK(r.back().v_error < 5e-3);
  CHECK(r.back().p_error < 0.06);
  CHECK(r[1].oscillation < 0.5);
  CHECK(bare.oscillation > 100 * r[1].oscillation);
}

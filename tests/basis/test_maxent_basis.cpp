// MaxEntBasis: dimensions 1 and 3, hull handling, parallel determinism, and every
// bad input raising maxentflow::Error with what and where.
#include <catch2/catch.hpp>

#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/core/parallel.hpp>

#include "../support/clouds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

using maxentflow::Error;
using maxentflow::MaxEntBasis;
using maxentflow::test::grid_cloud;
using Catch::Matchers::Contains;

TEST_CASE("1-D basis: consistency inside, Kronecker delta at the ends", "[basis]") {
  const int n = 11;
  Eigen::Matrix<double, 1, Eigen::Dynamic> nodes(1, n);
  for (int a = 0; a < n; ++a) nodes(0, a) = a * 0.1 + (a % 2 ? 0.02 : 0.0) * (a < n - 1);
  const MaxEntBasis<1> basis(nodes, Eigen::VectorXd::Constant(n, 0.1));
  Eigen::Matrix<double, 1, Eigen::Dynamic> x(1, 101);
  for (int i = 0; i <= 100; ++i) x(0, i) = i / 100.0;
  const auto t = basis.evaluate(x);
  for (int i = 0; i < t.size(); ++i) {
    double s = 0, l = 0, gs = 0, gl = 0;
    for (std::size_t j = 0; j < t.nodes(i).size(); ++j) {
      const double xa = nodes(0, t.nodes(i)[j]);
      s += t.values(i)[j];
      l += t.values(i)[j] * xa;
      gs += t.gradients(i)(0, static_cast<Eigen::Index>(j));
      gl += t.gradients(i)(0, static_cast<Eigen::Index>(j)) * xa;
    }
    CHECK(std::abs(s - 1) <= 1e-13);
    CHECK(std::abs(l - x(0, i)) <= 1e-13);
    CHECK(std::abs(gs) <= 1e-9);
    CHECK(std::abs(gl - 1) <= 1e-10);
  }
  CHECK(t.on_hull.front() == 1);
  CHECK(t.on_hull.back() == 1);
  // At the end node the basis is its Kronecker delta (other entries exactly 0).
  const auto e0 = basis.evaluate(Eigen::Matrix<double, 1, 1>(0.0), false);
  for (std::size_t j = 0; j < e0.node.size(); ++j) CHECK(e0.p[j] == (e0.node[j] == 0 ? 1.0 : 0.0));
}

TEST_CASE("3-D basis: interior consistency; faces, edges and corners restrict", "[basis]") {
  const int n = 5;
  Eigen::Matrix3Xd nodes(3, n * n * n);
  int a = 0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) nodes.col(a++) << i / 4.0, j / 4.0, k / 4.0;
  const MaxEntBasis<3> basis(nodes, Eigen::VectorXd::Constant(nodes.cols(), 0.25));
  auto check = [&](const Eigen::Vector3d& x, bool on_hull) {
    const auto e = basis.evaluate(x);
    CHECK(e.on_hull == on_hull);
    double s = 0;
    Eigen::Vector3d l = Eigen::Vector3d::Zero(), gs = Eigen::Vector3d::Zero();
    Eigen::Matrix3d gl = Eigen::Matrix3d::Zero();
    for (std::size_t j = 0; j < e.node.size(); ++j) {
      const Eigen::Vector3d xa = nodes.col(e.node[j]);
      CHECK(e.p[j] >= 0);
      s += e.p[j];
      l += e.p[j] * xa;
      gs += e.gradients().col(static_cast<Eigen::Index>(j));
      gl += e.gradients().col(static_cast<Eigen::Index>(j)) * xa.transpose();
      // On a face, edge or corner, only nodes on it carry weight.
      for (int k = 0; k < 3; ++k)
        if (x(k) == 0.0 || x(k) == 1.0)
          if (xa(k) != x(k)) CHECK(e.p[j] == 0.0);
    }
    CHECK(std::abs(s - 1) <= 1e-12);
    CHECK((l - x).norm() <= 1e-12 * 0.25);
    CHECK(gs.norm() * 0.25 <= 1e-10);
    CHECK((gl - Eigen::Matrix3d::Identity()).norm() <= 1e-8);
  };
  check(Eigen::Vector3d(0.31, 0.52, 0.47), false);
  check(Eigen::Vector3d(0.013, 0.77, 0.5), false);
  check(Eigen::Vector3d(0.3, 0.6, 0.0), true);    // face z = 0
  check(Eigen::Vector3d(1.0, 0.45, 0.72), true);  // face x = 1
  check(Eigen::Vector3d(0.37, 0.0, 1.0), true);   // edge y = 0, z = 1
  const auto corner = basis.evaluate(Eigen::Vector3d(1, 1, 0), false);
  const int corner_node = 4 + 5 * 4;  // (1, 1, 0)
  for (std::size_t j = 0; j < corner.node.size(); ++j)
    CHECK(corner.p[j] == (corner.node[j] == corner_node ? 1.0 : 0.0));
}

TEST_CASE("A side straight over the support but concave at large: the support's hull facet", "[basis][hull]") {
  // An 11 x 11 grid (h = 1) whose right side x = 10 - amp (y/10)^2 bends in
  // (convex over each support) below y = 8 and bulges out to 10 + amp above:
  // the cloud's hull there is one facet from (10, 0) to (10 + amp, 8), a few
  // amp inside of the points on the side's segments, which lie on the hull of
  // their own support, where the dual has no minimizer. (A workpiece side as a
  // cutting tool approaches; amp from 2e-6 to 2e-5 failed before.)
  const double amp = GENERATE(2e-6, 1e-5, 2e-5);
  const int n = 11;
  Eigen::Matrix2Xd nodes(2, n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double bend = j >= 8 ? amp : -amp * (j / 10.0) * (j / 10.0);
      nodes.col(j * n + i) << i + (i == n - 1 ? bend : 0.0), j;
    }
  const MaxEntBasis<2> basis(nodes, Eigen::VectorXd::Ones(n * n));
  for (int j = 0; j < 5; ++j)
    for (double t : {0.1, 0.5, 0.9}) {
      const Eigen::Vector2d a = nodes.col(j * n + n - 1), b = nodes.col((j + 1) * n + n - 1);
      const Eigen::Vector2d x = a + t * (b - a);
      INFO("amp " << amp << ", point (" << x.transpose() << ")");
      const auto e = basis.evaluate(x);
      double sum = 0;
      Eigen::Vector2d lin = Eigen::Vector2d::Zero(), gsum = Eigen::Vector2d::Zero();
      for (std::size_t k = 0; k < e.node.size(); ++k) {
        sum += e.p[k];
        lin += e.p[k] * nodes.col(e.node[k]);
        gsum += e.gradients().col(static_cast<Eigen::Index>(k));
        // The side's nodes carry the weight (weak Kronecker-delta property, to
        // the distance from the support's hull where the dual is solvable).
        if (e.node[k] % n != n - 1) CHECK(e.p[k] <= 10 * amp);
      }
      CHECK(std::abs(sum - 1.0) <= 1e-12);
      CHECK((lin - x).norm() <= 3e-6);  // the accuracy stated on a hull facet
      CHECK(gsum.allFinite());
      CHECK(gsum.norm() <= 1e-5);  // one-sided limit from just inside (solve_on_hull)
    }
}

TEST_CASE("Batch evaluation: thread count and blocks do not change results", "[basis]") {
  const auto cloud = grid_cloud("perturbed", 30);
  const MaxEntBasis<2> basis(cloud.nodes, cloud.h);
  const Eigen::Matrix2Xd x = maxentflow::test::random_points(5000, 0, 1);
  const int threads = maxentflow::max_threads();
  maxentflow::set_threads(1);
  const auto serial = basis.evaluate(x);
  maxentflow::set_threads(std::max(2, threads));
  const auto parallel = basis.evaluate(x);
  maxentflow::set_threads(threads);
  CHECK(serial.offset == parallel.offset);
  CHECK(serial.node == parallel.node);
  CHECK(serial.p == parallel.p);  // bitwise
  CHECK(serial.grad == parallel.grad);
  // Single-point evaluation (no warm start) agrees to the solver tolerance.
  double worst = 0;
  for (int i = 0; i < 200; ++i) {
    const auto e = basis.evaluate(Eigen::Vector2d(x.col(i)));
    REQUIRE(e.node.size() == serial.nodes(i).size());
    for (std::size_t j = 0; j < e.node.size(); ++j) worst = std::max(worst, std::abs(e.p[j] - serial.values(i)[j]));
  }
  CHECK(worst <= 1e-11);
  CHECK(serial.mean_iterations() > 0);
  CHECK(serial.max_iterations() <= 20);
}

TEST_CASE("Support cut-off: only nodes within h sqrt(-ln tol0 / gamma)", "[basis]") {
  const auto cloud = grid_cloud("regular", 21);
  MaxEntBasis<2>::params prm;
  prm.gamma = 1.6;
  prm.tol0 = 1e-4;
  const MaxEntBasis<2> basis(cloud.nodes, cloud.h, prm);
  const Eigen::Vector2d x(0.513, 0.487);
  const auto e = basis.evaluate(x, false);
  const double R = cloud.h0 * std::sqrt(-std::log(1e-4) / 1.6);
  int inside = 0;
  for (Eigen::Index a = 0; a < cloud.nodes.cols(); ++a)
    if ((cloud.nodes.col(a) - x).norm() <= R) ++inside;
  CHECK(static_cast<int>(e.node.size()) == inside);
  for (int a : e.node) CHECK((cloud.nodes.col(a) - x).norm() <= R);
}

TEST_CASE("Support search: every point's support is exactly the nodes whose radius reaches it",
          "[basis]") {
  // Graded spacing (1:5) and per-node gamma: radii vary by ~8x, so the grid's
  // cells (half the median radius) see nodes registered from many cells away.
  const auto cloud = maxentflow::test::grid_cloud("graded", 25);
  Eigen::VectorXd gamma(cloud.nodes.cols());
  for (Eigen::Index a = 0; a < gamma.size(); ++a) gamma(a) = 0.8 + 1.6 * cloud.nodes(0, a);
  const MaxEntBasis<2> basis(cloud.nodes, cloud.h, gamma);
  const Eigen::Matrix2Xd x = maxentflow::test::random_points(3000, 0.0, 1.0, 5);
  const auto t = basis.evaluate(x, false);
  int mismatches = 0;
  for (int i = 0; i < x.cols(); ++i) {
    std::vector<int> expected;
    for (Eigen::Index a = 0; a < cloud.nodes.cols(); ++a)
      if ((cloud.nodes.col(a) - x.col(i)).norm() <= basis.support_radius()(a)) expected.push_back(static_cast<int>(a));
    const auto got = t.nodes(i);
    if (!std::equal(got.begin(), got.end(), expected.begin(), expected.end())) ++mismatches;
  }
  CHECK(mismatches == 0);
}

TEST_CASE("The dual's vectorized exp is exp to within 2 ulp", "[basis]") {
  double worst = 0;
  for (double x = -708.0; x <= 709.0; x += 0.0173) {
    const double e = std::exp(x);
    worst = std::max(worst, std::abs(maxentflow::detail::exp_kernel(x) - e) / e);
  }
  for (double x = -1e-3; x <= 1e-3; x += 1.7e-7) {  // near 0: the small arguments of Newton's last steps
    const double e = std::exp(x);
    worst = std::max(worst, std::abs(maxentflow::detail::exp_kernel(x) - e) / e);
  }
  CHECK(worst <= 2 * std::numeric_limits<double>::epsilon());
  CHECK(std::isnan(maxentflow::detail::exp_kernel(std::numeric_limits<double>::quiet_NaN())));
}

TEST_CASE("The dual solve's small-step weight updates give the weights of a fresh evaluation", "[basis]") {
  // Newton's last steps update the weights by a Taylor polynomial of
  // exp(step . (x - x_a)); the p they leave must be those of Eq. (5) at the
  // final lambda, evaluated from scratch.
  const auto cloud = grid_cloud("perturbed", 15);
  const double gamma = 1.6, R = cloud.h0 * std::sqrt(-std::log(1e-6) / gamma);
  const Eigen::Matrix2Xd x = maxentflow::test::random_points(200, 0.2, 0.8, 9);
  double worst_p = 0, worst_r = 0;
  int iterations = 0;
  for (int i = 0; i < x.cols(); ++i) {
    maxentflow::detail::DualWorkspace<2> ws;
    ws.reserve(cloud.nodes.cols());
    int m = 0;
    for (Eigen::Index a = 0; a < cloud.nodes.cols(); ++a) {
      const Eigen::Vector2d d = x.col(i) - cloud.nodes.col(a);
      if (d.norm() > R) continue;
      const double beta = gamma / (cloud.h0 * cloud.h0);
      ws.dx[0](m) = d(0);
      ws.dx[1](m) = d(1);
      ws.beta(m) = beta;
      ws.q(m) = -beta * d.squaredNorm();
      ++m;
    }
    const auto res = maxentflow::detail::solve_dual<2>(ws, m, Eigen::Vector2d::Zero(), 1e-13 * cloud.h0, 100);
    REQUIRE(res.status == maxentflow::detail::DualStatus::converged);
    iterations += res.iterations;
    const Eigen::ArrayXd p = ws.p.head(m);
    Eigen::Vector2d r;
    Eigen::Matrix2d J;
    maxentflow::detail::evaluate_dual<2>(ws, m, res.lambda, r, J);  // from scratch
    const Eigen::ArrayXd fresh = ws.p.head(m) / ws.Z;
    worst_p = std::max(worst_p, ((p - fresh).abs() / fresh.maxCoeff()).maxCoeff());
    worst_r = std::max(worst_r, (r - res.r).norm() / cloud.h0);
  }
  CHECK(iterations >= 3 * x.cols());  // the small-step updates did run
  CHECK(worst_p <= 1e-14);
  CHECK(worst_r <= 1e-14);
}

TEST_CASE("Bad input raises maxentflow::Error with what and where", "[basis][errors]") {
  const auto cloud = grid_cloud("regular", 6);
  SECTION("no NaN gradients: a point on a node whose neighbours' weights underflow (fuzz_basis)") {
    Eigen::Matrix2Xd x(2, 8);
    x << 4, 0.17254901960789998, 0.17254901960784313, 0.17254901960784313, 3, 0.050962116069246541,
        0.99999999999964473, 0.0234375,  //
        2, 0.17254901960784313, 0.17254902775691566, 0.31433671631672544, 3, 0.09591444132272349, 1, 1;
    MaxEntBasis<2>::params prm;
    prm.gamma = 16.211764705882352;
    const MaxEntBasis<2> basis(x, prm);
    try {
      const auto v = basis.evaluate(Eigen::Vector2d(1, 1), true);
      for (double g : v.grad) CHECK(std::isfinite(g));
    } catch (const Error& e) {
      CHECK_THAT(std::string(e.what()), Contains("not finite"));
    }
  }
  SECTION("gamma <= 0") {
    MaxEntBasis<2>::params prm;
    prm.gamma = 0;
    CHECK_THROWS_WITH(MaxEntBasis<2>(cloud.nodes, cloud.h, prm), Contains("gamma must be positive"));
    Eigen::VectorXd g = Eigen::VectorXd::Constant(cloud.h.size(), 1.6);
    g(7) = -1;
    CHECK_THROWS_WITH(MaxEntBasis<2>(cloud.nodes, cloud.h, g), Contains("node 7"));
  }
  SECTION("h <= 0") {
    Eigen::VectorXd h = cloud.h;
    h(4) = 0;
    CHECK_THROWS_WITH(MaxEntBasis<2>(cloud.nodes, h), Contains("h must be positive") && Contains("node 4"));
  }
  SECTION("coincident nodes") {
    Eigen::Matrix2Xd nodes = cloud.nodes;
    nodes.col(20) = nodes.col(13);
    CHECK_THROWS_WITH(MaxEntBasis<2>(nodes, cloud.h), Contains("coincident nodes 13 and 20"));
  }
  SECTION("NaN coordinates") {
    Eigen::Matrix2Xd nodes = cloud.nodes;
    nodes(1, 9) = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH(MaxEntBasis<2>(nodes, cloud.h), Contains("NaN") && Contains("node 9"));
    const MaxEntBasis<2> basis(cloud.nodes, cloud.h);
    CHECK_THROWS_WITH(basis.evaluate(Eigen::Vector2d(0.5, std::nan(""))), Contains("NaN"));
  }
  SECTION("collinear nodes") {
    Eigen::Matrix2Xd nodes(2, 5);
    nodes << 0, 1, 2, 3, 4, 0, 1, 2, 3, 4;
    CHECK_THROWS_WITH(MaxEntBasis<2>(nodes, Eigen::VectorXd::Ones(5)), Contains("span"));
  }
  SECTION("point outside the hull") {
    const MaxEntBasis<2> basis(cloud.nodes, cloud.h);
    CHECK_THROWS_WITH(basis.evaluate(Eigen::Vector2d(1.2, 0.5)), Contains("outside the convex hull"));
    CHECK_THROWS_WITH(basis.evaluate(Eigen::Vector2d(0.5, -1e-6)), Contains("outside the convex hull"));
    Eigen::Matrix2Xd x(2, 3);
    x << 0.5, 0.2, 1.5, 0.5, 0.2, 0.5;
    CHECK_THROWS_WITH(basis.evaluate(x), Contains("point 2"));
  }
  SECTION("too few neighbours") {
    // A square grid and one far node: the hull is large but a point far from the
    // grid sees no node within its support.
    Eigen::Matrix2Xd nodes(2, cloud.nodes.cols() + 1);
    nodes << cloud.nodes, Eigen::Vector2d(3.0, 3.0);
    Eigen::VectorXd h(nodes.cols());
    h << cloud.h, 0.2;
    const MaxEntBasis<2> basis(nodes, h);
    CHECK_THROWS_WITH(basis.evaluate(Eigen::Vector2d(2.0, 2.0)), Contains("support") && Contains("point"));
  }
  SECTION("point outside the hull of its neighbours: the dual solve fails") {
    Eigen::Matrix2Xd nodes(2, cloud.nodes.cols() + 1);
    nodes << cloud.nodes, Eigen::Vector2d(3.0, 3.0);
    Eigen::VectorXd h(nodes.cols());
    h << cloud.h, 0.2;
    MaxEntBasis<2>::params prm;
    prm.max_iterations = 30;
    const MaxEntBasis<2> basis(nodes, h, prm);
    // Just beyond the grid's corner: inside the global hull, outside the hull of
    // its support (grid nodes only), so ln Z has no minimizer.
    CHECK_THROWS_WITH(basis.evaluate(Eigen::Vector2d(1.05, 1.04)),
                      Contains("dual solve failed") && Contains("iterations") && Contains("|r|"));
  }
}

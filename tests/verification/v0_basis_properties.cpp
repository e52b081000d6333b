// V0 (docs/cases.md): max-ent basis properties on regular, perturbed and
// graded clouds, gamma in {0.8, 1.6, 4.0}, deep inside and within 1e-6 h of the
// boundary; weak Kronecker-delta on hull edges; Sukumar's published 1-D values.
#include <catch2/catch.hpp>

#include <maxentflow/basis/maxent_basis.hpp>

#include "../support/clouds.hpp"

#include <cmath>

using maxentflow::MaxEntBasis;
using maxentflow::test::grid_cloud;

namespace {

struct Worst {
  double negative = 0, unity = 0, linear = 0, grad_sum = 0, grad_linear = 0;
};

// Checks every point of a table; errors relative to h (linear) and 1/h (gradients).
Worst check_table(const MaxEntBasis<2>& basis, const Eigen::Matrix2Xd& x,
                  const maxentflow::BasisTable<2>& t, double h) {
  Worst w;
  for (int i = 0; i < t.size(); ++i) {
    const auto nodes = t.nodes(i);
    const auto p = t.values(i);
    const auto g = t.gradients(i);
    double sum = 0;
    Eigen::Vector2d lin = Eigen::Vector2d::Zero(), gs = Eigen::Vector2d::Zero();
    Eigen::Matrix2d gl = Eigen::Matrix2d::Zero();
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      const Eigen::Vector2d xa = basis.nodes().col(nodes[j]);
      w.negative = std::min(w.negative, p[j]);
      sum += p[j];
      lin += p[j] * xa;
      gs += g.col(static_cast<Eigen::Index>(j));
      gl += g.col(static_cast<Eigen::Index>(j)) * xa.transpose();
    }
    w.unity = std::max(w.unity, std::abs(sum - 1));
    w.linear = std::max(w.linear, (lin - x.col(i)).norm() / h);
    w.grad_sum = std::max(w.grad_sum, gs.norm() * h);
    w.grad_linear = std::max(w.grad_linear, (gl - Eigen::Matrix2d::Identity()).norm());
  }
  return w;
}

}  // namespace

TEST_CASE("V0: positivity, partition of unity, linear and gradient consistency", "[verification][V0]") {
  const auto kind = GENERATE(as<std::string>{}, "regular", "perturbed", "graded");
  const double gamma = GENERATE(0.8, 1.6, 4.0);
  const auto cloud = grid_cloud(kind, 13);
  MaxEntBasis<2>::params prm;
  prm.gamma = gamma;
  const MaxEntBasis<2> basis(cloud.nodes, cloud.h, prm);
  const double hmin = cloud.h.minCoeff();

  Eigen::Matrix2Xd deep = maxentflow::test::random_points(300, 0.0, 1.0);
  Eigen::Matrix2Xd edge = maxentflow::test::near_boundary_points(25, 1e-6 * hmin);
  for (const Eigen::Matrix2Xd* x : {&deep, &edge}) {
    INFO(kind << " gamma=" << gamma << (x == &edge ? " near boundary" : " interior"));
    const auto t = basis.evaluate(*x);
    const Worst w = check_table(basis, *x, t, hmin);
    CHECK(w.negative >= 0.0);
    CHECK(w.unity <= 1e-12);
    CHECK(w.linear * 1e12 <= 1.0);
    CHECK(w.grad_sum <= 1e-10);
    CHECK(w.grad_linear <= 1e-10);
  }
}

TEST_CASE("V0: gradients match central finite differences", "[verification][V0]") {
  const auto kind = GENERATE(as<std::string>{}, "regular", "perturbed", "graded");
  const double gamma = GENERATE(0.8, 1.6, 4.0);
  const auto cloud = grid_cloud(kind, 11);
  MaxEntBasis<2>::params prm;
  prm.gamma = gamma;
  prm.newton_tol = 1e-14;  // finite differences of values need a little more
  const MaxEntBasis<2> basis(cloud.nodes, cloud.h, prm);
  const Eigen::Matrix2Xd x = maxentflow::test::random_points(40, 0.15, 0.85, 21);
  double worst = 0;
  for (Eigen::Index i = 0; i < x.cols(); ++i) {
    const auto e = basis.evaluate(Eigen::Vector2d(x.col(i)));
    const double d = 1e-5 * cloud.h.minCoeff();
    double gmax = 0;
    for (std::size_t j = 0; j < e.node.size(); ++j) gmax = std::max(gmax, e.gradients().col(j).norm());
    for (int k = 0; k < 2; ++k) {
      Eigen::Vector2d xp = x.col(i), xm = x.col(i);
      xp(k) += d;
      xm(k) -= d;
      // Same support on both sides, so the cut-off cannot jump between them.
      const auto ep = basis.evaluate_on(xp, e.node, false);
      const auto em = basis.evaluate_on(xm, e.node, false);
      for (std::size_t j = 0; j < e.node.size(); ++j) {
        const double fd = (ep.p[j] - em.p[j]) / (2 * d);
        worst = std::max(worst, std::abs(fd - e.gradients()(k, static_cast<Eigen::Index>(j))) / gmax);
      }
    }
  }
  INFO(kind << " gamma=" << gamma << " worst relative FD error " << worst);
  CHECK(worst <= 1e-6);
}

TEST_CASE("V0: weak Kronecker-delta on convex hull edges", "[verification][V0]") {
  const auto kind = GENERATE(as<std::string>{}, "regular", "perturbed", "graded");
  const double gamma = GENERATE(0.8, 1.6, 4.0);
  const auto cloud = grid_cloud(kind, 9);
  MaxEntBasis<2>::params prm;
  prm.gamma = gamma;
  const MaxEntBasis<2> basis(cloud.nodes, cloud.h, prm);
  // Points exactly on the four sides (and the corners).
  Eigen::Matrix2Xd x(2, 4 * 7 + 4);
  int c = 0;
  for (int k = 1; k <= 7; ++k) {
    const double s = k / 8.0 + 0.013;
    x.col(c++) << s, 0.0;
    x.col(c++) << 1.0, s;
    x.col(c++) << s, 1.0;
    x.col(c++) << 0.0, s;
  }
  x.col(c++) << 0, 0;
  x.col(c++) << 1, 0;
  x.col(c++) << 1, 1;
  x.col(c++) << 0, 1;
  const auto t = basis.evaluate(x);
  double off_edge = 0, linear = 0, unity = 0;
  for (int i = 0; i < t.size(); ++i) {
    const Eigen::Vector2d xi = x.col(i);
    CHECK(t.on_hull[static_cast<std::size_t>(i)] == 1);
    double sum = 0;
    Eigen::Vector2d lin = Eigen::Vector2d::Zero();
    for (std::size_t j = 0; j < t.nodes(i).size(); ++j) {
      const Eigen::Vector2d xa = basis.nodes().col(t.nodes(i)[j]);
      const double p = t.values(i)[j];
      sum += p;
      lin += p * xa;
      // A node off every side the point lies on has a zero function there.
      const bool point_on_x0 = xi(0) == 0, point_on_x1 = xi(0) == 1;
      const bool point_on_y0 = xi(1) == 0, point_on_y1 = xi(1) == 1;
      const bool shares = (point_on_x0 && xa(0) == 0) || (point_on_x1 && xa(0) == 1) ||
                          (point_on_y0 && xa(1) == 0) || (point_on_y1 && xa(1) == 1);
      if (!shares) off_edge = std::max(off_edge, p);
    }
    unity = std::max(unity, std::abs(sum - 1));
    linear = std::max(linear, (lin - xi).norm() / cloud.h0);
  }
  CHECK(off_edge < 1e-10);
  CHECK(unity <= 1e-12);
  CHECK(linear <= 1e-12);
  // At a corner the basis is the Kronecker delta of the corner node.
  const auto corner = basis.evaluate(Eigen::Vector2d(1, 1), false);
  const int corner_node = 9 * 9 - 1;  // (1, 1)
  for (std::size_t j = 0; j < corner.node.size(); ++j)
    CHECK(corner.p[j] == (corner.node[j] == corner_node ? 1.0 : 0.0));
}

TEST_CASE("V0: uniform prior reproduces Sukumar's published 1-D values", "[verification][V0]") {
  Eigen::Matrix<double, 1, Eigen::Dynamic> nodes(1, 3);
  nodes << 0.0, 0.5, 1.0;
  const auto basis = MaxEntBasis<1>::from_beta(nodes, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(0.5));
  const auto e = basis.evaluate(Eigen::Matrix<double, 1, 1>(0.3), false);
  REQUIRE(e.node.size() == 3);
  CHECK(e.p[0] == Approx(0.55397228268).epsilon(1e-10));
  CHECK(e.p[1] == Approx(0.29205543464).epsilon(1e-10));
  CHECK(e.p[2] == Approx(0.15397228268).epsilon(1e-10));
}

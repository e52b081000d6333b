// Nodal spacing h_a: natural-neighbour mean (paper, after Eq. (14)).
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <maxentflow/mesh/integration_mesh.hpp>
#include <maxentflow/mesh/nodal_spacing.hpp>
#include <maxentflow/mesh/nodal_spacing_3.hpp>

using maxentflow::Error;

namespace {

// nx x ny grid with spacings hx, hy; node (i, j) has index j * nx + i.
Eigen::Matrix2Xd grid(int nx, int ny, double hx, double hy) {
  Eigen::Matrix2Xd x(2, nx * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) x.col(j * nx + i) << i * hx, j * hy;
  return x;
}

// Each grid square split by one diagonal; `alternate` flips it in a checkerboard.
std::vector<std::array<int, 3>> grid_triangles(int nx, int ny, bool alternate) {
  std::vector<std::array<int, 3>> t;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int a = j * nx + i, b = a + 1, c = a + nx + 1, d = a + nx;
      if (alternate && (i + j) % 2) {
        t.push_back({a, b, d});
        t.push_back({b, c, d});
      } else {
        t.push_back({a, b, c});
        t.push_back({a, c, d});
      }
    }
  return t;
}

bool interior(int a, int nx, int ny) {
  const int i = a % nx, j = a / nx;
  return i > 0 && j > 0 && i + 1 < nx && j + 1 < ny;
}

}  // namespace

TEST_CASE("nodal_spacing is the grid spacing on a square grid, at every node", "[mesh]") {
  const double h = 0.1;
  for (bool alternate : {false, true}) {
    const auto x = grid(9, 7, h, h);
    const Eigen::VectorXd ha = maxentflow::nodal_spacing(x, grid_triangles(9, 7, alternate));
    REQUIRE(ha.size() == 63);
    // The diagonals are zero-length Voronoi edges and do not count.
    CHECK((ha.array() / h - 1.0).abs().maxCoeff() < 1e-14);
  }
}

TEST_CASE("nodal_spacing on a rectangular grid hx != hy", "[mesh]") {
  const double hx = 0.1, hy = 0.25;
  const int nx = 8, ny = 6;
  const Eigen::VectorXd ha =
      maxentflow::nodal_spacing(grid(nx, ny, hx, hy), grid_triangles(nx, ny, true));
  for (int a = 0; a < nx * ny; ++a) {
    CAPTURE(a);
    const int i = a % nx, j = a / nx;
    const bool side_x = i == 0 || i + 1 == nx, side_y = j == 0 || j + 1 == ny;
    double expected = 0.5 * (hx + hy);                    // interior: 2 hx + 2 hy
    if (side_x && !side_y) expected = (hx + 2 * hy) / 3;  // on a vertical side
    if (side_y && !side_x) expected = (2 * hx + hy) / 3;  // on a horizontal side
    CHECK(std::abs(ha[a] / expected - 1.0) < 1e-14);
  }
}

TEST_CASE("nodal_spacing counts a diagonal unless the quad is cocircular", "[mesh]") {
  // Unit square, two triangles: shared circumcentre, diagonal excluded.
  Eigen::Matrix2Xd sq(2, 4);
  sq << 0, 1, 1, 0, 0, 0, 1, 1;
  const Eigen::VectorXd hs = maxentflow::nodal_spacing(sq, {{0, 1, 2}, {0, 2, 3}});
  CHECK((hs.array() - 1.0).abs().maxCoeff() < 1e-15);
  // A kite (not cocircular): the diagonal 0-2 is a natural-neighbour edge.
  Eigen::Matrix2Xd kite(2, 4);
  kite << 0, 1, 2, 1, 0, -0.5, 0, 0.8;
  const Eigen::VectorXd hk = maxentflow::nodal_spacing(kite, {{0, 1, 2}, {0, 2, 3}});
  const double l01 = std::hypot(1.0, 0.5), l03 = std::hypot(1.0, 0.8);
  CHECK(hk[0] == Approx((l01 + l03 + 2.0) / 3.0).epsilon(1e-15));
  CHECK(hk[1] == Approx(l01).epsilon(1e-15));
  // Boundary edges always count: one triangle, each node the mean of its 2 edges.
  Eigen::Matrix2Xd tri(2, 3);
  tri << 0, 3, 0, 0, 0, 4;
  const Eigen::VectorXd ht = maxentflow::nodal_spacing(tri, {{0, 1, 2}});
  CHECK(ht[0] == Approx(3.5).epsilon(1e-15));
  CHECK(ht[1] == Approx(4.0).epsilon(1e-15));
  CHECK(ht[2] == Approx(4.5).epsilon(1e-15));
}

TEST_CASE("nodal_spacing rejects nodes in no triangle and bad triangles", "[mesh]") {
  auto x = grid(3, 3, 1.0, 1.0);
  auto t = grid_triangles(3, 3, false);
  t.erase(t.begin() + 7);  // triangle {4, 8, 7}
  t.erase(t.begin() + 6);  // triangle {4, 5, 8}: node 8 is now in no triangle
  try {
    maxentflow::nodal_spacing(x, t);
    FAIL("no throw");
  } catch (const Error& e) {
    CHECK(e.description().find("1 node(s) in no triangle: 8") != std::string::npos);
    CHECK(e.where().find("8") != std::string::npos);
  }
  CHECK_THROWS_AS(maxentflow::nodal_spacing(x, {{0, 1, 9}}), Error);
  CHECK_THROWS_AS(maxentflow::nodal_spacing(x, {{0, 1, 1}}), Error);
  // Three triangles on one edge is no triangulation.
  CHECK_THROWS_WITH(maxentflow::nodal_spacing(x, {{0, 1, 3}, {1, 0, 4}, {0, 1, 5}}),
                    Catch::Contains("shared by 3 triangles"));
  x(1, 4) = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(maxentflow::nodal_spacing(x, grid_triangles(3, 3, false)),
                    Catch::Contains("node 4"));
}

TEST_CASE("delaunay_spacing<1>: neighbours in sorted order", "[mesh]") {
  Eigen::Matrix<double, 1, Eigen::Dynamic> x(1, 5);
  x << 0.4, 0.0, 0.1, 1.0, 0.2;  // unsorted on purpose
  const Eigen::VectorXd h = maxentflow::delaunay_spacing<1>(x);
  CHECK(h[1] == Approx(0.1));
  CHECK(h[2] == Approx(0.1));
  CHECK(h[4] == Approx(0.15));
  CHECK(h[0] == Approx(0.4));
  CHECK(h[3] == Approx(0.6));
  Eigen::Matrix<double, 1, Eigen::Dynamic> u(1, 11);
  for (int i = 0; i < 11; ++i) u[i] = 0.25 * i;
  CHECK((maxentflow::delaunay_spacing<1>(u).array() / 0.25 - 1.0).abs().maxCoeff() < 1e-14);
  x[4] = 0.1;
  CHECK_THROWS_WITH(maxentflow::delaunay_spacing<1>(x),
                    Catch::Contains("coincident nodes 2 and 4"));
  CHECK_THROWS_AS(maxentflow::delaunay_spacing<1>(Eigen::Matrix<double, 1, Eigen::Dynamic>(1, 1)),
                  Error);
}

TEST_CASE("delaunay_spacing<2> is the grid spacing on regular grids", "[mesh]") {
  // Every square of the grid is cocircular: CGAL's choice of diagonal must not matter.
  const double h = 0.05;
  const Eigen::VectorXd ha = maxentflow::delaunay_spacing<2>(grid(15, 12, h, h));
  CHECK((ha.array() / h - 1.0).abs().maxCoeff() < 1e-14);
  const double hx = 0.05, hy = 0.08;
  const Eigen::VectorXd hr = maxentflow::delaunay_spacing<2>(grid(10, 10, hx, hy));
  for (int a = 0; a < 100; ++a)
    if (interior(a, 10, 10)) CHECK(std::abs(hr[a] / (0.5 * (hx + hy)) - 1.0) < 1e-14);
}

TEST_CASE("delaunay_spacing<2> on a perturbed cloud is the natural-neighbour mean", "[mesh]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  Eigen::Matrix2Xd x = grid(12, 12, 1.0, 1.0);
  for (Eigen::Index a = 0; a < x.cols(); ++a) x.col(a) += Eigen::Vector2d(u(rng), u(rng));
  const Eigen::VectorXd h = maxentflow::delaunay_spacing<2>(x);
  // No cocircular quads here: every Delaunay edge counts; bounded by the nearest
  // and farthest node distances, and close to 1 in the interior.
  for (Eigen::Index a = 0; a < x.cols(); ++a) {
    double dmin = 1e300;
    for (Eigen::Index b = 0; b < x.cols(); ++b)
      if (b != a) dmin = std::min(dmin, (x.col(b) - x.col(a)).norm());
    CHECK(h[a] >= dmin);
    // (On the hull, long edges of the convex hull count: no alpha cut here.)
    if (interior(static_cast<int>(a), 12, 12)) CHECK(std::abs(h[a] - 1.1) < 0.35);
  }
}

TEST_CASE("delaunay_spacing<2> bad input", "[mesh]") {
  Eigen::Matrix2Xd x = grid(4, 4, 1.0, 1.0);
  x.col(7) = x.col(3);
  CHECK_THROWS_WITH(maxentflow::delaunay_spacing<2>(x),
                    Catch::Contains("coincident nodes 3 and 7"));
  Eigen::Matrix2Xd line(2, 5);
  line << 0, 1, 2, 3, 4, 0, 2, 4, 6, 8;
  CHECK_THROWS_WITH(maxentflow::delaunay_spacing<2>(line), Catch::Contains("collinear"));
}

TEST_CASE("delaunay_spacing<3> is the grid spacing on a regular cubic grid", "[mesh]") {
  const double h = 0.2;
  const int n = 5;
  Eigen::Matrix3Xd x(3, n * n * n);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) x.col((k * n + j) * n + i) << i * h, j * h, k * h;
  const Eigen::VectorXd ha = maxentflow::delaunay_spacing<3>(x);
  // Face and body diagonals have zero-area Voronoi facets, inside and on the
  // hull (coplanar hull facets): only the 6 axis neighbours count.
  CHECK((ha.array() / h - 1.0).abs().maxCoeff() < 1e-14);

  Eigen::Matrix3Xd y = x;
  y.col(30) = y.col(12);
  CHECK_THROWS_WITH(maxentflow::delaunay_spacing<3>(y),
                    Catch::Contains("coincident nodes 12 and 30"));
  Eigen::Matrix3Xd flat = x;
  flat.row(2).setZero();
  flat.conservativeResize(3, 25);  // the k = 0 layer only: coplanar
  CHECK_THROWS_WITH(maxentflow::delaunay_spacing<3>(flat), Catch::Contains("coplanar"));
}

TEST_CASE("IntegrationMesh::h is nodal_spacing on the kept triangles", "[mesh]") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  Eigen::Matrix2Xd x = grid(15, 10, 1.0, 1.0);
  for (Eigen::Index a = 0; a < x.cols(); ++a)
    if (interior(static_cast<int>(a), 15, 10)) x.col(a) += Eigen::Vector2d(u(rng), u(rng));
  const maxentflow::IntegrationMesh<> m(x);
  const Eigen::VectorXd h = maxentflow::nodal_spacing(m.nodes(), m.triangles());
  CHECK((h - m.h()).cwiseAbs().maxCoeff() < 1e-14);
}

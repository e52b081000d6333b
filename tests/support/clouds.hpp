// Node clouds for the tests: regular, perturbed and graded grids on a box, with
// their nodal spacing, and random points inside.
#pragma once

#include <Eigen/Core>

#include <cmath>
#include <random>
#include <string>

namespace maxentflow::test {

struct Cloud2 {
  std::string name;
  Eigen::Matrix2Xd nodes;
  Eigen::VectorXd h;  // mean distance to the 4 grid neighbours (2 or 3 on the boundary)
  double h0 = 0;      // nominal spacing
};

/// n x n nodes on [0, 1]^2. kind: "regular", "perturbed" (interior nodes moved up
/// to 0.3 h in each direction, boundary nodes only along the boundary, so the hull
/// stays the square), "graded" (x = (s + 2 s^2)/3 along each axis: spacing 1:5).
inline Cloud2 grid_cloud(const std::string& kind, int n, unsigned seed = 7) {
  Cloud2 c;
  c.name = kind;
  c.h0 = 1.0 / (n - 1);
  c.nodes.resize(2, n * n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  auto map = [&](double s) { return kind == "graded" ? (s + 2 * s * s) / 3.0 : s; };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      double s = static_cast<double>(i) / (n - 1), t = static_cast<double>(j) / (n - 1);
      if (kind == "perturbed") {
        const bool bi = i == 0 || i == n - 1, bj = j == 0 || j == n - 1;
        if (!bi) s += u(rng) * c.h0;
        if (!bj) t += u(rng) * c.h0;
      }
      c.nodes.col(j * n + i) << map(s), map(t);
    }
  c.h.resize(n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      double sum = 0;
      int cnt = 0;
      const int a = j * n + i;
      const int di[4] = {1, -1, 0, 0}, dj[4] = {0, 0, 1, -1};
      for (int k = 0; k < 4; ++k) {
        const int ii = i + di[k], jj = j + dj[k];
        if (ii < 0 || jj < 0 || ii >= n || jj >= n) continue;
        sum += (c.nodes.col(jj * n + ii) - c.nodes.col(a)).norm();
        ++cnt;
      }
      c.h(a) = sum / cnt;
    }
  return c;
}

/// Uniform random points in [lo, hi]^2.
inline Eigen::Matrix2Xd random_points(int count, double lo, double hi, unsigned seed = 11) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  Eigen::Matrix2Xd x(2, count);
  for (int k = 0; k < count; ++k) x.col(k) << u(rng), u(rng);
  return x;
}

/// Points at distance `d` inside each side of the unit square, spread along it.
inline Eigen::Matrix2Xd near_boundary_points(int per_side, double d, unsigned seed = 13) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  Eigen::Matrix2Xd x(2, 4 * per_side);
  for (int k = 0; k < per_side; ++k) {
    x.col(4 * k + 0) << u(rng), d;
    x.col(4 * k + 1) << 1 - d, u(rng);
    x.col(4 * k + 2) << u(rng), 1 - d;
    x.col(4 * k + 3) << d, u(rng);
  }
  return x;
}

}  // namespace maxentflow::test

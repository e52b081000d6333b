// Benchmark: integration mesh build (Delaunay + alpha cut + edges + boundary
// loops + h) on perturbed square grids of 1k .. 1M nodes, as done every step.
// Prints `BENCH mesh_build nodes=N seconds=T` per size (best of repeats, the
// mesh object reused as in a simulation) and the fitted growth exponent.
// Never fails on time.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <maxentflow/mesh/integration_mesh.hpp>

namespace {

Eigen::Matrix2Xd perturbed_grid(int n, double delta, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-delta, delta);
  Eigen::Matrix2Xd x(2, n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const bool inner = i > 0 && j > 0 && i + 1 < n && j + 1 < n;
      const double dx = u(rng), dy = u(rng);
      x.col(j * n + i) << i + (inner ? dx : 0.0), j + (inner ? dy : 0.0);
    }
  return x;
}

}  // namespace

int main() {
  using clock = std::chrono::steady_clock;
  const std::vector<int> sides = {32, 100, 316, 1000};  // 1k, 10k, 100k, 1M nodes
  std::vector<double> log_n, log_t;
  maxentflow::IntegrationMesh<> mesh;
  for (int side : sides) {
    const Eigen::Matrix2Xd x = perturbed_grid(side, 0.25, 1);
    double best = 1e300, spent = 0.0;
    int runs = 0;
    // Best of several runs, at least 2 and about 0.5 s per size (1 run at 1M).
    while (runs < 2 || (spent < 0.5 && runs < 200)) {
      const auto t0 = clock::now();
      mesh.build(x);
      const double s = std::chrono::duration<double>(clock::now() - t0).count();
      best = std::min(best, s);
      spent += s;
      ++runs;
      if (x.cols() >= 1000000 && runs >= 2) break;
    }
    std::printf(
        "BENCH mesh_build nodes=%ld seconds=%.6f triangles=%ld boundary_loops=%zu runs=%d\n",
        static_cast<long>(x.cols()), best, static_cast<long>(mesh.number_of_triangles()),
        mesh.boundary_loops().size(), runs);
    std::fflush(stdout);
    log_n.push_back(std::log(static_cast<double>(x.cols())));
    log_t.push_back(std::log(best));
  }
  // Least-squares slope of log t against log N.
  const double mn = [&] {
    double s = 0;
    for (double v : log_n) s += v;
    return s / log_n.size();
  }();
  const double mt = [&] {
    double s = 0;
    for (double v : log_t) s += v;
    return s / log_t.size();
  }();
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t k = 0; k < log_n.size(); ++k) {
    sxy += (log_n[k] - mn) * (log_t[k] - mt);
    sxx += (log_n[k] - mn) * (log_n[k] - mn);
  }
  std::printf("BENCH mesh_build_exponent value=%.3f\n", sxy / sxx);
  return 0;
}

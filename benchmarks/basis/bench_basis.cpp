// Benchmark: max-ent basis evaluations per second (values + gradients), 2-D,
// gamma = 1.6, perturbed grid, ~1 M points laid out as Gauss points (6 per grid
// cell, cell by cell), on 1 and 2 threads; at MaxEntBasis's default support
// cut-off (tol0 1e-6) and at the stepper's (1e-4). Prints `BENCH ...` lines;
// never fails on time. Usage: bench_basis [points_millions]
#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/core/parallel.hpp>

#include <chrono>
#include <cstdio>
#include <random>
#include <string>

int main(int argc, char** argv) {
  const double millions = argc > 1 ? std::stod(argv[1]) : 1.0;
  const int cells = static_cast<int>(std::sqrt(millions * 1e6 / 6.0));
  const int n = cells + 1;
  const double h = 1.0 / cells;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  Eigen::Matrix2Xd nodes(2, n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      double x = i * h, y = j * h;
      if (i > 0 && i < n - 1) x += u(rng) * h;
      if (j > 0 && j < n - 1) y += u(rng) * h;
      nodes.col(j * n + i) << x, y;
    }
  // Gauss-like points: 3 per triangle of each cell's two triangles, cell by cell.
  const double g[3][2] = {{1.0 / 6, 1.0 / 6}, {2.0 / 3, 1.0 / 6}, {1.0 / 6, 2.0 / 3}};
  Eigen::Matrix2Xd x(2, 6 * cells * cells);
  int k = 0;
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i) {
      const Eigen::Vector2d a = nodes.col(j * n + i), b = nodes.col(j * n + i + 1),
                            c = nodes.col((j + 1) * n + i + 1), d = nodes.col((j + 1) * n + i);
      for (const auto& w : g) x.col(k++) = a + w[0] * (b - a) + w[1] * (c - a);
      for (const auto& w : g) x.col(k++) = a + w[0] * (c - a) + w[1] * (d - a);
    }
  const Eigen::VectorXd hs = Eigen::VectorXd::Constant(nodes.cols(), h);
  const int max_threads = maxentflow::max_threads();
  for (double tol0 : {1e-6, 1e-4}) {
    maxentflow::MaxEntBasis<2>::params prm;
    prm.tol0 = tol0;
    auto t0 = std::chrono::steady_clock::now();
    const maxentflow::MaxEntBasis<2> basis(nodes, hs, prm);
    const double setup = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("BENCH basis_setup tol0=%.0e nodes=%ld seconds=%.4f\n", tol0, static_cast<long>(nodes.cols()),
                setup);
    for (int threads : {1, 2}) {
      if (threads > max_threads && threads > 1) break;
      maxentflow::set_threads(threads);
      // The table is reused, as a stepper does every step (the first call also pays
      // for the table's pages); the best of 3 calls counts.
      double best = 1e30;
      maxentflow::BasisTable<2> t;
      for (int rep = 0; rep < 3; ++rep) {
        t0 = std::chrono::steady_clock::now();
        basis.evaluate(x, t, true);
        best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      }
      const double rate = static_cast<double>(x.cols()) / best;
      std::printf(
          "BENCH basis_eval tol0=%.0e threads=%d points=%ld seconds=%.4f points_per_second=%.0f "
          "points_per_second_per_core=%.0f mean_newton_iterations=%.3f max_newton_iterations=%d "
          "mean_support=%.2f\n",
          tol0, threads, static_cast<long>(x.cols()), best, rate, rate / threads, t.mean_iterations(),
          t.max_iterations(), static_cast<double>(t.entries()) / t.size());
    }
  }
  maxentflow::set_threads(max_threads);
  return 0;
}

#include <catch2/catch.hpp>

#include <random>
#include <vector>

#include <Eigen/SparseCore>

#include <maxentflow/core/parallel.hpp>

using namespace maxentflow;

namespace {

// A random sparse n x n matrix with about `per_col` entries per column, some
// columns empty and a dense row (an uneven spread of nonzeros).
Eigen::SparseMatrix<double> random_sparse(int n, int per_col, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_int_distribution<int> row(0, n - 1);
  std::uniform_real_distribution<double> val(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> t;
  for (int j = 0; j < n; ++j) {
    if (j % 7 == 3) continue;
    for (int k = 0; k < per_col; ++k) t.emplace_back(row(gen), j, val(gen));
    t.emplace_back(0, j, val(gen));
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

}  // namespace

TEST_CASE("column_product: A v in parallel, equal to Eigen's product, the same for any thread count",
          "[core]") {
  const int n = 1000;
  const Eigen::SparseMatrix<double> A = random_sparse(n, 9, 7);
  const Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(n, -2.0, 3.0);
  const Eigen::VectorXd ref = A * v;
  Eigen::VectorXd y;
  Eigen::MatrixXd part;
  const int threads = max_threads();
  set_threads(1);
  column_product(A, v, y, part);
  const Eigen::VectorXd y1 = y;
  set_threads(2);
  column_product(A, v, y, part);
  set_threads(threads);
  // Only the order of the additions differs from Eigen's.
  CHECK((y1 - ref).cwiseAbs().maxCoeff() <= 1e-13 * ref.cwiseAbs().maxCoeff());
  CHECK(y == y1);  // bitwise: the chunks do not follow the threads
  // An uncompressed matrix (equal column cuts) and fewer columns than chunks.
  Eigen::SparseMatrix<double> B = A;
  B.coeffRef(5, 5) += 1.0;
  B.uncompress();
  REQUIRE_FALSE(B.isCompressed());
  column_product(B, v, y, part);
  CHECK((y - Eigen::VectorXd(B * v)).cwiseAbs().maxCoeff() <= 1e-13 * ref.cwiseAbs().maxCoeff());
  Eigen::SparseMatrix<double> C(3, 2);
  C.insert(0, 0) = 2.0;
  C.insert(2, 1) = -1.0;
  C.makeCompressed();
  const Eigen::VectorXd w = Eigen::Vector2d(3.0, 4.0);
  column_product(C, w, y, part);
  CHECK(y == Eigen::Vector3d(6.0, 0.0, -4.0));
}

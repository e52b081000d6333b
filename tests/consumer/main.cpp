// The README's consumer snippet: build a max-ent basis on a small node cloud and
// check the two properties the paper's method rests on (Eq. 1).
#include <maxentflow/maxentflow.hpp>

#include <cmath>
#include <iostream>

int main() {
  // 11 x 11 nodes on the unit square; h_a from the Delaunay neighbours, gamma = 1.6.
  Eigen::Matrix2Xd nodes(2, 121);
  for (int i = 0, k = 0; i <= 10; ++i)
    for (int j = 0; j <= 10; ++j) nodes.col(k++) << 0.1 * i, 0.1 * j;
  maxentflow::MaxEntBasis<2> basis(nodes);

  const Eigen::Vector2d x(0.437, 0.612);
  const auto v = basis.evaluate(x);  // p_a(x) and grad p_a(x) on the support of x
  double sum = 0;
  Eigen::Vector2d reproduced = Eigen::Vector2d::Zero();
  for (std::size_t k = 0; k < v.node.size(); ++k) {
    sum += v.p[k];
    reproduced += v.p[k] * nodes.col(v.node[k]);
  }
  std::cout << v.node.size() << " nodes in the support, sum p_a = " << sum
            << ", |sum p_a x_a - x| = " << (reproduced - x).norm() << '\n';
  return std::abs(sum - 1) < 1e-12 && (reproduced - x).norm() < 1e-10 ? 0 : 1;
}

// libFuzzer target: MaxEntBasis on an arbitrary node cloud (coincident,
// collinear, non-finite nodes included) evaluated at arbitrary points. Either
// an Error, or values that are a partition of unity, non-negative, with
// first-order consistency (sum p_a x_a = x, to the accuracy MaxEntBasis
// states) and finite gradients.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>

#include <fuzzer/FuzzedDataProvider.h>

#include <maxentflow/basis/maxent_basis.hpp>

#include "fuzz_support.hpp"

namespace {
double coordinate(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange(0, 7)) {
    case 0: return in.ConsumeFloatingPoint<double>();               // anything, NaN and inf too
    case 1: return static_cast<double>(in.ConsumeIntegralInRange(0, 4));  // grid: collinear, coincident
    default: return in.ConsumeFloatingPointInRange(0.0, 1.0);
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace maxentflow;
  FuzzedDataProvider in(data, size);
  const int n = in.ConsumeIntegralInRange(0, 24);
  MaxEntBasis<2>::params prm;
  prm.gamma = in.ConsumeBool() ? 1.6 : in.ConsumeFloatingPointInRange(-1.0, 20.0);
  Eigen::Matrix2Xd nodes(2, n);
  for (int a = 0; a < n; ++a) nodes.col(a) << coordinate(in), coordinate(in);
  fuzz::expect_error_or_success([&] {
    const MaxEntBasis<2> basis(nodes, prm);
    for (int q = 0; q < 4 && in.remaining_bytes() > 0; ++q) {
      const Eigen::Vector2d x(coordinate(in), coordinate(in));
      fuzz::expect_error_or_success([&] {
        const auto v = basis.evaluate(x, true);
        double sum = 0.0;
        Eigen::Vector2d first = Eigen::Vector2d::Zero(), gsum = Eigen::Vector2d::Zero();
        double scale = x.cwiseAbs().maxCoeff(), h_max = 0.0, h_near = 0.0, d_near = std::numeric_limits<double>::infinity();
        for (std::size_t j = 0; j < v.node.size(); ++j) {
          fuzz::require(std::isfinite(v.p[j]) && v.p[j] >= -1e-12, "finite, non-negative values");
          sum += v.p[j];
          const auto xa = nodes.col(v.node[j]);
          first += v.p[j] * xa;
          gsum += v.gradients().col(static_cast<Eigen::Index>(j));
          scale = std::max(scale, xa.cwiseAbs().maxCoeff());
          const double h = basis.h()(v.node[j]), d = (xa - x).norm();
          h_max = std::max(h_max, h);
          if (d < d_near) d_near = d, h_near = h;
        }
        // The accuracy MaxEntBasis states, beyond round-off in the coordinates.
        const double consistency = (v.on_hull ? 3e-6 * h_max : 1e-8 * h_near) +
                                   64 * std::numeric_limits<double>::epsilon() * scale;
        if (!(std::abs(sum - 1.0) <= 1e-8 && (first - x).norm() <= consistency && gsum.allFinite())) {
          std::fprintf(stderr, "gamma %.17g, point (%.17g, %.17g), on hull %d, |sum p x - x| %.3g, nodes:\n",
                       prm.gamma, x.x(), x.y(), int(v.on_hull), (first - x).norm());
          for (int a = 0; a < n; ++a) std::fprintf(stderr, "  %.17g %.17g\n", nodes(0, a), nodes(1, a));
        }
        fuzz::require(std::abs(sum - 1.0) <= 1e-8, "partition of unity");
        fuzz::require((first - x).norm() <= consistency, "first-order consistency");
        fuzz::require(gsum.allFinite(), "finite gradients");
      });
    }
  });
  return 0;
}

// libFuzzer target: RigidTool from an arbitrary polyline (points, corner
// radii, open or closed), then closest-point queries. Either an Error, or a
// tool whose projections are finite and consistent (|gap| = distance, the
// normal unit).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <fuzzer/FuzzedDataProvider.h>

#include <maxentflow/contact/rigid_tool.hpp>

#include "fuzz_support.hpp"

namespace {
// Mostly moderate coordinates (where geometry bugs live), sometimes any double.
double coordinate(FuzzedDataProvider& in) {
  return in.ConsumeBool() ? in.ConsumeFloatingPoint<double>() : in.ConsumeFloatingPointInRange(-10.0, 10.0);
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace maxentflow;
  FuzzedDataProvider in(data, size);
  const int n = in.ConsumeIntegralInRange(0, 8);
  const bool closed = in.ConsumeBool();
  Eigen::Matrix2Xd p(2, n);
  std::vector<double> radii;
  for (int j = 0; j < n; ++j) {
    p(0, j) = coordinate(in);
    p(1, j) = coordinate(in);
  }
  if (in.ConsumeBool())
    for (int j = 0; j < n; ++j) radii.push_back(in.ConsumeBool() ? 0.0 : in.ConsumeFloatingPointInRange(-1.0, 5.0));
  fuzz::expect_error_or_success([&] {
    const RigidTool tool("fuzz", p, radii, closed ? ToolClosure::closed : ToolClosure::open);
    for (int q = 0; q < 4 && in.remaining_bytes() > 0; ++q) {
      const Eigen::Vector2d x(coordinate(in), coordinate(in));
      const ToolProjection r = tool.closest(x);
      fuzz::require(std::isfinite(r.gap) && r.normal.allFinite(), "finite projection");
      fuzz::require(std::abs(std::abs(r.gap) - r.distance) <= 1e-9 * (1.0 + r.distance), "|gap| = distance");
      fuzz::require(std::abs(r.normal.norm() - 1.0) <= 1e-9, "unit normal");
    }
  });
  return 0;
}

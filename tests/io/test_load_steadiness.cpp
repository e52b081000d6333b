// The load-curve figures the examples report (examples/common/load_steadiness.hpp):
// the cutting example's plateau check and the extrusion example's ram load.
#include <catch2/catch.hpp>

#include <cmath>
#include <sstream>
#include <vector>

#include "../../examples/common/load_steadiness.hpp"

using maxentflow::examples::load_steadiness;

TEST_CASE("load steadiness: mean, band and step-to-step changes of a load curve", "[io][examples]") {
  const auto s = load_steadiness({100, 110, 90, 100});
  CHECK(s.samples == 4);
  CHECK(s.mean == Approx(100).epsilon(1e-15));
  CHECK(s.low == Approx(-0.1).epsilon(1e-13));
  CHECK(s.high == Approx(0.1).epsilon(1e-13));
  CHECK(s.band() == Approx(0.1).epsilon(1e-13));
  // Changes +10, -20, +10 of a mean of 100.
  CHECK(s.rms_change == Approx(std::sqrt(0.06 / 3)).epsilon(1e-13));
  CHECK(s.largest_change == Approx(0.2).epsilon(1e-13));
  std::ostringstream os;
  os << s;
  CHECK(os.str() == "mean 100, band -10.00 / +10.00 %, step-to-step change 14.14 % rms (largest 20.00 %, 4 steps)");
}

TEST_CASE("load steadiness: an uneven band and a steady curve", "[io][examples]") {
  const auto s = load_steadiness({2, 2, 2, 5});  // mean 2.75: -27 % / +82 %
  CHECK(s.low == Approx(2 / 2.75 - 1).epsilon(1e-13));
  CHECK(s.high == Approx(5 / 2.75 - 1).epsilon(1e-13));
  CHECK(s.band() == Approx(5 / 2.75 - 1).epsilon(1e-13));
  CHECK(s.rms_change == Approx(std::sqrt((3 / 2.75) * (3 / 2.75) / 3)).epsilon(1e-13));
  const auto flat = load_steadiness({7, 7, 7});
  CHECK(flat.band() == 0);
  CHECK(flat.rms_change == 0);
  CHECK(load_steadiness({}).samples == 0);
  const auto one = load_steadiness({3});
  CHECK(one.samples == 1);
  CHECK(one.rms_change == 0);
}

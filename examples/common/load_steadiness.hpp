// Examples: how steady a load curve is over a window of steps: the figures a
// press operator reads off a load-stroke curve in a steady flow (its mean,
// the band around it and the jumps from one step to the next).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <vector>

namespace maxentflow::examples {

struct LoadSteadiness {
  int samples = 0;
  double mean = 0;
  double low = 0, high = 0;      ///< min / mean - 1 and max / mean - 1
  double rms_change = 0;         ///< rms of (F_k - F_{k-1}) / mean
  double largest_change = 0;     ///< largest |F_k - F_{k-1}| / mean
  /// The band as one figure: the larger of -low and high.
  double band() const { return std::max(-low, high); }
};

/// Figures of the loads `f` (consecutive steps, in order). Fewer than two
/// samples or a zero mean give samples < 2 or non-finite ratios.
inline LoadSteadiness load_steadiness(const std::vector<double>& f) {
  LoadSteadiness s;
  s.samples = static_cast<int>(f.size());
  if (f.empty()) return s;
  double sum = 0, lo = f[0], hi = f[0];
  for (double v : f) {
    sum += v;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  s.mean = sum / static_cast<double>(f.size());
  s.low = lo / s.mean - 1;
  s.high = hi / s.mean - 1;
  double sq = 0;
  for (std::size_t k = 1; k < f.size(); ++k) {
    const double c = (f[k] - f[k - 1]) / s.mean;
    sq += c * c;
    s.largest_change = std::max(s.largest_change, std::abs(c));
  }
  if (f.size() > 1) s.rms_change = std::sqrt(sq / static_cast<double>(f.size() - 1));
  return s;
}

/// "mean M, band -a / +b %, step-to-step change c % rms (largest d %, n steps)".
inline std::ostream& operator<<(std::ostream& os, const LoadSteadiness& s) {
  char buf[192];
  std::snprintf(buf, sizeof buf,
                "mean %.6g, band %+.2f / %+.2f %%, step-to-step change %.2f %% rms (largest %.2f %%, %d steps)",
                s.mean, 100 * s.low, 100 * s.high, 100 * s.rms_change, 100 * s.largest_change, s.samples);
  return os << buf;
}

/// Where the tools' power goes over the same window (StepRecord::power and
/// tool_power): the plastic dissipation's and the stabilization's shares of
/// it, the rest being the gap closure's, friction's and the prescribed
/// velocities'; and how steady the plastic part alone is (load_steadiness
/// of plastic / speed): a load whose noise is the plastic part's comes from
/// the flow, not from how the multipliers sum to a force.
struct PowerShares {
  int samples = 0;
  double plastic = 0, stabilization = 0;           ///< mean shares of the tools' power
  double stabilization_low = 0, stabilization_high = 0;
  LoadSteadiness plastic_load;                     ///< of plastic / speed
};

template <class Record>
PowerShares power_shares(const std::vector<const Record*>& steps, double speed) {
  PowerShares s;
  s.samples = static_cast<int>(steps.size());
  if (steps.empty()) return s;
  std::vector<double> plastic_load;
  s.stabilization_low = 1e300;
  s.stabilization_high = -1e300;
  for (const Record* r : steps) {
    const double sp = r->power.volumetric / r->tool_power;
    s.plastic += r->power.plastic / r->tool_power / s.samples;
    s.stabilization += sp / s.samples;
    s.stabilization_low = std::min(s.stabilization_low, sp);
    s.stabilization_high = std::max(s.stabilization_high, sp);
    plastic_load.push_back(r->power.plastic / speed);
  }
  s.plastic_load = load_steadiness(plastic_load);
  return s;
}

/// "plastic a %, stabilization b % (c-d %); plastic part alone: step-to-step change e % rms".
inline std::ostream& operator<<(std::ostream& os, const PowerShares& s) {
  char buf[224];
  std::snprintf(buf, sizeof buf,
                "plastic %.2f %%, stabilization %.2f %% (%.2f-%.2f %%), the rest %.2f %%; the plastic part "
                "alone: band %+.2f / %+.2f %%, step-to-step change %.2f %% rms",
                100 * s.plastic, 100 * s.stabilization, 100 * s.stabilization_low, 100 * s.stabilization_high,
                100 * (1 - s.plastic - s.stabilization), 100 * s.plastic_load.low, 100 * s.plastic_load.high,
                100 * s.plastic_load.rms_change);
  return os << buf;
}

}  // namespace maxentflow::examples

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

}  // namespace maxentflow::examples

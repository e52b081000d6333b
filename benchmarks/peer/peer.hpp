// The FEM yardstick beside a benchmark: FreeFEM (Debian freefem++) on E2's
// first configuration (e2_step1_mini.edp), timed by the wall clock in the
// same run, so that the benchmark prints a ratio rather than a drifting time.
#pragma once

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace maxentflow::bench {

/// Wall seconds of the peer's step-1 solve at `side` nodes per side, or a
/// negative value when FreeFem++ is not on the machine (or failed).
inline double peer_step1_seconds(int side) {
  if (std::system("command -v FreeFem++ > /dev/null 2>&1") != 0) {
    std::printf("BENCH peer skipped: FreeFem++ not found (Debian package freefem++)\n");
    return -1.0;
  }
  const std::string cmd = std::string("FreeFem++ -nw -v 0 '") + MAXENTFLOW_PEER_SCRIPT + "' " +
                          std::to_string(side) + " > /dev/null 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = std::system(cmd.c_str());
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (rc != 0) {
    std::printf("BENCH peer failed: '%s' exited with %d\n", cmd.c_str(), rc);
    return -1.0;
  }
  std::printf("BENCH peer freefem_p1b_p1_step1 side=%d wall_s=%.3f\n", side, s);
  return s;
}

}  // namespace maxentflow::bench

// Examples: run a matplotlib script (Debian's python3-matplotlib) on the CSV files
// an example wrote. The library itself never depends on Python.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

namespace maxentflow::examples {

/// A Python interpreter that has matplotlib: $MAXENTFLOW_PYTHON, else Debian's
/// /usr/bin/python3 (a pyenv python3 first on PATH often lacks it), else python3.
inline std::string python_with_matplotlib() {
  std::string candidates[3];
  int n = 0;
  if (const char* env = std::getenv("MAXENTFLOW_PYTHON")) candidates[n++] = env;
  if (std::filesystem::exists("/usr/bin/python3")) candidates[n++] = "/usr/bin/python3";
  candidates[n++] = "python3";
  for (int i = 0; i < n; ++i) {
    const std::string probe = "\"" + candidates[i] + "\" -c \"import matplotlib\" >/dev/null 2>&1";
    if (std::system(probe.c_str()) == 0) return candidates[i];
  }
  return {};
}

/// Runs `script args...`; returns false (with a note) if plotting is unavailable
/// or fails: the CSV results stand on their own.
inline bool run_plot_script(const std::filesystem::path& script, const std::string& args) {
  const std::string python = python_with_matplotlib();
  if (python.empty()) {
    std::cerr << "note: no python3 with matplotlib (Debian: python3-matplotlib); PNG figures skipped\n";
    return false;
  }
  const std::string cmd = "\"" + python + "\" \"" + script.string() + "\" " + args;
  if (std::system(cmd.c_str()) != 0) {
    std::cerr << "note: plotting failed: " << cmd << "\n";
    return false;
  }
  return true;
}

}  // namespace maxentflow::examples

// Examples: the checkpoint and restart options every forming example takes
// (--checkpoint-every, --restart), and the case signature a restart must match.
#pragma once

#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <utility>

#include <maxentflow/maxentflow.hpp>

namespace maxentflow::examples {

struct RestartOptions {
  int every = 0;    ///< checkpoint every this many steps; 0: at each VTU step
  std::string dir;  ///< --restart: the results folder of the run to resume

  void add_to(CLI::App& app) {
    app.add_option("--checkpoint-every", every,
                   "Write the run's checkpoint (results folder, checkpoint.mxf) every this many steps; "
                   "0: at each VTU step")
        ->check(CLI::Range(0, 100000));
    auto* restart = app.add_option("--restart", dir,
                                   "Resume the run whose results are in this folder from its last checkpoint, with "
                                   "the same options; its results are appended to (the folder replaces --out-dir)")
                        ->check(CLI::ExistingDirectory);
    // The restarted run's results go where the first run's are: one folder.
    if (auto* out = app.get_option_no_throw("--out-dir")) restart->excludes(out);
  }
  bool restarting() const { return !dir.empty(); }
  /// Whether step k (1-based) ends with a checkpoint.
  bool due(int k, bool vtu) const { return every > 0 ? k % every == 0 : vtu; }

  /// --restart: the run in `dir` back from its checkpoint (read_checkpoint,
  /// `extra` reads the example's own figures) with a line saying from where;
  /// a run that has done all its `steps` is an Error (`who`: the example).
  template <class Sim, class Extra>
  static void resume(const std::filesystem::path& dir, const std::string& signature, Sim& sim,
                     ResultsWriter& writer, int steps, const char* who, Extra&& extra) {
    read_checkpoint(dir, signature, sim, writer, std::forward<Extra>(extra));
    if (sim.steps_done() >= steps)
      throw Error(detail::cat("the run in ", dir.string(), " has done its ", sim.steps_done(),
                              " steps; nothing to restart"),
                  detail::cat(who, " --restart"));
    std::cout << "restarted from " << checkpoint_file(dir) << " after step " << sim.steps_done() << "\n";
  }

  /// The options that define the case, one "name=value" per line (every
  /// option of `app` with its value, defaults included, except those that
  /// only say where and how the results are shown): what a checkpoint is
  /// stamped with and a restart must match.
  static std::string signature(const CLI::App& app) {
    static const std::set<std::string> ignored = {"out-dir", "restart", "checkpoint-every", "no-plots",
                                                  "verbose", "check", "area-tol", "plateau-tol",
                                                  "ratio-tol"};
    std::istringstream all(app.config_to_str(true, false));
    std::string line, sig;
    while (std::getline(all, line)) {
      const auto eq = line.find('=');
      if (eq == std::string::npos) continue;
      std::string key = line.substr(0, eq);
      while (!key.empty() && key.back() == ' ') key.pop_back();
      if (ignored.count(key)) continue;
      sig += line + "\n";
    }
    return sig;
  }
};

}  // namespace maxentflow::examples

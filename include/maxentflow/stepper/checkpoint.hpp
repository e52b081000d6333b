// maxentflow: checkpoint and restart of a forming run: the stepper's state,
// the results writer's and the application's own, in one file written whole.
#pragma once

#include <filesystem>
#include <string>
#include <system_error>

#include <maxentflow/core/error.hpp>
#include <maxentflow/io/checkpoint.hpp>
#include <maxentflow/stepper/results_writer.hpp>

namespace maxentflow {

/// The checkpoint file of a run whose results go to `dir` (one per run, the
/// last one written).
inline std::filesystem::path checkpoint_file(const std::filesystem::path& dir) { return dir / "checkpoint.mxf"; }

/// Removes `<name>.tmp.<pid>` files (write_file_atomic's, left by a killed
/// process) from `dir`; returns how many.
inline int remove_temporaries(const std::filesystem::path& dir) {
  int removed = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    const auto at = name.rfind(".tmp.");
    if (at == std::string::npos || at + 5 >= name.size() ||
        name.find_first_not_of("0123456789", at + 5) != std::string::npos)
      continue;
    std::filesystem::remove(e.path(), ec);
    removed += !ec;
  }
  return removed;
}

/// Writes the run's checkpoint after a step: `signature` names the case (what
/// a restart must match: the options that define the physics), then the
/// stepper's state (Stepper::save), the writer's, and what `extra(out)` adds
/// (the application's running figures, its own tables). Temporary file +
/// rename: a run killed at any moment leaves the previous checkpoint whole.
template <class Sim, class Extra>
void write_checkpoint(const std::filesystem::path& dir, const std::string& signature, Sim& sim,
                      const ResultsWriter& writer, Extra&& extra) {
  CheckpointOut out;
  out.put("maxentflow run").put(signature);
  sim.save(out);
  writer.save(out);
  extra(out);
  out.write(checkpoint_file(dir));
}

/// Reads the checkpoint in `dir` back into a run set up as the one that wrote
/// it (same case, tools and fields): the stepper, the writer, then
/// `extra(in)` in the order write_checkpoint() wrote them. A checkpoint of
/// another format, another case (signature) or a damaged one is refused with
/// an Error. Removes the temporary files a killed write left in `dir`.
template <class Sim, class Extra>
void read_checkpoint(const std::filesystem::path& dir, const std::string& signature, Sim& sim, ResultsWriter& writer,
                     Extra&& extra) {
  const auto file = checkpoint_file(dir);
  if (!std::filesystem::exists(file))
    throw Error(detail::cat("no checkpoint '", file.string(), "' to restart from"), "read_checkpoint");
  CheckpointIn in(file);
  if (in.get_string() != "maxentflow run") in.fail("not the checkpoint of a run");
  const std::string written = in.get_string();
  if (written != signature)
    in.fail(detail::cat("written by another case:\n  checkpoint: ", written, "\n  this run:   ", signature));
  sim.load(in);
  writer.load(in);
  extra(in);
  in.expect_end();
  remove_temporaries(dir);
}

}  // namespace maxentflow

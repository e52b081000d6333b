// Benchmarks: a run's step records summed into the figures each stepper
// benchmark prints (time per part, iteration counts, fallbacks, rezoning).
#pragma once

#include <algorithm>
#include <vector>

#include <maxentflow/maxentflow.hpp>

namespace maxentflow::bench {

struct StepTotals {
  double mesh = 0, basis = 0, solve = 0, post = 0, assembly = 0, factorization = 0, linear = 0;
  int picard = 0, newton = 0, krylov = 0, max_krylov = 0, fallbacks = 0, preconditioner_updates = 0;
  int retried = 0, added = 0, removed = 0, nodes_max = 0;

  explicit StepTotals(const std::vector<StepRecord>& history) {
    for (const auto& r : history) {
      mesh += r.mesh_seconds;
      basis += r.basis_seconds;
      solve += r.solve_seconds;
      post += r.post_seconds;
      assembly += r.assembly_seconds;
      factorization += r.factorization_seconds;
      linear += r.linear_seconds;
      picard += r.picard;
      newton += r.newton;
      krylov += r.linear_iterations;
      max_krylov = std::max(max_krylov, r.max_linear_iterations);
      fallbacks += r.direct_fallbacks;
      preconditioner_updates += r.preconditioner_updates;
      retried += r.substeps > 1;
      added += r.nodes_added;
      removed += r.nodes_removed;
      nodes_max = std::max(nodes_max, r.nodes);
    }
  }
};

}  // namespace maxentflow::bench

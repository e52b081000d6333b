// maxentflow: what the unknowns of a system mean, so that a factorization
// made for one configuration can be applied to the next.
#pragma once

#include <cstdint>
#include <vector>

namespace maxentflow {

/// The unknowns of a saddle system: `fields` field unknowns (3 per node:
/// v_x, v_y, p) first, then one Lagrange multiplier per constraint row, each
/// named by a key (its part, node and direction; see FlowSystem::layout).
/// Two layouts with equal `fields` and keys give each unknown the same meaning.
struct DofLayout {
  int fields = 0;
  std::vector<std::uint64_t> multipliers;

  int size() const { return fields + static_cast<int>(multipliers.size()); }
  bool operator==(const DofLayout&) const = default;

  /// The key of a multiplier row: part, node (-1 allowed) and the main axis
  /// of its direction (0: x, 1: y), which survive a small move of the nodes.
  static std::uint64_t key(int part, int node, int axis) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(part + 1)) << 33) |
           (static_cast<std::uint64_t>(static_cast<std::uint32_t>(node + 1)) << 1) |
           static_cast<std::uint64_t>(axis & 1);
  }
};

}  // namespace maxentflow

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

  /// The key of a multiplier row: part, node (-1 allowed), the main axis of
  /// its direction (0: x, 1: y), which survive a small move of the nodes, and
  /// its role at the node (0: the condition or contact normal, 1: a contact
  /// law's tangential row).
  static std::uint64_t key(int part, int node, int axis, int role = 0) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(part + 1)) << 34) |
           (static_cast<std::uint64_t>(static_cast<std::uint32_t>(node + 1)) << 2) |
           (static_cast<std::uint64_t>(role & 1) << 1) | static_cast<std::uint64_t>(axis & 1);
  }
  /// The node of a key, and the key with another node (renumbered nodes).
  static int key_node(std::uint64_t k) { return static_cast<int>((k >> 2) & 0xffffffffu) - 1; }
  static std::uint64_t with_node(std::uint64_t k, int node) {
    const std::uint64_t mask = std::uint64_t{0xffffffffu} << 2;
    return (k & ~mask) | (static_cast<std::uint64_t>(static_cast<std::uint32_t>(node + 1)) << 2);
  }
};

}  // namespace maxentflow

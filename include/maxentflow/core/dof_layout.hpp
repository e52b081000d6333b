// maxentflow: what the unknowns of a system mean, so that a factorization
// made for one configuration can be applied to the next.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace maxentflow {

/// The unknowns of a saddle system: `fields` field unknowns (3 per node:
/// v_x, v_y, p) first, then one Lagrange multiplier per constraint row, each
/// named by a key (its part, node and direction; see FlowSystem::layout).
/// Two layouts with equal `fields` and keys give each unknown the same meaning.
struct DofLayout {
  int fields = 0;
  std::vector<std::uint64_t> multipliers;

  /// Field unknowns per node, interleaved: v_x, v_y (v_r, v_z), p.
  static constexpr int per_node = 3;
  static constexpr int velocity(int node, int axis) { return per_node * node + axis; }
  static constexpr int pressure(int node) { return per_node * node + 2; }
  /// The field unknowns of `nodes` nodes; the multipliers follow them.
  static constexpr int fields_of(int nodes) { return per_node * nodes; }
  /// The position of multiplier i.
  int multiplier(int i) const { return fields + i; }

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

/// sum_b p_b X_b: the fields (v_x, v_y, p) at a point from the basis values
/// p (at the nodes `nodes`) there and the unknowns X (the max-ent basis is not
/// interpolating inside, so the coefficients are not the nodal values).
template <class Nodes, class Values>
Eigen::Vector3d interpolate_fields(const Nodes& nodes, const Values& p, const Eigen::VectorXd& X) {
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < static_cast<std::size_t>(nodes.size()); ++j)
    f += p[j] * X.segment<DofLayout::per_node>(DofLayout::per_node * nodes[j]);
  return f;
}

}  // namespace maxentflow

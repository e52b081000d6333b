// maxentflow: essential conditions by Lagrange multipliers (Eq. 15), with the
// multipliers discretized by linear FE functions on the boundary segments.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/dof_layout.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/flow/stabilized_flow.hpp>

namespace maxentflow {

/// One Lagrange multiplier Lambda_i: the condition sum_k coef_k X[dof_k] = rhs
/// (a row of L^T in Eq. 21) and the force its multiplier puts on the part:
/// Lambda_i * force (the force the workpiece exerts on a plate or tool).
struct ConstraintRow {
  std::vector<int> dof;  ///< ascending
  std::vector<double> coef;
  double rhs = 0.0;
  int part = -1;
  int node = -1;  ///< the boundary node carrying the multiplier's hat function (-1: none)
  Eigen::Vector2d direction = Eigen::Vector2d::Zero();  ///< constrained velocity direction
  Eigen::Vector2d force = Eigen::Vector2d::Zero();
  int role = 0;   ///< 0: the condition or contact normal; 1: a contact law's tangential row
  /// The row's key in a DofLayout (matches it across configurations).
  std::uint64_t key() const {
    return DofLayout::key(part, node, std::abs(direction.x()) >= std::abs(direction.y()) ? 0 : 1, role);
  }
};

/// Chooses boundary segments by their end points (material on the left of a -> b).
using SegmentSelector = std::function<bool(const Eigen::Vector2d& xa, const Eigen::Vector2d& xb)>;

/// Segments with both ends within tol of the line through `point` with normal `normal`.
inline SegmentSelector on_line(Eigen::Vector2d point, Eigen::Vector2d normal, double tol) {
  normal.normalize();
  return [point, normal, tol](const Eigen::Vector2d& xa, const Eigen::Vector2d& xb) {
    return std::abs((xa - point).dot(normal)) <= tol && std::abs((xb - point).dot(normal)) <= tol;
  };
}

/// The hat-function integrals of one multiplier (Eq. 15): the row
/// int N_a (sum_b phi_b V_b) . e_a ds over the segments at node a, its right-hand
/// side int N_a g ds and int N_a ds (the force per unit multiplier).
struct HatIntegrals {
  std::map<int, double> coef;  ///< velocity dof -> coefficient
  double rhs = 0.0, length = 0.0;
};

/// Hat integrals for every end node of the boundary segments `keep` accepts,
/// node a's multiplier constraining v . direction(a) = value(a, x) along them.
/// The one place where hat-multiplier rows are integrated (velocity conditions,
/// tool contact).
template <class Keep, class Direction, class Value>
std::map<int, HatIntegrals> hat_integrals(const IntegrationMesh<2>& mesh, const FlowDiscretization& disc,
                                          Keep&& keep, Direction&& direction, Value&& value) {
  std::map<int, HatIntegrals> out;
  const auto& edges = mesh.edges();
  const int ne = disc.points_per_edge();
  const auto& tab = disc.edge_basis();
  for (const auto& seg : mesh.boundary_segments()) {
    if (!keep(seg)) continue;
    const auto& edge = edges[static_cast<std::size_t>(seg.edge)];
    for (int k = 0; k < ne; ++k) {
      const int ge = seg.edge * ne + k;
      const double s = disc.edge_parameter(k);  // from edge.a
      const double w = disc.edge_weights()(ge);
      const Eigen::Vector2d x = disc.edge_points().col(ge);
      const int ends[2] = {edge.a, edge.b};
      const double hat[2] = {1.0 - s, s};
      const auto nodes = tab.nodes(ge);
      const auto p = tab.values(ge);
      for (int e = 0; e < 2; ++e) {
        const Eigen::Vector2d n = direction(ends[e]);
        HatIntegrals& r = out[ends[e]];
        for (std::size_t j = 0; j < nodes.size(); ++j) {
          if (p[j] == 0.0) continue;
          for (int c = 0; c < 2; ++c)
            if (n[c] != 0.0) r.coef[velocity_dof(nodes[j], c)] += w * hat[e] * p[j] * n[c];
        }
        r.rhs += w * hat[e] * value(ends[e], x);
        r.length += w * hat[e];
      }
    }
  }
  return out;
}

/// The constraint rows of a configuration, grouped into named parts
/// (a plate, a symmetry line, a tool), with the reaction on each part.
class ConstraintSet {
 public:
  using Mesh = IntegrationMesh<2>;
  using Value = std::function<double(const Eigen::Vector2d&)>;

  int add_part(const std::string& name) {
    const auto it = std::find(names_.begin(), names_.end(), name);
    if (it != names_.end()) return static_cast<int>(it - names_.begin());
    names_.push_back(name);
    return static_cast<int>(names_.size()) - 1;
  }
  int find_part(const std::string& name) const {
    const auto it = std::find(names_.begin(), names_.end(), name);
    require(it != names_.end(), detail::cat("no constraint part named '", name, "'"),
            "ConstraintSet::find_part");
    return static_cast<int>(it - names_.begin());
  }
  const std::vector<std::string>& parts() const { return names_; }
  const std::vector<ConstraintRow>& rows() const { return rows_; }
  std::vector<ConstraintRow>& rows() { return rows_; }
  int size() const { return static_cast<int>(rows_.size()); }
  void clear_rows() { rows_.clear(); }
  /// Removes the rows of one part (e.g. a tool's contact rows before a new active set).
  void clear_part(int part) {
    rows_.erase(std::remove_if(rows_.begin(), rows_.end(),
                               [part](const ConstraintRow& r) { return r.part == part; }),
                rows_.end());
  }
  void add(ConstraintRow row) {
    require(row.dof.size() == row.coef.size(), "a constraint row needs one coefficient per dof",
            "ConstraintSet::add");
    rows_.push_back(std::move(row));
  }

  /// The row of node `node`'s hat multiplier from its integrals.
  static ConstraintRow hat_row(const HatIntegrals& h, int part, int node, const Eigen::Vector2d& direction) {
    ConstraintRow row;
    row.direction = direction;
    row.part = part;
    row.node = node;
    for (const auto& [dof, c] : h.coef) {
      row.dof.push_back(dof);
      row.coef.push_back(c);
    }
    row.rhs = h.rhs;
    row.force = h.length * direction;
    return row;
  }

  /// v . e = value(x) on the boundary segments chosen by `select` (Eq. 15), e a
  /// unit direction (e = (1,0) for v_x, the normal for a symmetry line). One
  /// multiplier per segment end node, hat functions along the chosen segments:
  /// row i is int N_i phi_a e ds . v_a = int N_i value ds. The measure is plain
  /// arc length also in axisymmetric problems (the multiplier then carries the
  /// 2 pi r, and sums to the total force); this keeps the rows regular on the axis.
  /// A node that already carries a multiplier for a parallel direction (the
  /// corner shared with an earlier part) gets none here: two would constrain
  /// the same velocity twice and make the system singular.
  /// Returns the number of rows added (0 if no segment was chosen).
  int add_velocity(const Mesh& mesh, const FlowDiscretization& disc, const SegmentSelector& select,
                   Eigen::Vector2d direction, const Value& value, const std::string& part_name) {
    const int part = add_part(part_name);
    require(direction.norm() > 0, "a velocity condition needs a nonzero direction",
            detail::cat("ConstraintSet::add_velocity, part '", part_name, "'"));
    direction.normalize();
    const auto& X = mesh.nodes();
    const auto hats = hat_integrals(
        mesh, disc, [&](const BoundarySegment& seg) { return select(X.col(seg.a), X.col(seg.b)); },
        [&](int) { return direction; },
        [&](int, const Eigen::Vector2d& x) { return value ? value(x) : 0.0; });
    int added = 0;
    for (const auto& [node, h] : hats) {
      if (has_parallel_row(node, direction)) continue;
      ++added;
      rows_.push_back(hat_row(h, part, node, direction));
    }
    return added;
  }

  /// A node already carries a multiplier for a direction parallel to e (two
  /// would constrain the same velocity twice: a singular system).
  bool has_parallel_row(int node, const Eigen::Vector2d& e) const {
    return std::any_of(rows_.begin(), rows_.end(), [&](const ConstraintRow& r) {
      return r.node == node && std::abs(r.direction.dot(e)) > 1.0 - 1e-12;
    });
  }

  /// Fixes the pressure level: int p dOmega = mean * |Omega| (needed when the
  /// velocity is prescribed on the whole boundary, as in a closed die).
  void add_pressure_mean(const FlowDiscretization& disc, double mean,
                         const std::string& part_name = "pressure mean") {
    const int part = add_part(part_name);
    std::map<int, double> c;
    double volume = 0.0;
    for (int t = 0; t < disc.cells(); ++t) {
      const auto u = disc.nodes(t);
      for (int q = 0; q < disc.points_per_cell(); ++q) {
        const double w = disc.weight(t * disc.points_per_cell() + q);
        const double* p = disc.values(t, q);
        volume += w;
        for (std::size_t i = 0; i < u.size(); ++i)
          if (p[i] != 0.0) c[pressure_dof(u[i])] += w * p[i];
      }
    }
    ConstraintRow row;
    row.part = part;
    for (const auto& [dof, v] : c) {
      row.dof.push_back(dof);
      row.coef.push_back(v / volume);
    }
    row.rhs = mean;
    rows_.push_back(std::move(row));
  }

  /// The force the workpiece exerts on a part, from the multipliers (X[3N + i]).
  Eigen::Vector2d reaction(int part, const Eigen::VectorXd& X, int n_nodes) const {
    Eigen::Vector2d f = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < rows_.size(); ++i)
      if (rows_[i].part == part) f += X[DofLayout::fields_of(n_nodes) + static_cast<Eigen::Index>(i)] * rows_[i].force;
    return f;
  }

 private:
  std::vector<std::string> names_;
  std::vector<ConstraintRow> rows_;
};

}  // namespace maxentflow

// maxentflow: frictionless rigid-tool contact by Lagrange multipliers
// (Eqs. 16-17), multipliers on the workpiece's alpha-shape boundary.
#pragma once

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>

namespace maxentflow {

/// One boundary node's state against one tool.
struct ContactPoint {
  int node = -1;
  ToolProjection projection;
  double h = 0.0;  ///< nodal spacing, the scale of the gap tolerances
  bool active = false;
};

/// Contact of the workpiece boundary with one rigid tool over a step dt.
///
/// The gap g_n of Eq. (16) must stay >= 0 at the end of the step; with the
/// velocity v of the step, g_n(t + dt) = g_n + dt (v - v_tool) . n. An active
/// node gets (v - v_tool) . n = -g_n / dt (closes a small gap or penetration
/// left by the previous step, so errors do not accumulate), imposed weakly
/// with a linear hat multiplier on the boundary segments whose two ends are
/// active, like the essential conditions; an active node with no active
/// neighbour gets a point constraint. The force the workpiece exerts on the
/// tool is the sum of the multipliers times their hat integrals and normals;
/// compressive contact has Lambda < 0 (the force points into the tool).
/// Frictionless: only the normal velocity is constrained (friction would add
/// tangential rows or a traction with the same hats).
class ToolContact {
 public:
  using Mesh = IntegrationMesh<Traits<2>>;

  struct params {
    double gap_tol = 1e-3;      ///< in contact when g_n <= gap_tol * h_a
    double release_tol = 1e-9;  ///< released when Lambda > release_tol * max|Lambda| (tensile)
  };

  ToolContact() = default;
  explicit ToolContact(params prm) : prm_(prm) {}
  const params& parameters() const { return prm_; }

  /// Projects every boundary node onto the tool; active: within the gap
  /// tolerance, or predicted to penetrate during dt with the velocity guess
  /// v_guess (2 x N, e.g. the previous step's nodal velocity; may be empty).
  void detect(const Mesh& mesh, const RigidTool& tool, const Eigen::Matrix2Xd& v_guess, double dt) {
    points_.clear();
    const auto& x = mesh.nodes();
    const auto& h = mesh.h();
    for (int a : mesh.boundary_nodes()) {
      ContactPoint c;
      c.node = a;
      c.h = h(a);
      c.projection = tool.closest(x.col(a));
      const double g = c.projection.gap;
      double g_end = g;
      if (v_guess.cols() == x.cols())
        g_end = g + dt * (v_guess.col(a) - tool.velocity()).dot(c.projection.normal);
      c.active = g <= prm_.gap_tol * h(a) || g_end < 0.0;
      // A node far from the tool (beyond a few h) cannot be reached in one step.
      if (c.projection.distance > 10.0 * h(a) && g > 0) c.active = false;
      points_.push_back(c);
    }
  }

  const std::vector<ContactPoint>& points() const { return points_; }
  int active_count() const {
    return static_cast<int>(std::count_if(points_.begin(), points_.end(),
                                          [](const ContactPoint& c) { return c.active; }));
  }

  /// Adds the rows of the active nodes to `cs` under `part`.
  void add_rows(ConstraintSet& cs, int part, const Mesh& mesh, const FlowDiscretization& disc,
                const MaxEntBasis<2>& basis, const RigidTool& tool, double dt) const {
    std::map<int, const ContactPoint*> active;
    for (const auto& c : points_)
      if (c.active) active[c.node] = &c;
    if (active.empty()) return;
    const auto& edges = mesh.edges();
    const int ne = disc.points_per_edge();
    const auto& tab = disc.edge_basis();
    struct Acc {
      std::map<int, double> coef;
      double rhs = 0, len = 0;
    };
    std::map<int, Acc> acc;
    auto target = [&](const ContactPoint& c) {  // (v - v_tool) . n = -g / dt
      return tool.velocity().dot(c.projection.normal) - c.projection.gap / dt;
    };
    for (const auto& seg : mesh.boundary_segments()) {
      const auto ia = active.find(seg.a), ib = active.find(seg.b);
      if (ia == active.end() || ib == active.end()) continue;
      const auto& edge = edges[static_cast<std::size_t>(seg.edge)];
      for (int k = 0; k < ne; ++k) {
        const int ge = seg.edge * ne + k;
        const double s = disc.edge_parameter(k);
        const double w = disc.edge_weights()(ge);
        const int ends[2] = {edge.a, edge.b};
        const double hat[2] = {1.0 - s, s};
        const auto nodes = tab.nodes(ge);
        const auto p = tab.values(ge);
        for (int e = 0; e < 2; ++e) {
          const ContactPoint& c = *active[ends[e]];
          const Eigen::Vector2d& n = c.projection.normal;
          Acc& r = acc[ends[e]];
          for (std::size_t j = 0; j < nodes.size(); ++j) {
            if (p[j] == 0.0) continue;
            for (int cc = 0; cc < 2; ++cc)
              if (n[cc] != 0.0) r.coef[velocity_dof(nodes[j], cc)] += w * hat[e] * p[j] * n[cc];
          }
          r.rhs += w * hat[e] * target(c);
          r.len += w * hat[e];
        }
      }
    }
    for (const auto& [node, cp] : active) {
      const Eigen::Vector2d& n = cp->projection.normal;
      const bool taken = std::any_of(cs.rows().begin(), cs.rows().end(), [&](const ConstraintRow& r) {
        return r.node == node && std::abs(r.direction.dot(n)) > 1.0 - 1e-12;
      });
      if (taken) continue;
      ConstraintRow row;
      row.part = part;
      row.node = node;
      row.direction = n;
      const auto it = acc.find(node);
      if (it != acc.end()) {
        for (const auto& [dof, c] : it->second.coef) {
          row.dof.push_back(dof);
          row.coef.push_back(c);
        }
        row.rhs = it->second.rhs;
        row.force = it->second.len * n;
      } else {  // isolated contact: the point condition at the node, unit weight
        const auto v = basis.evaluate(Eigen::Vector2d(mesh.nodes().col(node)), false);
        std::map<int, double> c;
        for (std::size_t j = 0; j < v.node.size(); ++j)
          for (int cc = 0; cc < 2; ++cc)
            if (n[cc] != 0.0 && v.p[j] != 0.0) c[velocity_dof(v.node[j], cc)] += v.p[j] * n[cc];
        for (const auto& [dof, cf] : c) {
          row.dof.push_back(dof);
          row.coef.push_back(cf);
        }
        row.rhs = target(*cp);
        row.force = n;
      }
      cs.add(std::move(row));
    }
  }

  /// Active-set update after a solve: releases nodes whose multiplier is
  /// tensile, activates free nodes that would penetrate with the velocity v
  /// (2 x N nodal values). Returns the number of changes.
  int update(const ConstraintSet& cs, int part, const Eigen::VectorXd& X, int n_nodes,
             const Eigen::Matrix2Xd& v, const RigidTool& tool, double dt) {
    std::map<int, double> lambda;
    double lmax = 0.0;
    for (std::size_t i = 0; i < cs.rows().size(); ++i)
      if (cs.rows()[i].part == part) {
        const double l = X[3 * n_nodes + static_cast<Eigen::Index>(i)];
        lambda[cs.rows()[i].node] = l;
        lmax = std::max(lmax, std::abs(l));
      }
    int changes = 0;
    for (auto& c : points_) {
      if (c.active) {
        const auto it = lambda.find(c.node);
        if (it != lambda.end() && it->second > prm_.release_tol * lmax) {
          c.active = false;
          ++changes;
        }
      } else {
        const double g_end =
            c.projection.gap + dt * (v.col(c.node) - tool.velocity()).dot(c.projection.normal);
        if (g_end < -prm_.gap_tol * c.h) {
          c.active = true;
          ++changes;
        }
      }
    }
    return changes;
  }

 private:
  params prm_;
  std::vector<ContactPoint> points_;
};

}  // namespace maxentflow

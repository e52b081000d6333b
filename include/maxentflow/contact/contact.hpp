// maxentflow: rigid-tool contact by Lagrange multipliers (Eqs. 16-17) on the
// workpiece's alpha-shape boundary: detection and the active set of one tool.
#pragma once

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/contact/contact_law.hpp>
#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>

namespace maxentflow {

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
/// What an active node's multipliers impose is the contact law's
/// (contact_law.hpp): the normal condition above, and a tangential one for
/// sticking; the active set reads the normal multipliers only.
class ToolContact {
 public:
  using Mesh = IntegrationMesh<2>;

  struct params {
    double gap_tol = 1e-3;      ///< in contact when g_n <= gap_tol * h_a
    /// Released when Lambda > release_tol * max|Lambda| (tensile). A smaller
    /// tensile multiplier is the weak imposition's noise, not a separation:
    /// e.g. on the axis of an axisymmetric contact, where the plain-arc-length
    /// hat's multiplier carries 2 pi r p and is zero up to that noise (friction
    /// made it flip there every step). Separations seen on E2 start at 0.09.
    double release_tol = 1e-3;
    /// A node released in this step comes back only if it would penetrate by
    /// more than reentry_tol * h_a: without this hysteresis a node at a die
    /// corner can flip between tensile-and-active and free-and-penetrating
    /// forever. The small penetration it may keep is closed at the next step
    /// (the -g/dt term) and stays far inside StepperParams::penetration_tol.
    double reentry_tol = 1e-3;
    /// A node at a tool corner or open end that the velocity guess moves more
    /// than leave_tol * h_a away from the tool during the step starts it free.
    /// Material leaving a die land's exit would otherwise start each such
    /// step in contact there (gap 0), come out tensile and cost an active-set
    /// re-solve: a fifth of E2's nonlinear iterations (docs/method.md section
    /// 8). A node that rounds a die corner moves off by far less (E2: 0.02 h)
    /// and stays for its multiplier to decide.
    double leave_tol = 0.1;
    /// A node within corner_tol * h_a of a concave tool corner (a container's
    /// wall meeting the die face) is held by both faces: the condition of the
    /// face it projects on, and a point condition along the other face's
    /// normal. With one, the nearer face decided, and a node at E2's
    /// dead-zone corner swapped faces every step (a new multiplier, a new
    /// layout, a start 5 % off; docs/method.md section 4).
    double corner_tol = 0.05;
    /// An Eulerian zone's node (ContactPoint::put_back) with a tensile
    /// multiplier is released even inside a contact zone (E2's die land,
    /// where the product's contact carries almost no pressure). false: as
    /// any node, only from a zone's edge. Next to a cutting tool's tip the
    /// hat multipliers oscillate (the tip's node compressive, the next one up
    /// the rake face tensile); released, that node ran into the tool by
    /// 0.03-0.1 h every step, and cost an active-set re-solve each step.
    bool release_put_back = true;
  };

  ToolContact() = default;
  explicit ToolContact(params prm) : prm_(prm) {}
  const params& parameters() const { return prm_; }

  /// Projects every boundary node onto the tool; active: within the gap
  /// tolerance, or predicted to penetrate during dt with the velocity guess
  /// v_guess (2 x N, e.g. the previous step's nodal velocity; may be empty;
  /// a NaN column: no guess for that node, its gap alone decides),
  /// unless at a tool corner and predicted to leave it (params::leave_tol).
  /// put_back (one per node, or empty) marks nodes put back at fixed places
  /// (ContactPoint::put_back) with their state at the end of the last step:
  /// held, in contact also at a tool corner it leaves (its last velocity is a
  /// held node's); free, free unless the guess takes it into the tool, also
  /// on the face (the state the last active set ended in, not the gap of a
  /// node put back on the face).
  void detect(const Mesh& mesh, const RigidTool& tool, const Eigen::Matrix2Xd& v_guess, double dt,
              const std::vector<PutBack>& put_back = {}) {
    points_.clear();
    const auto& x = mesh.nodes();
    const auto& h = mesh.h();
    const auto corners = tool.concave_corners();
    for (int a : mesh.boundary_nodes()) {
      ContactPoint c;
      c.node = a;
      c.h = h(a);
      c.projection = tool.closest(x.col(a));
      const double g = c.projection.gap;
      double g_end = g;
      if (v_guess.cols() == x.cols() && !v_guess.col(a).hasNaN())
        g_end = predicted_gap(tool, x.col(a), v_guess.col(a), dt);
      const PutBack mark =
          static_cast<Eigen::Index>(put_back.size()) == x.cols() ? put_back[static_cast<std::size_t>(a)] : PutBack::no;
      c.put_back = mark != PutBack::no;
      c.active = g <= prm_.gap_tol * h(a) || g_end < 0.0;
      // A node far from the tool (beyond a few h) cannot be reached in one step.
      if (c.projection.distance > 10.0 * h(a) && g > 0) c.active = false;
      if (mark == PutBack::free) c.active = g_end < -prm_.gap_tol * h(a);
      if (c.projection.at_corner && g_end > prm_.leave_tol * h(a) && mark != PutBack::held) c.active = false;
      for (const auto& k : corners)
        if ((x.col(a) - k.point).norm() <= prm_.corner_tol * h(a)) {
          // The first face's condition, whichever face is nearer, and the second's.
          c.projection.normal = k.n_in;
          c.projection.point = k.point;
          c.projection.gap = (x.col(a) - k.point).dot(k.n_in);
          c.second_normal = k.n_out;
        }
      points_.push_back(c);
    }
    std::map<int, int> index;  // node -> position in points_
    for (std::size_t i = 0; i < points_.size(); ++i) index[points_[i].node] = static_cast<int>(i);
    for (const auto& seg : mesh.boundary_segments()) {
      const auto a = index.find(seg.a), b = index.find(seg.b);
      if (a == index.end() || b == index.end()) continue;
      points_[static_cast<std::size_t>(a->second)].next = b->second;
      points_[static_cast<std::size_t>(b->second)].prev = a->second;
    }
  }

  const std::vector<ContactPoint>& points() const { return points_; }
  int active_count() const {
    return static_cast<int>(std::count_if(points_.begin(), points_.end(),
                                          [](const ContactPoint& c) { return c.active; }));
  }

  /// Adds the rows `law` gives the active nodes to `cs` under `part`: hat
  /// multipliers on the segments whose two ends are active, a point condition
  /// at an active node with no active neighbour.
  void add_rows(ConstraintSet& cs, int part, const Mesh& mesh, const FlowDiscretization& disc,
                const MaxEntBasis<2>& basis, const RigidTool& tool, const AnyContactLaw& law,
                double dt) const {
    std::map<int, std::vector<ContactCondition>> cond;  // active node -> its conditions
    for (const auto& c : points_)
      if (c.active) law.conditions(c, tool, dt, cond[c.node]);
    if (cond.empty()) return;
    const std::size_t roles = cond.begin()->second.size();
    for (const auto& [node, list] : cond)
      require(list.size() == roles,
              detail::cat("contact law '", law.name(), "' gave ", list.size(), " conditions at node ", node,
                          " and ", roles, " at node ", cond.begin()->first),
              "ToolContact::add_rows");
    for (std::size_t r = 0; r < roles; ++r) {
      const auto hats = hat_integrals(
          mesh, disc, [&](const BoundarySegment& seg) { return cond.count(seg.a) && cond.count(seg.b); },
          [&](int a) { return cond.at(a)[r].direction; },
          [&](int a, const Eigen::Vector2d&) { return cond.at(a)[r].target; });
      for (const auto& [node, list] : cond) {
        const ContactCondition& k = list[r];
        if (cs.has_parallel_row(node, k.direction)) continue;
        const auto it = hats.find(node);
        ConstraintRow row = it != hats.end() ? ConstraintSet::hat_row(it->second, part, node, k.direction)
                                             : point_row(mesh, basis, part, node, k);
        row.role = k.role;
        cs.add(std::move(row));
      }
    }
    if (roles != 1) return;  // a tangential condition holds the node already
    for (const auto& c : points_) {
      if (!c.active || !c.second_normal) continue;
      ContactPoint second = c;
      second.projection.normal = *c.second_normal;
      second.projection.gap = (mesh.nodes().col(c.node) - c.projection.point).dot(*c.second_normal);
      std::vector<ContactCondition> list;
      law.conditions(second, tool, dt, list);
      if (list.empty() || cs.has_parallel_row(c.node, list[0].direction)) continue;
      ConstraintRow row = point_row(mesh, basis, part, c.node, list[0]);
      // Two rows of one node need two keys (the layout's): faces along the same main axis get none.
      const bool distinct = std::none_of(cs.rows().begin(), cs.rows().end(),
                                         [&](const ConstraintRow& r) { return r.key() == row.key(); });
      if (distinct) cs.add(std::move(row));
    }
  }

  /// A TractionContactLaw's traction on the segments whose two ends are
  /// active, added to sys (a FlowSystem) under `part` (replacing the last).
  template <class System>
  void add_tractions(System& sys, int part, const Mesh& mesh, const RigidTool& tool, const AnyContactLaw& law) const {
    sys.clear_velocity_tractions(part);
    if (!law.has_traction()) return;
    std::vector<char> active(static_cast<std::size_t>(mesh.number_of_nodes()), 0);
    for (const auto& c : points_)
      if (c.active) active[static_cast<std::size_t>(c.node)] = 1;
    const auto& segs = mesh.boundary_segments();
    for (std::size_t s = 0; s < segs.size(); ++s) {
      if (!active[static_cast<std::size_t>(segs[s].a)] || !active[static_cast<std::size_t>(segs[s].b)]) continue;
      // The tool outlives the system's solve (both belong to one step).
      // lambda is the normal multipliers' field: p_n = -lambda, so the
      // law's dt/dp_n enters the system as dt/dlambda = -dt/dp_n (Coulomb
      // returns it that way round).
      sys.add_velocity_traction(
          part, static_cast<int>(s),
          [&tool, law](const TractionPointState& p) {
            ContactTractionPoint q;
            q.x = p.x;
            q.normal = tool.closest(p.x).normal;
            q.v = p.v;
            q.v_tool = tool.velocity();
            q.k = p.k;
            q.p_n = -p.lambda;
            return law.traction(q);
          },
          law.reads_pressure() ? part : -1);
    }
  }

  /// Active-set update after a solve: releases nodes whose multiplier is
  /// tensile, activates free nodes that would penetrate with the velocity v
  /// (2 x N nodal values). Returns the number of changes.
  int update(const ConstraintSet& cs, int part, const Eigen::VectorXd& X, int n_nodes,
             const Eigen::Matrix2Xd& x, const Eigen::Matrix2Xd& v, const RigidTool& tool, double dt) {
    std::map<int, double> lambda;
    double lmax = 0.0;
    for (std::size_t i = 0; i < cs.rows().size(); ++i)
      if (cs.rows()[i].part == part && cs.rows()[i].role == 0) {
        const double l = X[DofLayout::fields_of(n_nodes) + static_cast<Eigen::Index>(i)];
        // A corner node's two rows: it stays while either face presses on it.
        const auto [it, fresh] = lambda.try_emplace(cs.rows()[i].node, l);
        if (!fresh) it->second = std::min(it->second, l);
        lmax = std::max(lmax, std::abs(l));
      }
    int changes = 0;
    changed_.clear();
    // Contact zones open from their edges: a node is released only if it is
    // joined to a free boundary neighbour by a run of nodes that all release.
    // Inside a zone a tensile multiplier is the weak hat imposition's
    // oscillation (e.g. next to a die corner's pressure peak), and releasing
    // it would free both its segments and let them penetrate. A whole run
    // goes in one update: one node per update from the edge could not open a
    // zone that separates along many nodes (material leaving a ram near the
    // end of an extrusion stroke) within the active-set iterations.
    // Decided on the state before this update.
    std::vector<char> releases(points_.size(), 0);
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const ContactPoint& c = points_[i];
      const auto it = lambda.find(c.node);
      // Released at most once per step: a node that the free solve drives
      // back into the tool stays in contact (its multiplier is then only
      // slightly tensile, an artefact of the weak hat imposition).
      releases[i] = c.active && it != lambda.end() && it->second > prm_.release_tol * lmax && c.releases == 0;
    }
    auto edge_side = [&](int j) { return j < 0 || !points_[static_cast<std::size_t>(j)].active; };
    std::vector<char> release(points_.size(), 0);
    for (std::size_t i = 0; i < points_.size(); ++i) {
      if (!releases[i] || release[i]) continue;
      // The run of releasing nodes through i, and whether a free node or an
      // open end bounds it.
      std::vector<std::size_t> run{i};
      bool edge = false;
      for (const bool forward : {false, true}) {
        int j = forward ? points_[i].next : points_[i].prev;
        while (true) {
          if (edge_side(j)) {
            edge = true;
            break;
          }
          const auto k = static_cast<std::size_t>(j);
          if (!releases[k] || k == i) break;  // k == i: a closed loop of releasing nodes
          run.push_back(k);
          j = forward ? points_[k].next : points_[k].prev;
        }
      }
      if (edge) {
        for (std::size_t k : run) release[k] = 1;
      } else if (points_[i].put_back && prm_.release_put_back) {
        release[i] = 1;  // an Eulerian zone's node: no penetration builds up
      }
    }
    for (std::size_t i = 0; i < points_.size(); ++i) {
      ContactPoint& c = points_[i];
      if (c.active) {
        if (release[i]) {
          c.active = false;
          ++c.releases;
          ++changes;
          changed_.push_back(c.node);
        }
      } else if (!(c.put_back && c.releases > 0)) {
        const double g_end = predicted_gap(tool, x.col(c.node), v.col(c.node), dt);
        if (g_end < -(c.releases > 0 ? prm_.reentry_tol : prm_.gap_tol) * c.h) {
          c.active = true;
          ++changes;
          changed_.push_back(c.node);
        }
      }
    }
    return changes;
  }

  /// Nodes whose state the last update() changed.
  const std::vector<int>& changed_nodes() const { return changed_; }

  /// Gap at the end of the step if the node moves with v: the tool's true
  /// shape at the moved relative position, not g + dt (v - v_tool) . n, whose
  /// frozen normal is wrong at a tool corner (a node sliding round a die
  /// corner into the opening would count as penetrating the die face).
  static double predicted_gap(const RigidTool& tool, const Eigen::Vector2d& x, const Eigen::Vector2d& v,
                              double dt) {
    return tool.gap(x + dt * (v - tool.velocity()));
  }

 private:
  // An isolated contact node: the condition at the node itself, unit weight.
  static ConstraintRow point_row(const Mesh& mesh, const MaxEntBasis<2>& basis, int part, int node,
                                 const ContactCondition& k) {
    const auto v = basis.evaluate(Eigen::Vector2d(mesh.nodes().col(node)), false);
    std::map<int, double> c;
    const Eigen::Vector2d& n = k.direction;
    for (std::size_t j = 0; j < v.node.size(); ++j)
      for (int cc = 0; cc < 2; ++cc)
        if (n[cc] != 0.0 && v.p[j] != 0.0) c[velocity_dof(v.node[j], cc)] += v.p[j] * n[cc];
    ConstraintRow row;
    row.part = part;
    row.node = node;
    row.direction = n;
    for (const auto& [dof, cf] : c) {
      row.dof.push_back(dof);
      row.coef.push_back(cf);
    }
    row.rhs = k.target;
    row.force = n;
    return row;
  }

  params prm_;
  std::vector<ContactPoint> points_;
  std::vector<int> changed_;
};

}  // namespace maxentflow

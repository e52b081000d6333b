// maxentflow: the rigid tools of a simulation with their contact state, the
// part of the stepper that owns everything contact (docs/architecture.md).
#pragma once

#include <algorithm>
#include <limits>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/contact/contact.hpp>
#include <maxentflow/contact/contact_law.hpp>
#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/io/checkpoint.hpp>

namespace maxentflow {

/// The tools, each with its contact law and active set, and the multipliers'
/// warm start across configurations. Per configuration: begin() (parts,
/// detection), then add_rows() / update() until the active set settles, then
/// remember() the multipliers; reactions(), snap() and check_penetration()
/// for the post-processing; move() the tools at the end of the step.
class ContactSet {
 public:
  using Mesh = IntegrationMesh<2>;

  explicit ContactSet(ToolContact::params prm = {}) : prm_(prm) {}

  /// Adds a tool with its law (and its own detection and release tolerances);
  /// returns its index.
  int add_tool(RigidTool tool, AnyContactLaw law = Frictionless{}) { return add_tool(std::move(tool), std::move(law), prm_); }
  int add_tool(RigidTool tool, AnyContactLaw law, ToolContact::params prm) {
    tools_.push_back(std::move(tool));
    entries_.push_back({ToolContact(prm), std::move(law), -1});
    return static_cast<int>(tools_.size()) - 1;
  }
  std::size_t size() const { return tools_.size(); }
  const AnyContactLaw& law(std::size_t k) const { return entries_[k].law; }
  /// The tools, in the order they were added.
  const std::vector<RigidTool>& tools() const { return tools_; }

  /// A new configuration: one constraint part per tool ("tool <name>"), each
  /// boundary node projected on each tool, the first active set from the gap
  /// and the velocity guess (2 x N; may be empty). put_back (one per node,
  /// or empty): 0 for a material node, else the node is put back at a fixed
  /// place (ToolContact::detect): 1 + its flag at the end of the last step
  /// (flags(): 0 free, k + 1 on tool k), or -1 where that is unknown.
  void begin(ConstraintSet& cs, const Mesh& mesh, const Eigen::Matrix2Xd& v_guess, double dt,
             const std::vector<int>& put_back = {}) {
    std::vector<PutBack> mask(put_back.size(), PutBack::no);
    for (std::size_t k = 0; k < tools_.size(); ++k) {
      for (std::size_t a = 0; a < put_back.size(); ++a)
        mask[a] = put_back[a] == 0                         ? PutBack::no
                  : put_back[a] < 0                        ? PutBack::unknown
                  : put_back[a] == static_cast<int>(k) + 2 ? PutBack::held
                                                           : PutBack::free;
      entries_[k].part = cs.add_part("tool " + tools_[k].name());
      entries_[k].contact.detect(mesh, tools_[k], v_guess, dt, mask);
    }
  }

  /// Replaces the tools' rows in `cs` with those of the current active sets.
  void add_rows(ConstraintSet& cs, const Mesh& mesh, const FlowDiscretization& disc,
                const MaxEntBasis<2>& basis, double dt) const {
    for (std::size_t k = 0; k < tools_.size(); ++k) {
      const Entry& e = entries_[k];
      cs.clear_part(e.part);
      e.contact.add_rows(cs, e.part, mesh, disc, basis, tools_[k], e.law, dt);
    }
  }

  /// Multipliers of the rows of `cs` (after the `fields` field unknowns of X)
  /// from the last solve that had a row of the same key: a warm-started
  /// Newton then sees only the change.
  void warm_start(const ConstraintSet& cs, Eigen::VectorXd& X, int fields) const {
    const auto& rows = cs.rows();
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto it = lambda_.find(rows[i].key());
      if (it != lambda_.end()) X[fields + static_cast<Eigen::Index>(i)] = it->second;
    }
  }
  /// Keeps the multipliers of a solve for warm_start().
  void remember(const ConstraintSet& cs, const Eigen::VectorXd& X, int fields) {
    lambda_.clear();
    const auto& rows = cs.rows();
    for (std::size_t i = 0; i < rows.size(); ++i)
      lambda_[rows[i].key()] = X[fields + static_cast<Eigen::Index>(i)];
  }

  /// Active-set update after a solve (ToolContact::update on every tool),
  /// with x the nodes and v their velocity (2 x N). Returns the changes.
  int update(const ConstraintSet& cs, const Eigen::VectorXd& X, int n_nodes, const Eigen::Matrix2Xd& x,
             const Eigen::Matrix2Xd& v, double dt) {
    int changes = 0;
    for (std::size_t k = 0; k < tools_.size(); ++k)
      changes += entries_[k].contact.update(cs, entries_[k].part, X, n_nodes, x, v, tools_[k], dt);
    return changes;
  }
  /// The nodes the last update() changed, for an error message.
  std::string last_changes(const Eigen::Matrix2Xd& x) const {
    std::string which;
    for (std::size_t k = 0; k < tools_.size(); ++k)
      for (int a : entries_[k].contact.changed_nodes())
        which += detail::cat(" node ", a, " at (", x(0, a), ", ", x(1, a), ") now ", state(k, a), " on '",
                             tools_[k].name(), "';");
    return which;
  }

  /// The laws' tractions (TractionContactLaw) on each tool's contact
  /// segments, into sys (a FlowSystem); after add_rows().
  template <class System>
  void add_tractions(System& sys, const Mesh& mesh) const {
    for (std::size_t k = 0; k < tools_.size(); ++k)
      entries_[k].contact.add_tractions(sys, entries_[k].part, mesh, tools_[k], entries_[k].law);
  }

  /// The force the workpiece exerts on each tool at X (a solution of sys, a
  /// FlowSystem): its multipliers' and its laws' tractions.
  template <class System>
  std::vector<Eigen::Vector2d> reactions(const System& sys, const Eigen::VectorXd& X) const {
    std::vector<Eigen::Vector2d> f;
    for (const auto& e : entries_)
      f.push_back(sys.constraints().reaction(e.part, X, sys.number_of_nodes()) +
                  sys.velocity_traction_force(e.part, X));
    return f;
  }
  /// Nodal contact fields at X (a solution of sys, a FlowSystem), for
  /// output, on each node active on a tool (zero elsewhere): the contact
  /// pressure p_n, the friction stress |tau| and the slip velocity (the
  /// tangential part of v - v_tool, v the nodal velocity, 2 x N). p_n and a
  /// sticking law's tau come from the node's hat multipliers, per unit area
  /// (Lambda_a int N_a ds / int N_a 2 pi r ds axisymmetric); a traction law's
  /// tau from its Gauss points, lumped with the hats (int N_a |t| / int N_a).
  template <class System>
  void contact_fields(System& sys, const Eigen::VectorXd& X, const Eigen::Matrix2Xd& v, Eigen::VectorXd& p_n,
                      Eigen::VectorXd& tau, Eigen::Matrix2Xd& slip) const {
    const Mesh& mesh = sys.mesh();
    const int N = mesh.number_of_nodes();
    const bool axi = sys.discretization().axisymmetric();
    constexpr double two_pi = 6.283185307179586476925;
    p_n.setZero(N);
    tau.setZero(N);
    slip.setZero(2, N);
    const int nv = DofLayout::fields_of(N);
    const auto& rows = sys.constraints().rows();
    std::vector<char> active(static_cast<std::size_t>(N));
    Eigen::VectorXd len(N), len_r(N);
    for (std::size_t k = 0; k < tools_.size(); ++k) {
      const Entry& e = entries_[k];
      // int N_a ds and int N_a r ds over the tool's contact segments (both ends active).
      std::fill(active.begin(), active.end(), 0);
      for (const auto& c : e.contact.points()) active[static_cast<std::size_t>(c.node)] = c.active;
      len.setZero();
      len_r.setZero();
      for (const auto& seg : mesh.boundary_segments()) {
        if (!active[static_cast<std::size_t>(seg.a)] || !active[static_cast<std::size_t>(seg.b)]) continue;
        const double ra = mesh.nodes()(0, seg.a), rb = mesh.nodes()(0, seg.b);
        len[seg.a] += seg.length / 2;
        len[seg.b] += seg.length / 2;
        len_r[seg.a] += seg.length * (2 * ra + rb) / 6;
        len_r[seg.b] += seg.length * (ra + 2 * rb) / 6;
      }
      // A point row (an isolated contact node) carries a force, not a pressure: 0.
      auto per_area = [&](int a) {
        if (!(len[a] > 0)) return 0.0;
        return axi ? (len_r[a] > 0 ? len[a] / (two_pi * len_r[a]) : 0.0) : 1.0;
      };
      std::vector<char> seen(static_cast<std::size_t>(N), 0);
      for (std::size_t i = 0; i < rows.size(); ++i) {
        const ConstraintRow& r = rows[i];
        if (r.part != e.part || r.node < 0) continue;
        const double lambda = X[nv + static_cast<Eigen::Index>(i)] * per_area(r.node);
        if (r.role != 0) tau[r.node] = std::abs(lambda);
        else if (!seen[static_cast<std::size_t>(r.node)]++) p_n[r.node] = -lambda;  // a corner's second row: a force
      }
      for (const auto& c : e.contact.points())
        if (c.active) {
          const Eigen::Vector2d& n = c.projection.normal;
          const Eigen::Vector2d dv = v.col(c.node) - tools_[k].velocity();
          slip.col(c.node) = dv - dv.dot(n) * n;
        }
      if (!e.law.has_traction()) continue;
      Eigen::VectorXd num = Eigen::VectorXd::Zero(N), den = Eigen::VectorXd::Zero(N);
      for (const auto& smp : sys.velocity_traction_samples(e.part, X))
        for (int j = 0; j < 2; ++j) {
          num[smp.end[j]] += smp.hat[j] * smp.w * smp.t.norm();
          den[smp.end[j]] += smp.hat[j] * smp.w;
        }
      for (int a = 0; a < N; ++a)
        if (den[a] > 0) tau[a] = num[a] / den[a];
    }
  }
  std::vector<double> strokes() const {
    std::vector<double> s;
    for (const auto& t : tools_) s.push_back(t.stroke());
    return s;
  }
  /// flag[a] = k + 1 for a node active on tool k, else 0; returns the active count.
  int flags(std::vector<int>& flag) const {
    std::fill(flag.begin(), flag.end(), 0);
    int count = 0;
    for (std::size_t k = 0; k < tools_.size(); ++k)
      for (const auto& c : entries_[k].contact.points())
        if (c.active) {
          flag[static_cast<std::size_t>(c.node)] = static_cast<int>(k) + 1;
          ++count;
        }
    return count;
  }

  /// Active nodes within snap_tol * max(h_a, h_mean) of their tool end the step
  /// on it: the weak imposition leaves scatter that would make a flat contact
  /// face jagged and the max-ent dual stiff there (StepperParams::snap_tol).
  void snap(Eigen::Matrix2Xd& x, double h_mean, double snap_tol) const {
    for (std::size_t k = 0; k < tools_.size(); ++k)
      for (const auto& c : entries_[k].contact.points()) {
        if (!c.active) continue;
        const ToolProjection pr = tools_[k].closest(x.col(c.node));
        // Outside a corner the closest point is the vertex: snapping would
        // pull a node that rounds a die corner back onto it.
        if (pr.at_corner && pr.gap > 0.0) continue;
        if (std::abs(pr.gap) <= snap_tol * std::max(c.h, h_mean)) x.col(c.node) -= pr.gap * pr.normal;
      }
  }
  /// Throws if a boundary node of `mesh` at its position in x is deeper than
  /// tol * max(h_a, h_mean) in a tool.
  void check_penetration(const Mesh& mesh, const Eigen::Matrix2Xd& x, double tol, double h_mean) const {
    for (std::size_t k = 0; k < tools_.size(); ++k)
      for (int a : mesh.boundary_nodes()) {
        const double g = tools_[k].gap(x.col(a));
        MAXENTFLOW_REQUIRE(g >= -tol * std::max(mesh.h()(a), h_mean),
                           detail::cat("node ", a, " at (", x(0, a), ", ", x(1, a), ") penetrates tool '",
                                       tools_[k].name(), "' by ", -g, " (", -g / mesh.h()(a),
                                       " h; it was ", state(k, a), " in this step)"),
                           "ContactSet::check_penetration");
      }
  }
  /// How deep p lies inside the tools (the largest -gap; <= 0 outside all).
  double depth(const Eigen::Vector2d& p) const {
    double d = -std::numeric_limits<double>::infinity();
    for (const auto& t : tools_) d = std::max(d, -t.gap(p));
    return d;
  }
  /// Whether the segment a-b passes through a tool (RigidTool::crosses).
  bool crossed(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
    return std::any_of(tools_.begin(), tools_.end(), [&](const RigidTool& t) { return t.crosses(a, b); });
  }
  /// The tools' sharp convex corners, where they are now.
  std::vector<Eigen::Vector2d> convex_corners() const {
    std::vector<Eigen::Vector2d> c;
    for (const auto& t : tools_) {
      const auto tc = t.convex_corners();
      c.insert(c.end(), tc.begin(), tc.end());
    }
    return c;
  }
  /// True if p is outside every tool (where rezoning may put a node).
  bool admissible(const Eigen::Vector2d& p) const {
    return std::all_of(tools_.begin(), tools_.end(), [&](const RigidTool& t) { return t.gap(p) >= 0; });
  }

  void move(double dt) {
    for (auto& t : tools_) t.move(dt);
  }
  std::vector<Eigen::Vector2d> displacements() const {
    std::vector<Eigen::Vector2d> d;
    for (const auto& t : tools_) d.push_back(t.displacement());
    return d;
  }
  /// Puts the tools back where displacements() saw them (a failed step).
  void restore(const std::vector<Eigen::Vector2d>& d) {
    for (std::size_t k = 0; k < tools_.size(); ++k) tools_[k].translate(d[k] - tools_[k].displacement());
  }
  /// Node renumbering (rezoning): old node a is old_to_new[a] (-1: removed).
  void renumber(const std::vector<int>& old_to_new) {
    std::map<std::uint64_t, double> moved;
    for (const auto& [k, l] : lambda_) {
      const int b = old_to_new[static_cast<std::size_t>(DofLayout::key_node(k))];
      if (b >= 0) moved[DofLayout::with_node(k, b)] = l;
    }
    lambda_.swap(moved);
  }

  /// The state a step carries to the next, for a checkpoint: each tool's
  /// displacement and velocity, the multipliers' warm start. load() needs the
  /// same tools (names, order) added, as the run that wrote it had.
  void save(CheckpointOut& out) const {
    out.put(static_cast<std::int64_t>(tools_.size()));
    for (const auto& t : tools_) out.put(t.name()).put(t.displacement()).put(t.velocity());
    out.put(static_cast<std::int64_t>(lambda_.size()));
    for (const auto& [k, l] : lambda_) out.put(static_cast<std::int64_t>(k)).put(l);
  }
  void load(CheckpointIn& in) {
    const auto n = static_cast<std::size_t>(in.get_count());
    if (n != tools_.size()) in.fail(detail::cat(n, " tools, this run has ", tools_.size()));
    for (auto& t : tools_) {
      const std::string name = in.get_string();
      const Eigen::MatrixXd d = in.get_matrix(), v = in.get_matrix();
      if (name != t.name() || d.size() != 2 || v.size() != 2)
        in.fail(detail::cat("tool '", name, "' where this run has '", t.name(), "'"));
      t.translate(Eigen::Vector2d(d(0), d(1)) - t.displacement());
      t.set_velocity(Eigen::Vector2d(v(0), v(1)));
    }
    lambda_.clear();
    for (auto m = in.get_count(); m > 0; --m) {
      const auto key = static_cast<std::uint64_t>(in.get_int());
      lambda_[key] = in.get_double();
    }
  }

  /// "in contact", "free" or "not on the boundary" (node a on tool k, this configuration).
  const char* state(std::size_t k, int a) const {
    for (const auto& c : entries_[k].contact.points())
      if (c.node == a) return c.active ? "in contact" : "free";
    return "not on the boundary";
  }

 private:
  struct Entry {
    ToolContact contact;
    AnyContactLaw law;
    int part;  // its constraint part in the current configuration
  };
  ToolContact::params prm_;
  std::vector<RigidTool> tools_;
  std::vector<Entry> entries_;  // per tool
  std::map<std::uint64_t, double> lambda_;  // last multipliers by row key
};

}  // namespace maxentflow

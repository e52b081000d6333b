// maxentflow: the updated-Lagrangian forming simulation (Eq. 18): per step,
// Delaunay + alpha-shape, max-ent basis, contact active set + flow solve,
// x += v dt, tools move.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/contact/contact_law.hpp>
#include <maxentflow/contact/contact_set.hpp>
#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/flow/flow_system.hpp>
#include <maxentflow/io/checkpoint.hpp>
#include <maxentflow/material/norton_hoff.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>
#include <maxentflow/solver/nonlinear_solver.hpp>
#include <maxentflow/stepper/eulerian_zone.hpp>
#include <maxentflow/stepper/nodal_fields.hpp>
#include <maxentflow/stepper/node_adaptivity.hpp>

namespace maxentflow {

/// Where the next step's solve starts (the nodes carry coefficients, so
/// both are a per-node velocity and pressure):
/// - material: this step's coefficients as they are (right when a material
///   point's velocity changes slowly, e.g. upsetting);
/// - spatial: this step's field at the node's new position,
///   V_a + f(x_a + dt v_a) - f(x_a), right for a flow that is steady where the
///   tools are (extrusion, cutting): a node entering the die picks up the
///   die's velocity instead of keeping the container's;
/// - extrapolated: material, extrapolated linearly in time from the last two
///   steps, V + (dt / dt_last)(V - V_last): right when a material point's
///   velocity changes steadily (upsetting: the exact start to O(dt^2)).
enum class Predictor { material, spatial, extrapolated };

/// How the nodes move with the velocities of the steps (the material path):
/// - euler: Eq. (18), x += dt v, first order: a run loses area (volume) as
///   O(dt) (E1: 0.5 %, E2: 1.75 % over the stroke);
/// - adams_bashforth2: x += dt ((1 + r/2) v - (r/2) v_last), r = dt / dt_last,
///   with v_last the node's velocity in the step before (variable-step AB2):
///   second order along the path, with velocities the run already has (no
///   extra solve). The first step, and a node with no history, use euler.
enum class NodeUpdate { euler, adams_bashforth2 };

struct StepperParams {
  Geometry geometry = Geometry::plane_strain;
  double dt = 1.0;
  double gamma = 1.6;                            ///< max-ent locality, beta_a = gamma / h_a^2
  /// Max-ent support cut-off on the prior weight (MaxEntBasis params tol0;
  /// support radius h sqrt(-ln tol0 / gamma): 2.94 h at 1e-6, 2.40 h at 1e-4
  /// for gamma 1.6). The smaller support at 1e-4 thins the system by a third
  /// and moves E2's step-1 profiles by < 4e-5 and E3's first forces by < 0.1 %
  /// against 1e-6; 1e-3 moves E2's ram force by 3.5 % (docs/method.md, 7).
  double tol0 = 1e-4;
  IntegrationMesh<2>::params mesh;       ///< alpha-shape (alpha = 1.3 h)
  FlowDiscretizationParams discretization;
  StabilizationParams stabilization;             ///< Cs
  NonlinearSolverParams solver;
  ToolContact::params contact;
  int max_active_set_iterations = 12;
  /// The contact active set is first checked on a solve converged only to this
  /// (relative velocity increment and residual); the solve is finished to the
  /// solver's tolerances once the set holds there, and checked again. Solves
  /// that an active-set change throws away then cost a few Newton iterations,
  /// not a whole solve. 0: every check on a fully converged solve.
  double active_set_tol = 1e-2;
  int max_retries = 4;          ///< dt halvings before a failed step stops the run (HalvingRetry)
  /// A node deeper than this * h in a tool fails the step. h here and in
  /// snap_tol is max(h_a, mean h): nodes crowding into a die corner get a
  /// small h_a that would make the tolerances vanish.
  double penetration_tol = 0.05;
  /// Active contact nodes within snap_tol * h of their tool end the step on it:
  /// the hat multipliers impose (v - v_tool) . n = -g / dt on average over a
  /// node's segments, so next to a die corner's pressure peak a node can miss
  /// the tool: measured on E2 up to 6 % of h (16 x 16 nodes), and 0.32 h_a
  /// for a node crossing the die corner onto the land (32 x 32).
  double snap_tol = 0.5;
  /// Node rezoning at the start of each step after the first (off by default;
  /// see node_adaptivity.hpp). h0 is the first configuration's h_a.
  NodeAdaptivityParams adapt;
  Predictor predictor = Predictor::extrapolated;
  NodeUpdate node_update = NodeUpdate::adams_bashforth2;

  /// Throws Error naming the first parameter out of range (NaN, inf, sign,
  /// bounds); `where` says who asked. The nested parameters of the mesh,
  /// basis, assembler and rezoning are checked where those are built.
  void validate(const std::string& where) const {
    auto positive = [&](double v, const char* name) {
      require(std::isfinite(v) && v > 0, detail::cat(name, " must be finite and > 0, got ", v), where);
    };
    auto non_negative = [&](double v, const char* name) {
      require(std::isfinite(v) && v >= 0, detail::cat(name, " must be finite and >= 0, got ", v), where);
    };
    positive(dt, "dt");
    positive(gamma, "gamma");
    require(std::isfinite(tol0) && tol0 > 0 && tol0 < 1, detail::cat("tol0 must lie in (0, 1), got ", tol0), where);
    require(max_active_set_iterations >= 1,
            detail::cat("max_active_set_iterations must be >= 1, got ", max_active_set_iterations), where);
    require(max_retries >= 0, detail::cat("max_retries must be >= 0, got ", max_retries), where);
    positive(penetration_tol, "penetration_tol");
    non_negative(snap_tol, "snap_tol");
    non_negative(contact.gap_tol, "contact.gap_tol");
    non_negative(contact.release_tol, "contact.release_tol");
    non_negative(contact.reentry_tol, "contact.reentry_tol");
    non_negative(contact.leave_tol, "contact.leave_tol");
    non_negative(active_set_tol, "active_set_tol");
    positive(solver.velocity_tol, "solver.velocity_tol");
    positive(solver.residual_tol, "solver.residual_tol");
    require(solver.max_iterations >= 1, detail::cat("solver.max_iterations must be >= 1, got ", solver.max_iterations),
            where);
  }
};

/// What one step did (also one line of the progress log).
struct StepRecord {
  int step = 0;
  double time = 0.0;      ///< at the end of the step
  double dt = 0.0;        ///< the step's size
  int substeps = 1;       ///< > 1 if the step was retried with a smaller dt
  int picard = 0, newton = 0, active_set_iterations = 0;
  int linear_iterations = 0;  ///< Krylov iterations (0 with a direct solver)
  int max_linear_iterations = 0;  ///< Krylov iterations of the step's longest solve
  int preconditioner_updates = 0, direct_fallbacks = 0;  ///< see SolveReport
  int contact_nodes = 0;
  int nodes = 0;                            ///< nodes in the step's configuration
  int nodes_added = 0, nodes_removed = 0;   ///< by the rezoning before the step
  bool zone_active = false;  ///< the Eulerian zone's nodes were put back before the step
  std::vector<Eigen::Vector2d> tool_force;  ///< force on each tool, configuration at the step start
  std::vector<double> tool_stroke;          ///< each tool's travel at the step start
  /// The solve's power balance (FlowSystem::power_balance), and the power the
  /// tools deliver, -sum_k f_k . v_k: the loads' work rate, which differs from
  /// power.constraints by the prescribed velocities' and the gap closure's.
  PowerBalance power;
  double tool_power = 0.0;
  double seconds = 0.0, mesh_seconds = 0.0, basis_seconds = 0.0, solve_seconds = 0.0,
         post_seconds = 0.0;
  /// Parts of solve_seconds: assembly (A, R, preconditioner), factorization, linear solves.
  double assembly_seconds = 0.0, factorization_seconds = 0.0, linear_seconds = 0.0;
  std::string note;  ///< retries and their reasons
  /// What the step degraded instead of failing (each also in `degraded`, and
  /// logged the first time it happens in a run):
  /// nodes whose spatial predictor could not be evaluated (x + dt v beyond the
  /// configuration's hull, e.g. a free surface moving outward) and kept the
  /// material one;
  int predictor_fallbacks = 0;
  /// the nodal strain rate came from the Gauss points because the basis'
  /// gradients at the nodes failed (a sharp spike of the free surface).
  bool nodal_gradient_fallback = false;
  std::string degraded;  ///< what was degraded, and why; empty if nothing
};

/// Step control (as odeint's controlled steppers): how a step that failed is
/// tried again. substeps(f) is the number of equal substeps of the attempt
/// after f failures (1 for the first attempt), 0 to give up.
template <class C>
concept StepControl = requires(const C& c, int failures) {
  { c.substeps(failures) } -> std::convertible_to<int>;
};

/// The default: a failed step is done again as 2, 4, ... substeps, up to
/// max_retries halvings (StepperParams::max_retries).
struct HalvingRetry {
  int max_retries = 4;
  int substeps(int failures) const { return failures <= max_retries ? 1 << failures : 0; }
};

/// A fixed velocity condition v . e = value on the boundary chosen by a selector,
/// re-applied on each configuration (symmetry lines, the axis, a clamped edge).
struct VelocityCondition {
  std::string name;
  SegmentSelector select;
  Eigen::Vector2d direction;
  double value = 0.0;
};

/// The forming simulation: nodes that carry the material, rigid tools that move.
/// Composes IntegrationMesh, MaxEntBasis, FlowDiscretization, FlowSystem<Material>
/// (StabilizedFlowAssembler + constraints), a ContactSet (tools, their contact
/// laws and active sets), NonlinearSolver<Linear> and a StepControl.
template <ViscosityLaw Material, LinearSolverPolicy Linear = GmresSolver<>, StepControl Control = HalvingRetry>
class Stepper {
 public:
  using Mesh = IntegrationMesh<2>;
  using Basis = MaxEntBasis<2>;

  Stepper(Eigen::Matrix2Xd nodes, Material material, StepperParams prm)
      : Stepper(std::move(nodes), std::move(material), prm, default_control(prm)) {}
  Stepper(Eigen::Matrix2Xd nodes, Material material, StepperParams prm, Control control)
      : prm_(std::move(prm)), material_(std::move(material)), control_(std::move(control)), x_(std::move(nodes)) {
    prm_.validate("Stepper");
    require(x_.cols() >= 3, detail::cat("a workpiece needs at least 3 nodes, got ", x_.cols()), "Stepper");
    for (Eigen::Index a = 0; a < x_.cols(); ++a)
      require(x_.col(a).allFinite(), detail::cat("node ", a, " has a non-finite coordinate"), "Stepper");
    const auto n = x_.cols();
    fields_ = NodalFields(n);
    k_.coef = fields_.add("coefficients", DofLayout::per_node, false);
    k_.coef_last = fields_.add("coefficients_last", DofLayout::per_node, false);
    k_.velocity = fields_.add("velocity", 2);
    k_.velocity_last = fields_.add("velocity_last", 2, false);
    k_.pressure = fields_.add("pressure", 1);
    k_.strain_rate = fields_.add("strain_rate", 1);
    k_.strain = fields_.add("effective_strain", 1);
    k_.h0 = fields_.add("h0", 1, false);
    // On the nodes in contact with a tool (zero elsewhere; ContactSet::contact_fields).
    k_.contact_pressure = fields_.add("contact_pressure", 1);
    k_.friction_stress = fields_.add("friction_stress", 1);
    k_.slip = fields_.add("slip_velocity", 2);
    contact_flag_.assign(static_cast<std::size_t>(n), 0);
  }

  /// Adds a rigid tool with its contact law (any ContactLaw; frictionless by default).
  int add_tool(RigidTool tool, AnyContactLaw law = Frictionless{}) {
    return contact_.add_tool(std::move(tool), std::move(law), prm_.contact);
  }
  void add_velocity_condition(VelocityCondition c) { conditions_.push_back(std::move(c)); }
  /// Makes a region fixed to the tools Eulerian (eulerian_zone.hpp): once
  /// the material fills it, its nodes are put back at the zone's nodes at
  /// the start of every step. Before the first step; the nodes carry which
  /// zone node they are in the nodal field "zone_node" (checkpointed).
  void set_eulerian_zone(EulerianZone zone) {
    require(step_ == 0, "an Eulerian zone is set before the first step", "Stepper::set_eulerian_zone");
    require(!zone_, "the stepper has an Eulerian zone already", "Stepper::set_eulerian_zone");
    zone.validate("Stepper::set_eulerian_zone");
    require(zone.tool < static_cast<int>(contact_.size()),
            detail::cat("the Eulerian zone moves with tool ", zone.tool, " but the stepper has ", contact_.size(),
                        " tools (add the tool first)"),
            "Stepper::set_eulerian_zone");
    Mesh m(prm_.mesh);
    m.build(zone.nodes);
    zone_h0_ = m.h();
    zone_ = std::move(zone);
    k_.zone = fields_.add("zone_node", 1, false);
    k_.zone_start = fields_.add("zone_start", DofLayout::per_node, false);
  }
  const std::optional<EulerianZone>& eulerian_zone() const { return zone_; }
  void set_log(std::ostream* log) { log_ = log; }

  const StepperParams& parameters() const { return prm_; }
  StepperParams& parameters() { return prm_; }
  const Material& material() const { return material_; }
  const Eigen::Matrix2Xd& nodes() const { return x_; }
  double time() const { return time_; }
  int steps_done() const { return step_; }
  const std::vector<RigidTool>& tools() const { return contact_.tools(); }
  const ContactSet& contact() const { return contact_; }
  const Control& step_control() const { return control_; }
  const std::vector<StepRecord>& history() const { return history_; }

  // Fields of the last solved configuration (the one at the start of the last
  // step; `nodes_solved()` are its positions).
  const Eigen::Matrix2Xd& nodes_solved() const { return x_solved_; }
  const Mesh& mesh() const {
    require(mesh_ != nullptr, "no step solved yet (or none since a restart)", "Stepper::mesh");
    return *mesh_;
  }
  const Eigen::MatrixXd& velocity() const { return fields_[k_.velocity]; }  ///< 2 x N
  Eigen::Map<const Eigen::VectorXd> pressure() const { return fields_.flat(k_.pressure); }
  Eigen::Map<const Eigen::VectorXd> strain_rate() const { return fields_.flat(k_.strain_rate); }
  /// Effective (equivalent) plastic strain accumulated at the nodes, int d dt.
  Eigen::Map<const Eigen::VectorXd> effective_strain() const { return fields_.flat(k_.strain); }
  /// Every per-node field (the stepper's and those added), as written to the VTU.
  const NodalFields& nodal_fields() const { return fields_; }
  /// Registers a field the nodes carry (a state a law or the user keeps):
  /// saved with each step, transferred on rezoning, written to the VTU if
  /// `output`. Its values: nodal_field(name), components x N.
  int add_nodal_field(const std::string& name, int components, bool output = true, double init = 0.0) {
    return fields_.add(name, components, output, init);
  }
  Eigen::MatrixXd& nodal_field(const std::string& name) { return fields_[name]; }
  const Eigen::MatrixXd& nodal_field(const std::string& name) const { return fields_[name]; }
  /// 0: free, k + 1: in contact with tool k (last solved configuration).
  const std::vector<int>& contact_flags() const { return contact_flag_; }
  /// Velocity and pressure of the last solve at points of its configuration
  /// (inside or on the alpha-shape's hull), rows v_x, v_y, p: sum_a p_a(x) X_a.
  /// For profiles along lines (the paper's Fig. 7).
  Eigen::Matrix3Xd fields_at(const Eigen::Matrix2Xd& points) const {
    require(basis_ != nullptr, "no step solved yet", "Stepper::fields_at");
    const BasisTable<2> t = basis_->evaluate(points, false);
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, points.cols());
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      f.col(i) = interpolate_fields(t.nodes(static_cast<int>(i)), t.values(static_cast<int>(i)), X_);
    return f;
  }
  /// The unknowns of the last solve (velocity and pressure coefficients, multipliers).
  const Eigen::VectorXd& solution() const { return X_; }

  /// One step of dt; a failed attempt (no convergence, inverted or penetrating
  /// configuration) is retried as two half steps, up to max_retries halvings.
  /// Throws Error if it cannot recover; the state is then that of the step start.
  const StepRecord& step() {
    prm_.validate(detail::cat("Stepper::step ", step_ + 1, " (parameters() changed)"));
    const auto t0 = std::chrono::steady_clock::now();
    StepRecord rec;
    rec.step = step_ + 1;
    rec.dt = prm_.dt;
    if ((prm_.adapt.enabled || zone_) && h0_set_) rezone(rec);
    rec.nodes = static_cast<int>(x_.cols());
    const State saved = save();
    std::string failures;
    for (int failed = 0;; ++failed) {
      const int sub = control_.substeps(failed);
      if (sub <= 0)
        throw Error(detail::cat("step ", step_ + 1, " failed after ", failed, " attempts:\n", failures),
                    "Stepper::step");
      try {
        StepRecord r = rec;
        r.substeps = sub;
        for (int k = 0; k < sub; ++k) advance(prm_.dt / sub, r, k == 0);
        rec = r;
        break;
      } catch (const Error& e) {
        restore(saved);
        failures += detail::cat("  attempt with dt/", sub, " failed: ", e.what(), "\n");
      }
    }
    rec.note = failures;
    ++step_;
    rec.time = time_;
    rec.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    history_.push_back(rec);
    if (log_) print(*log_, rec) << std::flush;  // a progress line is seen as the step ends, also in a file
    return history_.back();
  }

  /// The run's state at the end of the last step, for a restart: nodes, every
  /// nodal field (coefficients, effective strain, h0, ...), the tools'
  /// positions and velocities, the multipliers' warm start, time, step, dt
  /// and the step history. It also drops the solver's carried factorizations
  /// (they only precondition, but they steer the iterates): the run that goes
  /// on and one restarted from this state then take the same path, bitwise.
  void save(CheckpointOut& out) {
    out.put("Stepper").put(step_).put(time_).put(prm_.dt).put(dt_last_).put(ab_ratio_).put(h0_set_);
    out.put(x_).put(contact_flag_);
    fields_.save(out);
    contact_.save(out);
    out.put(static_cast<std::int64_t>(history_.size()));
    for (const auto& r : history_) save_record(out, r);
    solver_.reset();
  }
  /// Restores what save() wrote into a stepper set up as the run that wrote
  /// it (same tools, conditions and nodal fields); the next step() goes on
  /// from there. Throws Error (and changes nothing) on a checkpoint that does
  /// not fit.
  void load(CheckpointIn& in) {
    if (in.get_string() != "Stepper") in.fail("no stepper state here");
    // Read whole before anything changes: a failure leaves the stepper as it was.
    const int step = static_cast<int>(in.get_count());
    const double time = in.get_double(), dt = in.get_double(), dt_last = in.get_double(), ab_ratio = in.get_double();
    const bool h0_set = in.get_bool();
    const Eigen::MatrixXd x = in.get_matrix();
    if (x.rows() != 2 || x.cols() < 3 || !x.allFinite()) in.fail("node positions are not a finite 2 x N cloud");
    std::vector<int> flag = in.get_ints();
    NodalFields fields = fields_;
    fields.load(in);
    if (fields.nodes() != x.cols() || flag.size() != static_cast<std::size_t>(x.cols()))
      in.fail("nodal fields and nodes disagree in number");
    ContactSet contact = contact_;
    contact.load(in);
    std::vector<StepRecord> history;
    for (auto n = in.get_count(); n > 0; --n) history.push_back(load_record(in));
    StepperParams prm = prm_;
    prm.dt = dt;
    prm.validate("Stepper::load");
    prm_ = prm;
    step_ = step;
    time_ = time;
    dt_last_ = dt_last;
    ab_ratio_ = ab_ratio;
    h0_set_ = h0_set;
    x_ = x;
    contact_flag_ = std::move(flag);
    fields_ = std::move(fields);
    contact_ = std::move(contact);
    history_ = std::move(history);
    solver_.reset();
    mesh_.reset();
    basis_.reset();
  }

  /// One progress line: step, time, strokes, iterations, contact, forces, wall time.
  static std::ostream& print(std::ostream& os, const StepRecord& r) {
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "step %4d  t %-9.4g dt %-8.3g picard %2d newton %2d krylov %4d  as %d  contact %3d",
                  r.step, r.time, r.dt / r.substeps, r.picard, r.newton, r.linear_iterations,
                  r.active_set_iterations, r.contact_nodes);
    os << buf;
    for (std::size_t k = 0; k < r.tool_force.size(); ++k) {
      std::snprintf(buf, sizeof buf, "  [%zu] stroke %.4g F (%.5g, %.5g)", k, r.tool_stroke[k],
                    r.tool_force[k].x(), r.tool_force[k].y());
      os << buf;
    }
    if (r.nodes_added || r.nodes_removed) {
      std::snprintf(buf, sizeof buf, "  nodes %d (+%d -%d)", r.nodes, r.nodes_added, r.nodes_removed);
      os << buf;
    }
    std::snprintf(buf, sizeof buf, "  %.3f s%s\n", r.seconds, r.substeps > 1 ? "  (retried)" : "");
    return os << buf;
  }

 private:
  static Control default_control(const StepperParams& prm) {
    if constexpr (std::same_as<Control, HalvingRetry>)
      return HalvingRetry{prm.max_retries};
    else
      return Control{};
  }

  struct State {
    Eigen::Matrix2Xd x;
    NodalFields fields;
    std::vector<Eigen::Vector2d> tool_disp;
    double time, dt_last;
    bool h0_set;
  };
  State save() const { return {x_, fields_, contact_.displacements(), time_, dt_last_, h0_set_}; }
  void restore(const State& s) {
    x_ = s.x;
    fields_ = s.fields;
    dt_last_ = s.dt_last;
    h0_set_ = s.h0_set;
    time_ = s.time;
    contact_.restore(s.tool_disp);
  }

  static void save_record(CheckpointOut& out, const StepRecord& r) {
    out.put(r.step).put(r.time).put(r.dt).put(r.substeps).put(r.picard).put(r.newton).put(r.active_set_iterations);
    out.put(r.linear_iterations).put(r.max_linear_iterations).put(r.preconditioner_updates).put(r.direct_fallbacks);
    out.put(r.contact_nodes).put(r.nodes).put(r.nodes_added).put(r.nodes_removed);
    Eigen::Matrix2Xd f(2, static_cast<Eigen::Index>(r.tool_force.size()));
    for (std::size_t k = 0; k < r.tool_force.size(); ++k) f.col(static_cast<Eigen::Index>(k)) = r.tool_force[k];
    out.put(f).put(Eigen::Map<const Eigen::VectorXd>(r.tool_stroke.data(), static_cast<Eigen::Index>(r.tool_stroke.size())));
    out.put(r.power.plastic).put(r.power.volumetric).put(r.power.constraints).put(r.power.tractions).put(r.tool_power);
    out.put(r.seconds).put(r.mesh_seconds).put(r.basis_seconds).put(r.solve_seconds).put(r.post_seconds);
    out.put(r.assembly_seconds).put(r.factorization_seconds).put(r.linear_seconds);
    out.put(r.note).put(r.predictor_fallbacks).put(r.nodal_gradient_fallback).put(r.degraded).put(r.zone_active);
  }
  static StepRecord load_record(CheckpointIn& in) {
    StepRecord r;
    auto i = [&] { return static_cast<int>(in.get_int()); };
    r.step = i();
    r.time = in.get_double();
    r.dt = in.get_double();
    r.substeps = i(), r.picard = i(), r.newton = i(), r.active_set_iterations = i();
    r.linear_iterations = i(), r.max_linear_iterations = i(), r.preconditioner_updates = i(), r.direct_fallbacks = i();
    r.contact_nodes = i(), r.nodes = i(), r.nodes_added = i(), r.nodes_removed = i();
    const Eigen::MatrixXd f = in.get_matrix(), stroke = in.get_matrix();
    if (f.rows() != 2 || stroke.size() != f.cols()) in.fail("a step record's tool forces and strokes disagree");
    for (Eigen::Index k = 0; k < f.cols(); ++k) {
      r.tool_force.emplace_back(f(0, k), f(1, k));
      r.tool_stroke.push_back(stroke(k));
    }
    for (double* d : {&r.power.plastic, &r.power.volumetric, &r.power.constraints, &r.power.tractions, &r.tool_power})
      *d = in.get_double();
    for (double* d : {&r.seconds, &r.mesh_seconds, &r.basis_seconds, &r.solve_seconds, &r.post_seconds,
                      &r.assembly_seconds, &r.factorization_seconds, &r.linear_seconds})
      *d = in.get_double();
    r.note = in.get_string();
    r.predictor_fallbacks = i();
    r.nodal_gradient_fallback = in.get_bool();
    r.degraded = in.get_string();
    r.zone_active = in.get_bool();
    return r;
  }

  using clock = std::chrono::steady_clock;
  static double since(clock::time_point t) {
    return std::chrono::duration<double>(clock::now() - t).count();
  }

  // One configuration of the nodes: its integration mesh and free surface,
  // max-ent basis, quadrature, and the basis at the nodes (for nodal fields).
  struct Configuration {
    std::shared_ptr<Mesh> mesh;
    std::shared_ptr<Basis> basis;
    std::shared_ptr<FlowDiscretization> disc;
    BasisTable<2> at_nodes;
  };

  // The algorithm of one step (Eq. 18 and the section on the time stepping):
  // configuration x_ -> flow solve with the contact active set -> loads and
  // nodal fields -> nodes and tools move by dt.
  void advance(double dt, StepRecord& rec, bool first) {
    const Configuration cfg = build_configuration(rec);
    auto t = clock::now();
    FlowSystem<Material> sys(*cfg.mesh, *cfg.disc, material_, prm_.stabilization);
    for (const auto& c : conditions_)
      sys.constraints().add_velocity(*cfg.mesh, *cfg.disc, c.select, c.direction,
                                     [v = c.value](const Eigen::Vector2d&) { return v; }, c.name);
    Eigen::VectorXd X;
    Eigen::Matrix2Xd v;
    solve_with_active_set(cfg, sys, dt, rec, X, v);
    rec.solve_seconds += since(t);
    t = clock::now();
    if (first) record_loads(sys, X, rec);
    keep_solution(cfg, sys, X, v, dt);
    move_nodes(cfg, X, v, dt, rec);
    rec.post_seconds += since(t);
  }

  // Mesh (Delaunay + alpha-shape), basis and quadrature of the nodes x_.
  Configuration build_configuration(StepRecord& rec) {
    auto t = clock::now();
    Configuration cfg;
    cfg.mesh = std::make_shared<Mesh>(prm_.mesh);
    // No material inside a tool: at a square die's corner the alpha cut keeps
    // a triangle across the die, and its interior node would flow into the die
    // (the rezoning's corner node then rounds the corner: NodeAdaptivityParams).
    if (!contact_.tools().empty())
      cfg.mesh->set_solid([this](const Eigen::Vector2d& p) { return contact_.depth(p); },
                          [this](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return contact_.crossed(a, b); });
    cfg.mesh->build(x_);
    if (!h0_set_) {  // the rezoning's target spacing: the first configuration's
      fields_.flat(k_.h0) = cfg.mesh->h();
      h0_set_ = true;
    }
    rec.mesh_seconds += since(t);
    t = clock::now();
    typename Basis::params bp;
    bp.gamma = prm_.gamma;
    bp.tol0 = prm_.tol0;
    cfg.basis = std::make_shared<Basis>(x_, cfg.mesh->h(), bp);
    cfg.disc = std::make_shared<FlowDiscretization>(*cfg.mesh, *cfg.basis, prm_.geometry, prm_.discretization);
    // Nodal gradients (strain rate) can fail at a sharp spike of the free
    // surface, where the one-sided limit's dual is unsolvable; the nodal
    // strain rate then comes from the Gauss points (nodal_fields).
    try {
      cfg.at_nodes = cfg.basis->evaluate(x_, true);
    } catch (const Error& e) {
      cfg.at_nodes = cfg.basis->evaluate(x_, false);
      rec.nodal_gradient_fallback = true;
      degrade(rec, 0, detail::cat("nodal strain rate from the Gauss points: the basis gradients at the nodes failed (",
                                  e.what(), ")"));
    }
    rec.basis_seconds += since(t);
    return cfg;
  }

  // Solves the flow of a step of dt on cfg: contact rows of the active set,
  // a nonlinear solve, an active-set update, until the set settles. X: the
  // unknowns, v: the nodal velocity.
  void solve_with_active_set(const Configuration& cfg, FlowSystem<Material>& sys, double dt, StepRecord& rec,
                             Eigen::VectorXd& X, Eigen::Matrix2Xd& v) {
    // sys.constraints() (non-const) marks the system's structure for an
    // update: asked for anew wherever the rows change.
    if (zone_) {
      // Zone nodes put back this step start their contact from their own
      // state at the end of the last one (ContactSet::begin); their last
      // velocity is their own last solve's at the same place.
      std::vector<int> put_back(static_cast<std::size_t>(x_.cols()), 0);
      for (Eigen::Index a = 0; a < x_.cols(); ++a)
        if (const auto id = static_cast<std::size_t>(fields_.flat(k_.zone)(a)); id > 0)
          put_back[static_cast<std::size_t>(a)] = id <= zone_held_.size() && zone_held_[id - 1] >= 0 ? 1 + zone_held_[id - 1] : -1;
      contact_.begin(sys.constraints(), *cfg.mesh, fields_[k_.velocity], dt, put_back);
    } else {
      contact_.begin(sys.constraints(), *cfg.mesh, fields_[k_.velocity], dt);
    }
    const ConstraintSet& cs = std::as_const(sys).constraints();
    const int N = static_cast<int>(x_.cols());
    // One solver for the whole run: its linear policy keeps factorizations
    // that precondition the next steps' solves while the layout stays.
    if (!solver_) solver_ = std::make_unique<NonlinearSolver<Linear>>(prm_.solver);
    solver_->parameters() = prm_.solver;
    v.resize(2, N);
    const double ratio = update_ratio(dt);
    for (int as = 0;; ++as) {
      contact_.add_rows(sys.constraints(), *cfg.mesh, *cfg.disc, *cfg.basis, dt);
      contact_.add_tractions(sys, *cfg.mesh);
      // The first solve starts from the predictor, a re-solve after an
      // active-set change from the last solve; multipliers from the last
      // solve that had the same row.
      const int nf = DofLayout::fields_of(N);
      const Eigen::VectorXd start = as == 0 ? predicted(dt) : Eigen::VectorXd(X.head(nf));
      X = Eigen::VectorXd::Zero(sys.size());
      X.head(nf) = start;
      contact_.warm_start(cs, X, nf);
      // A loose solve first (active_set_tol); once the set holds on it, the
      // same rows are solved on to the solver's tolerances and checked again.
      const bool loose = contact_.size() > 0 &&
                         prm_.active_set_tol > std::max(prm_.solver.velocity_tol, prm_.solver.residual_tol);
      int changes = 0;
      for (int pass = loose ? 0 : 1; pass < 2; ++pass) {
        solver_->parameters().velocity_tol = pass == 0 ? prm_.active_set_tol : prm_.solver.velocity_tol;
        solver_->parameters().residual_tol = pass == 0 ? prm_.active_set_tol : prm_.solver.residual_tol;
        // After an active-set change: the same configuration, other rows.
        if (pass == 1 && loose)
          add_report(solver_->resume(sys, X), rec);
        else
          add_report(as == 0 ? solver_->solve(sys, X) : solver_->resolve(sys, X), rec);
        contact_.remember(cs, X, nf);
        nodal_velocity(cfg.at_nodes, X, v);
        // Free nodes are checked against the tools with the move they will make.
        changes = contact_.update(cs, X, N, x_, move_velocity(v, fields_[k_.velocity], ratio), dt);
        if (changes > 0) break;
      }
      solver_->parameters() = prm_.solver;
      if (changes == 0) {
        rec.active_set_iterations += as + 1;
        return;
      }
      if (prm_.solver.log) *prm_.solver.log << "  active set:" << contact_.last_changes(x_) << '\n';
      if (as + 1 >= prm_.max_active_set_iterations)
        throw Error(detail::cat("the contact active set did not settle in ", as + 1,
                                " iterations; last changes:", contact_.last_changes(x_)),
                    "Stepper::advance");
    }
  }
  static void add_report(const SolveReport& rep, StepRecord& rec) {
    rec.picard += rep.picard;
    rec.newton += rep.newton;
    rec.linear_iterations += rep.linear_iterations;
    rec.max_linear_iterations = std::max(rec.max_linear_iterations, rep.max_linear_iterations);
    rec.preconditioner_updates += rep.preconditioner_updates;
    rec.direct_fallbacks += rep.direct_fallbacks;
    rec.assembly_seconds += rep.assembly_seconds;
    rec.factorization_seconds += rep.factorization_seconds;
    rec.linear_seconds += rep.solve_seconds;
  }

  // The step's loads (on the configuration at its start) and contact nodes.
  void record_loads(const FlowSystem<Material>& sys, const Eigen::VectorXd& X, StepRecord& rec) {
    rec.tool_force = contact_.reactions(sys, X);
    rec.tool_stroke = contact_.strokes();
    rec.power = sys.power_balance(X);
    rec.tool_power = 0.0;
    for (std::size_t k = 0; k < rec.tool_force.size(); ++k)
      rec.tool_power -= rec.tool_force[k].dot(contact_.tools()[k].velocity());
    rec.contact_nodes = contact_.flags(contact_flag_);
  }

  // The solution becomes the stepper's fields (and the predictor's history).
  void keep_solution(const Configuration& cfg, const FlowSystem<Material>& sys, const Eigen::VectorXd& X,
                     const Eigen::Matrix2Xd& v, double dt) {
    const int N = static_cast<int>(x_.cols());
    X_ = X;
    fields_[k_.coef_last] = fields_[k_.coef];
    fields_[k_.velocity_last] = fields_[k_.velocity];
    ab_ratio_ = update_ratio(dt);
    dt_last_ = dt;
    fields_.flat(k_.coef) = X.head(DofLayout::fields_of(N));
    if (zone_) fields_.flat(k_.zone_start) = fields_.flat(k_.coef);  // not moved by the predictor
    fields_[k_.velocity] = v;
    mesh_ = cfg.mesh;
    basis_ = cfg.basis;
    x_solved_ = x_;
    nodal_fields(cfg.at_nodes, X, dt, sys);
    Eigen::VectorXd p_n, tau;
    Eigen::Matrix2Xd slip;
    contact_.contact_fields(sys, X, v, p_n, tau, slip);
    fields_.flat(k_.contact_pressure) = p_n;
    fields_.flat(k_.friction_stress) = tau;
    fields_[k_.slip] = slip;
  }

  // The nodes move with the material velocity at their position (the node
  // update: AB2 or Eq. (18)), the tools with theirs; then the contact and velocity conditions of the
  // step are made exact on the new positions, and a penetration fails the step.
  void move_nodes(const Configuration& cfg, const Eigen::VectorXd& X, const Eigen::Matrix2Xd& v, double dt,
                  StepRecord& rec) {
    // Nodes under a velocity condition end the step where it puts them: the
    // hat multipliers impose it on average, and a symmetry-axis node that
    // drifts past the selector's tolerance would lose its condition.
    struct Held {
      int node;
      Eigen::Vector2d e;  // the condition's direction
      double target;      // e . x at the step end
    };
    std::vector<Held> held;
    for (const auto& c : conditions_) {
      const Eigen::Vector2d e = c.direction.normalized();
      for (const auto& seg : cfg.mesh->boundary_segments())
        if (c.select(x_.col(seg.a), x_.col(seg.b)))
          for (int a : {seg.a, seg.b}) held.push_back({a, e, e.dot(x_.col(a)) + dt * c.value});
    }
    if (prm_.predictor == Predictor::spatial) predict_spatial(*cfg.basis, X, v, dt, rec);
    x_ += dt * move_velocity(v, fields_[k_.velocity_last], ab_ratio_);
    for (const auto& h : held) x_.col(h.node) += (h.target - h.e.dot(x_.col(h.node))) * h.e;
    MAXENTFLOW_REQUIRE(x_.allFinite(), "node positions became NaN", "Stepper::advance");
    contact_.move(dt);
    time_ += dt;
    const double h_mean = cfg.mesh->h().mean();
    contact_.snap(x_, h_mean, prm_.snap_tol);
    contact_.check_penetration(*cfg.mesh, x_, prm_.penetration_tol, h_mean);
  }

  // The node update over a step of dt moves a node by dt * move_velocity:
  // v (Eq. 18), or (1 + r/2) v - (r/2) v_last with r = dt / dt_last (AB2;
  // r = 0 when there is no last step). update_ratio is r, before the step's
  // solution is kept.
  double update_ratio(double dt) const {
    return prm_.node_update == NodeUpdate::adams_bashforth2 && dt_last_ > 0 ? dt / dt_last_ : 0.0;
  }
  static Eigen::Matrix2Xd move_velocity(const Eigen::Matrix2Xd& v, const Eigen::MatrixXd& v_last, double r) {
    if (r == 0.0) return v;
    return (1 + 0.5 * r) * v - 0.5 * r * v_last;
  }

  // Where the solve of a step of dt starts (see Predictor).
  Eigen::VectorXd predicted(double dt) const {
    const auto V = fields_.flat(k_.coef);
    if (prm_.predictor != Predictor::extrapolated || !(dt_last_ > 0)) return V;
    const auto V_last = fields_.flat(k_.coef_last);
    return V + (dt / dt_last_) * (V - V_last);
  }

  // v(x_a) = sum_b p_b(x_a) V_b: max-ent is not interpolating inside, so the
  // coefficients are not the nodal values.
  static void nodal_velocity(const BasisTable<2>& tab, const Eigen::VectorXd& X, Eigen::Matrix2Xd& v) {
    for (int a = 0; a < tab.size(); ++a) v.col(a) = interpolate_fields(tab.nodes(a), tab.values(a), X).head<2>();
  }

  void nodal_fields(const BasisTable<2>& tab, const Eigen::VectorXd& X, double dt,
                    const FlowSystem<Material>& sys) {
    const bool axi = prm_.geometry == Geometry::axisymmetric;
    auto p_nodal = fields_.flat(k_.pressure);
    auto d_nodal = fields_.flat(k_.strain_rate);
    auto strain = fields_.flat(k_.strain);
    if (!tab.has_gradients()) {  // pressure from the basis, d: area-weighted Gauss-point mean
      const FlowPointState st = sys.point_state(X);
      const auto& disc = sys.discretization();
      const auto& mesh = sys.mesh();
      Eigen::VectorXd sum = Eigen::VectorXd::Zero(tab.size()), wsum = sum;
      for (int t = 0; t < disc.cells(); ++t) {
        double dm = 0;
        for (int q = 0; q < disc.points_per_cell(); ++q) dm += st.d[t * disc.points_per_cell() + q];
        dm /= disc.points_per_cell();
        for (int a : mesh.triangles()[static_cast<std::size_t>(t)]) {
          sum[a] += mesh.area(t) * dm;
          wsum[a] += mesh.area(t);
        }
      }
      for (int a = 0; a < tab.size(); ++a) {
        p_nodal[a] = interpolate_fields(tab.nodes(a), tab.values(a), X)[2];
        d_nodal[a] = wsum[a] > 0 ? sum[a] / wsum[a] : 0.0;
        strain[a] += d_nodal[a] * dt;
      }
      return;
    }
    for (int a = 0; a < tab.size(); ++a) {
      const auto nodes = tab.nodes(a);
      const auto p = tab.values(a);
      const auto g = tab.gradients(a);
      double pr = 0;
      Eigen::Matrix2d L = Eigen::Matrix2d::Zero();  // velocity gradient
      double vr = 0;
      for (std::size_t j = 0; j < nodes.size(); ++j) {
        const int b = nodes[j];
        pr += p[j] * X[DofLayout::pressure(b)];
        vr += p[j] * X[DofLayout::velocity(b, 0)];
        L.row(0) += X[DofLayout::velocity(b, 0)] * g.col(static_cast<Eigen::Index>(j)).transpose();
        L.row(1) += X[DofLayout::velocity(b, 1)] * g.col(static_cast<Eigen::Index>(j)).transpose();
      }
      const Eigen::Matrix2d D = 0.5 * (L + L.transpose());
      double dtt = 0.0;  // hoop rate v_r / r; on the axis its limit dv_r/dr
      if (axi) dtt = x_(0, a) > 1e-12 * mesh_h_scale(a) ? vr / x_(0, a) : L(0, 0);
      const double DD = D.squaredNorm() + dtt * dtt;
      p_nodal[a] = pr;
      d_nodal[a] = std::sqrt(2.0 / 3.0 * DD);
      strain[a] += d_nodal[a] * dt;
    }
  }
  // Predictor::spatial: V_a += f(x_a + dt v_a) - f(x_a) for f = (v, p) of
  // this solve; a node whose new position leaves this configuration's hull
  // (the nose of a product) keeps its coefficients.
  void predict_spatial(const Basis& basis, const Eigen::VectorXd& X, const Eigen::Matrix2Xd& v,
                       double dt, StepRecord& rec) {
    const int N = static_cast<int>(x_.cols());
    Eigen::Map<Eigen::VectorXd> V = fields_.flat(k_.coef);
    const auto p_nodal = fields_.flat(k_.pressure);
    int failed = 0, first = N;
#pragma omp parallel for schedule(dynamic, 32) reduction(+ : failed) reduction(min : first)
    for (int a = 0; a < N; ++a) {
      const Eigen::Vector2d y = x_.col(a) + dt * v.col(a);
      try {
        const auto pv = basis.evaluate(y, false);
        const Eigen::Vector3d f = interpolate_fields(pv.node, pv.p, X);
        V.segment<2>(DofLayout::velocity(a, 0)) += f.head<2>() - v.col(a);
        V[DofLayout::pressure(a)] += f[2] - p_nodal[a];
      } catch (const Error&) {  // counted and reported below
        ++failed;
        first = std::min(first, a);
      }
    }
    rec.predictor_fallbacks += failed;
    if (failed > 0)
      degrade(rec, 1, detail::cat("spatial predictor: ", failed, " nodes (first: node ", first, " at (",
                                  x_(0, first), ", ", x_(1, first), ")) move beyond the configuration's hull "
                                  "and keep the material predictor"));
  }
  // Records a degradation of kind `kind` in the step record; logs the first of each kind in the run.
  void degrade(StepRecord& rec, int kind, const std::string& what) {
    rec.degraded += what + "\n";
    if (log_ && !logged_degradation_[static_cast<std::size_t>(kind)])
      *log_ << "note (step " << step_ + 1 << "; logged once per run, counted in each StepRecord): " << what << '\n';
    logged_degradation_[static_cast<std::size_t>(kind)] = true;
  }
  // Rezones the cloud x_: the Eulerian zone's nodes back at their places,
  // then the node rezoning outside the zone (NodeAdaptation); every per-node
  // array follows to the new numbering, the next solve starts from the
  // transferred fields.
  void rezone(StepRecord& rec) {
    const auto t = clock::now();
    Mesh mesh(prm_.mesh);
    // Not across a thin tool (as the solve's mesh): an edge from one face of
    // a die plate to the other is no edge of the material, to split or to
    // collapse. (The centroid rule stays the solve's: the rezoning plans on
    // the plain alpha-shape next to a convex corner.)
    if (!contact_.tools().empty())
      mesh.set_solid({}, [this](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return contact_.crossed(a, b); });
    mesh.build(x_);
    bool zone_active = false;
    zone_held_.clear();  // known only for a zone put back this step
    std::optional<EulerianZone> zone;  // where it is now
    if (zone_)
      zone = zone_->tool < 0 ? *zone_
                             : zone_->translated(contact_.tools()[static_cast<std::size_t>(zone_->tool)].displacement());
    if (zone && zone_filled(mesh, *zone, zone_h0_)) {
      typename Basis::params bp;
      bp.gamma = prm_.gamma;
      bp.tol0 = prm_.tol0;
      const Basis old(x_, mesh.h(), bp);
      ZoneUpdate z = plan_zone_update(mesh, old, *zone, fields_.flat(k_.zone), fields_.flat(k_.h0), zone_h0_,
                                      [this](const Eigen::Vector2d& p) { return contact_.admissible(p); });
      zone_active = z.active;
      rec.zone_active = z.active;
      if (z.active && !zone_logged_ && log_) {
        *log_ << "note (step " << step_ + 1 << "): the material fills the Eulerian zone; its " << zone_->nodes.cols()
              << " nodes stay in place from now on\n";
        zone_logged_ = true;
      }
      if (z.active) {
        if (z.fallbacks > 0 || z.emitted_fallbacks > 0)
          degrade(rec, 2, detail::cat("Eulerian zone: ", z.fallbacks,
                                      " zone nodes took the nearest node's data and ", z.emitted_fallbacks,
                                      " emitted nodes kept their own (the old cloud's basis failed there)"));
        // A zone node's next solve starts from its own last solution, not the
        // moved cloud's interpolant: at a fixed place a steady flow changes
        // little from step to step, and max-ent coefficients are not nodal
        // values (the interpolant smooths them across the die corner).
        const Eigen::Index T = zone_->nodes.cols(), n_old = x_.cols();
        Eigen::Matrix3Xd own = Eigen::Matrix3Xd::Constant(3, T, std::numeric_limits<double>::quiet_NaN());
        Eigen::Matrix3Xd own_last(3, T);
        Eigen::Matrix2Xd own_v(2, T), own_v_last(2, T);
        zone_held_.assign(static_cast<std::size_t>(T), -1);
        // The zone node that comes back is the one that left: its contact
        // multipliers carry over (where it was not emitted into the material),
        // and its contact starts from its state at the end of the last step.
        std::vector<std::pair<int, int>> back;
        const Eigen::Index first = n_old - static_cast<Eigen::Index>(z.change.removed.size());  // zone node 0's index
        for (Eigen::Index a = 0; a < n_old; ++a)
          if (const auto id = static_cast<Eigen::Index>(fields_.flat(k_.zone)(a)); id > 0) {
            own.col(id - 1) = fields_[k_.zone_start].col(a);
            own_v.col(id - 1) = fields_[k_.velocity].col(a);
            own_last.col(id - 1) = fields_[k_.coef_last].col(a);
            own_v_last.col(id - 1) = fields_[k_.velocity_last].col(a);
            zone_held_[static_cast<std::size_t>(id - 1)] = contact_flag_[static_cast<std::size_t>(a)];
            back.emplace_back(static_cast<int>(a), static_cast<int>(first + id - 1));
          }
        // An emitted node's start, its last coefficients and velocities: the
        // old cloud's interpolant where it goes (its own are its zone place's,
        // half a spacing upstream, and their extrapolation a jump).
        for (int f : {k_.coef, k_.coef_last, k_.velocity, k_.velocity_last}) interpolate_emitted(z, fields_[f]);
        for (std::size_t k = 0; k < z.emitted.size(); ++k) {
          fields_.flat(k_.zone)(z.emitted[k]) = 0.0;  // the material's now
          x_.col(z.emitted[k]) = z.emitted_at.col(static_cast<Eigen::Index>(k));
        }
        apply(z.change, back);
        auto coef = fields_.flat(k_.coef);
        for (Eigen::Index k = 0; k < T; ++k)
          if (own.col(k).allFinite()) {
            coef.template segment<3>(DofLayout::per_node * (x_.cols() - T + k)) = own.col(k);
            fields_[k_.velocity].col(x_.cols() - T + k) = own_v.col(k);
            fields_[k_.coef_last].col(x_.cols() - T + k) = own_last.col(k);
            fields_[k_.velocity_last].col(x_.cols() - T + k) = own_v_last.col(k);
          }
        // Counted as the node count's change: the zone's nodes come back every step.
        const auto removed = static_cast<Eigen::Index>(z.change.removed.size());
        rec.nodes_added += static_cast<int>(std::max<Eigen::Index>(0, T - removed));
        rec.nodes_removed += static_cast<int>(std::max<Eigen::Index>(0, removed - T));
        fields_.flat(k_.h0).tail(T) = zone_h0_;
        for (Eigen::Index k = 0; k < T; ++k) fields_.flat(k_.zone)(x_.cols() - T + k) = static_cast<double>(k + 1);
        if (prm_.adapt.enabled) mesh.build(x_);
      }
    }
    if (prm_.adapt.enabled) {
      const auto admissible = [this](const Eigen::Vector2d& p) { return contact_.admissible(p); };
      NodeAdaptation a = plan_node_adaptation(mesh, fields_.flat(k_.h0), prm_.adapt, admissible);
      if (prm_.adapt.corner_nodes)
        add_corner_nodes(mesh, fields_.flat(k_.h0), prm_.adapt, contact_.convex_corners(), a);
      if (zone_active) outside_zone(*zone, a);
      if (!a.empty()) {
        apply(a);
        rec.nodes_added += a.added();
        rec.nodes_removed += static_cast<int>(a.removed.size());
        if (zone_) fields_.flat(k_.zone).tail(a.added()).setZero();  // new nodes are material nodes
      }
    }
    rec.mesh_seconds += since(t);
  }
  // Drops from a rezoning what touches the zone: removals of zone nodes,
  // insertions inside the zone.
  void outside_zone(const EulerianZone& zone, NodeAdaptation& a) const {
    std::erase_if(a.removed, [&](int r) { return fields_.flat(k_.zone)(r) > 0; });
    NodeAdaptation kept;
    kept.removed = std::move(a.removed);
    std::vector<Eigen::Vector2d> at;
    for (int i = 0; i < a.added(); ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (zone.inside(a.inserted.col(i))) continue;
      kept.parents.push_back(a.parents[k]);
      kept.weights.push_back(k < a.weights.size() ? a.weights[k] : std::vector<std::pair<int, double>>{});
      at.push_back(a.inserted.col(i));
    }
    kept.inserted.resize(2, static_cast<Eigen::Index>(at.size()));
    for (std::size_t i = 0; i < at.size(); ++i) kept.inserted.col(static_cast<Eigen::Index>(i)) = at[i];
    a = std::move(kept);
  }
  // Carries the cloud and every per-node array through a rezoning.
  // `same`: (old, new) pairs of nodes that continue where the plan removed
  // the old one (a zone node put back).
  void apply(const NodeAdaptation& a, const std::vector<std::pair<int, int>>& same = {}) {
    std::vector<int> map = a.old_to_new(x_.cols());
    for (const auto& [o, n] : same)
      if (map[static_cast<std::size_t>(o)] < 0) map[static_cast<std::size_t>(o)] = n;
    x_ = a.positions(x_);
    fields_.transfer(a);
    contact_flag_.assign(static_cast<std::size_t>(x_.cols()), 0);
    contact_.renumber(map);
  }
  double mesh_h_scale(int a) const { return mesh_ ? mesh_->h()(a) : 1.0; }

  StepperParams prm_;
  Material material_;
  Control control_;
  Eigen::Matrix2Xd x_, x_solved_;
  Eigen::VectorXd X_;
  // The per-node fields, and the stepper's own among them: velocity and
  // pressure coefficients (this solve's and the last one's, for
  // Predictor::extrapolated), nodal velocity, pressure, strain rate,
  // effective strain, the rezoning's target spacing h0.
  NodalFields fields_;
  struct {
    int coef, coef_last, velocity, velocity_last, pressure, strain_rate, strain, h0;
    int contact_pressure, friction_stress, slip;
    int zone = -1;  // with an Eulerian zone: the zone node a node is, plus one (0: a material node)
    int zone_start = -1;  // with an Eulerian zone: the last solve's coefficients (a zone node's next start)
  } k_{};
  std::optional<EulerianZone> zone_;
  Eigen::VectorXd zone_h0_;  // the zone nodes' spacing (their own cloud's h_a)
  std::vector<int> zone_held_;  // per zone node: the tool it ended the last step on (contact_flag_), 0: none, -1: unknown
  bool zone_logged_ = false;
  double dt_last_ = 0.0;  // the step of coefficients_last -> coefficients
  double ab_ratio_ = 0.0;  // this step's dt / the last one's (0: no last velocity)
  bool h0_set_ = false;
  std::vector<int> contact_flag_;
  ContactSet contact_;  // the tools, their laws and active sets
  std::vector<VelocityCondition> conditions_;
  std::vector<StepRecord> history_;
  std::shared_ptr<Mesh> mesh_;
  std::shared_ptr<Basis> basis_;
  std::unique_ptr<NonlinearSolver<Linear>> solver_;  // heap: LU factorizations do not move
  std::ostream* log_ = nullptr;
  std::array<bool, 3> logged_degradation_{};  // gradient fallback, predictor fallback, zone data fallback
  double time_ = 0.0;
  int step_ = 0;
};

}  // namespace maxentflow

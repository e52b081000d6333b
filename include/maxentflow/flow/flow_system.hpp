// maxentflow: the saddle system of Eq. (21) for one configuration: cell
// integrals, Lagrange-multiplier rows, tractions; what NonlinearSolver drives.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <maxentflow/core/dof_layout.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/flow/stabilized_flow.hpp>
#include <maxentflow/flow/velocity_traction.hpp>

namespace maxentflow {

/// FlowSystem::power_balance: Eq. (21) times the solution. The material's
/// dissipation int 2 mu D:D (`plastic`) and -int p div v (`volumetric`,
/// which the mass rows make int tau |grad p|^2: what the pressure-gradient
/// stabilization dissipates, zero in the continuum) against the power the
/// boundary delivers: -sum Lambda_i rhs_i over the multiplier rows
/// (`constraints`: tools, prescribed velocities and the contact's gap
/// closure -g/dt) and int t . v over the tractions (`tractions`, friction
/// included). A tool's load times its speed is its share of `constraints`.
struct PowerBalance {
  double plastic = 0.0, volumetric = 0.0, constraints = 0.0, tractions = 0.0;
  double delivered() const { return constraints + tractions; }
  double dissipated() const { return plastic + volumetric; }
};

/// X = [v_x, v_y, P per node (3N) | Lambda (one per constraint row)].
template <ViscosityLaw Material>
class FlowSystem {
 public:
  using Assembler = StabilizedFlowAssembler<Material>;
  using Matrix = SystemPattern::Matrix;
  using Mesh = IntegrationMesh<2>;
  using Traction = std::function<Eigen::Vector2d(const Eigen::Vector2d&)>;

  FlowSystem(const Mesh& mesh, const FlowDiscretization& disc, Material material,
             typename Assembler::params prm = {})
      : mesh_(&mesh), disc_(&disc), assembler_(disc, std::move(material), prm),
        traction_(Eigen::VectorXd::Zero(DofLayout::fields_of(disc.number_of_nodes()))) {
    pattern_.build_adjacency(disc);
    structure_dirty_ = true;
  }

  Assembler& assembler() { return assembler_; }
  const Assembler& assembler() const { return assembler_; }
  const FlowDiscretization& discretization() const { return *disc_; }
  const Mesh& mesh() const { return *mesh_; }
  ConstraintSet& constraints() {
    structure_dirty_ = true;  // the caller may change rows
    return constraints_;
  }
  const ConstraintSet& constraints() const { return constraints_; }
  const SystemPattern& pattern() const { return pattern_; }
  int number_of_nodes() const { return disc_->number_of_nodes(); }

  /// Prescribed traction t(x) on the chosen boundary segments (Eq. 6d):
  /// F_a += int phi_a t dGamma (2 pi r dGamma axisymmetric).
  void add_traction(const SegmentSelector& select, const Traction& t) {
    const auto& X = mesh_->nodes();
    for (const auto& seg : mesh_->boundary_segments()) {
      if (!select(X.col(seg.a), X.col(seg.b))) continue;
      for_each_segment_point(seg, [&](const Eigen::Vector2d& x, double w, double, auto nodes, auto p) {
        const Eigen::Vector2d tv = t(x);
        for (std::size_t j = 0; j < nodes.size(); ++j)
          for (int c = 0; c < 2; ++c) traction_[velocity_dof(nodes[j], c)] += w * p[j] * tv[c];
      });
    }
  }

  /// A velocity-dependent traction on boundary segment `segment` (index into
  /// mesh.boundary_segments()), grouped under `part` (a tool) for its force:
  /// R_a -= int phi_a t(x, v, k) dGamma, and Newton's tangent
  /// -int phi_a (dt/dv phi_b + dt/dk dk/dV_b), k the shear flow stress of the
  /// segment's triangle (TractionPointState). Its entries fall inside the
  /// pattern (the edge's basis nodes belong to its triangle's U_T, which the
  /// pattern couples).
  /// With a `multiplier_part` >= 0 the law also reads lambda, the multiplier
  /// field of that part's role-0 rows at the segment's two ends (a contact's
  /// normal pressure, for Coulomb friction), and the tangent gets dt/dlambda;
  /// those rows then couple to both velocity components of the segment's
  /// basis nodes (structural zeros where the row's direction has none). An
  /// end without such a row contributes no lambda.
  void add_velocity_traction(int part, int segment, VelocityTractionLaw law, int multiplier_part = -1) {
    require(segment >= 0 && segment < static_cast<int>(mesh_->boundary_segments().size()),
            detail::cat("no boundary segment ", segment), "FlowSystem::add_velocity_traction");
    const int e = mesh_->boundary_segments()[static_cast<std::size_t>(segment)].edge;
    const auto& edge = mesh_->edges()[static_cast<std::size_t>(e)];
    velocity_tractions_.push_back({part, segment, edge.left, std::move(law), multiplier_part, {edge.a, edge.b}, {-1, -1}});
    if (multiplier_part >= 0) structure_dirty_ = true;
  }
  /// Removes the velocity tractions of `part` (a new active set).
  void clear_velocity_tractions(int part) {
    std::erase_if(velocity_tractions_, [part](const VelocityTractionTerm& v) { return v.part == part; });
  }

  /// One Gauss point of a velocity traction at X: where, its weight (2 pi r
  /// dGamma axisymmetric), the segment's end nodes (edge order) with their
  /// hat values there, what the law read and the traction it gave.
  struct TractionSample {
    Eigen::Vector2d x = Eigen::Vector2d::Zero();
    double w = 0.0;
    int end[2] = {-1, -1};
    double hat[2] = {0.0, 0.0};
    TractionPointState state;
    Eigen::Vector2d t = Eigen::Vector2d::Zero();
  };
  /// The Gauss points of `part`'s velocity tractions at X (post-processing:
  /// friction stress, contact pressure), after an assembly or solve.
  std::vector<TractionSample> velocity_traction_samples(int part, const Eigen::VectorXd& X) const {
    require(!structure_dirty_, "the structure changed since the last assembly",
            "FlowSystem::velocity_traction_samples");
    std::vector<TractionSample> out;
    for_each_traction_point(X, [&](const VelocityTractionTerm& term, const TractionGauss& g) {
      if (term.part != part) return;
      TractionSample smp;
      smp.x = g.state.x;
      smp.w = g.w;
      smp.end[0] = term.end[0];
      smp.end[1] = term.end[1];
      smp.hat[0] = 1.0 - g.s;
      smp.hat[1] = g.s;
      smp.state = g.state;
      smp.t = g.vt.t;
      out.push_back(smp);
    });
    return out;
  }
  /// The force the workpiece exerts on `part` through its velocity tractions
  /// at X: -int t dGamma (2 pi r dGamma axisymmetric).
  Eigen::Vector2d velocity_traction_force(int part, const Eigen::VectorXd& X) const {
    Eigen::Vector2d f = Eigen::Vector2d::Zero();
    for_each_traction_point(X, [&](const VelocityTractionTerm& term, const TractionGauss& g) {
      if (term.part == part) f -= g.w * g.vt.t;
    });
    return f;
  }

  /// Unknowns (3N + constraint rows); finalizes the structure after changes.
  int size() {
    update_structure();
    return pattern_.size();
  }
  long structure_generation() {
    update_structure();
    return pattern_.generation();
  }

  /// What the unknowns mean: 3 per node, then the multiplier rows by (part,
  /// node, direction), whatever their coefficients. A factorization made for
  /// one configuration can precondition the next through it (GmresSolver's
  /// kept LU).
  const DofLayout& layout() {
    update_structure();
    return layout_;
  }

  /// The matrix assemble() builds of this kind is symmetric: Picard's and
  /// newton_symmetric's (O^T D O per Gauss point with D symmetric, the
  /// constraints as L and L^T), unless a velocity traction (friction) adds
  /// its non-symmetric derivatives. Newton's is not (d tau / d v couples the
  /// pressure-gradient rows to the strain rate alone).
  bool symmetric(Linearization kind) const {
    return kind != Linearization::newton && velocity_tractions_.empty();
  }

  /// A at X (Picard or Newton) and the residual R(X) = A_picard(X) X - F.
  void assemble(const Eigen::VectorXd& X, Linearization kind, Matrix& A, Eigen::VectorXd& R) {
    update_structure();
    require(X.size() == pattern_.size(), detail::cat("X has ", X.size(), " entries, the system ", pattern_.size()),
            "FlowSystem::assemble");
    reset_to_pattern(A, pattern_, generation_of_A_);
    residual_impl(X, kind, &A, R);
    add_constraint_entries(A, entry_pos_);
  }

  /// The Krylov preconditioner at X: the Picard matrix of the linear-triangle
  /// companion (FlowDiscretization::build_linear) with the same material, tau
  /// and constraint rows; the same unknowns as A.
  void assemble_preconditioner(const Eigen::VectorXd& X, Matrix& P) {
    update_structure();
    if (!linear_) {
      linear_ = std::make_unique<LinearCompanion>();
      linear_->disc.build_linear(*mesh_, *disc_);
      linear_->assembler.emplace(linear_->disc, assembler_.material(), assembler_.parameters());
      linear_->pattern.build_adjacency(linear_->disc);
      linear_->generation = -1;
    }
    if (linear_->generation != pattern_.generation()) {
      linear_->pattern.set_constraints(constraints_.rows());
      linear_->entry_pos = constraint_positions(linear_->pattern);
      linear_->generation = pattern_.generation();
    }
    const SystemPattern& lp = linear_->pattern;
    reset_to_pattern(P, lp, generation_of_P_);
    Eigen::VectorXd R = Eigen::VectorXd::Zero(lp.size());
    linear_->assembler->assemble(X, Linearization::picard, lp, &P, R);
    add_constraint_entries(P, linear_->entry_pos);
  }
  /// M gets the pattern's structure (when it or its generation differs) with
  /// zero values; otherwise its values are zeroed in place (no reallocation).
  static void reset_to_pattern(Matrix& M, const SystemPattern& pat, long& generation) {
    if (M.rows() != pat.size() || M.nonZeros() != pat.nonzeros() || generation != pat.generation()) {
      pat.zero_matrix(M);
      generation = pat.generation();
    } else {
      std::fill_n(M.valuePtr(), M.nonZeros(), 0.0);
    }
  }
  /// Changes whenever the preconditioner's structure does.
  long preconditioner_generation() {
    update_structure();
    return linear_ && linear_->generation == pattern_.generation() ? linear_->pattern.generation()
                                                                   : -1;
  }

  /// Jv = J(X) v, J Newton's tangent (the matrix assemble() builds with
  /// Linearization::newton), without forming it: a residual's cost; with
  /// Linearization::picard, the Picard matrix's product.
  void apply_tangent(const Eigen::VectorXd& X, const Eigen::VectorXd& v, Eigen::VectorXd& Jv,
                     Linearization kind = Linearization::newton) {
    update_structure();
    require(X.size() == pattern_.size() && v.size() == pattern_.size(),
            detail::cat("X and v need ", pattern_.size(), " entries"), "FlowSystem::apply_tangent");
    if (!(linearized_at_.size() == X.size() && linearized_at_ == X)) {  // a new X: new point operators
      assembler_.linearize(X);
      linearized_at_ = X;
    }
    Jv.setZero(pattern_.size());
    assembler_.apply_tangent(v, Jv, kind);
    add_multiplier_terms(v, false, Jv);
    const int nv = DofLayout::fields_of(number_of_nodes());
    for_each_traction_point(X, [&](const VelocityTractionTerm& term, const TractionGauss& g) {
      const CellFlowStress& k = *g.k;
      double dk = 0.0, dl = 0.0;
      for (std::size_t j = 0; j < k.u.size(); ++j)
        dk += k.dk_dv[2 * j] * v[DofLayout::velocity(k.u[j], 0)] + k.dk_dv[2 * j + 1] * v[DofLayout::velocity(k.u[j], 1)];
      for (int e = 0; e < 2; ++e)
        if (term.row[e] >= 0) dl += g.dlambda[e] * v[nv + term.row[e]];
      const Eigen::Vector2d dt = g.vt.dt_dv * Eigen::Vector3d(interpolate_fields(g.nodes, g.p, v)).head<2>() +
                                 g.vt.dt_dk * dk + g.vt.dt_dlambda * dl;
      for (std::size_t j = 0; j < g.nodes.size(); ++j)
        for (int c = 0; c < 2; ++c) Jv[DofLayout::velocity(g.nodes[j], c)] -= g.w * g.p[j] * dt[c];
    });
  }

  void residual(const Eigen::VectorXd& X, Eigen::VectorXd& R) {
    update_structure();
    residual_impl(X, Linearization::picard, nullptr, R);
  }

  /// For the iterate of a solve from rest, whose viscosity was uniform
  /// (mu(d_min)): that system's velocity does not depend on the viscosity's
  /// value (tau ~ 1/mu keeps Eq. (21) homogeneous in it), its pressure and
  /// multipliers scale with it (~1e5 times those of the flow's viscosity on
  /// bench_flow's block).
  /// Scales them by the c that minimizes the momentum residual at X (affine
  /// in c) and returns c; leaves X and returns 1 where that does not lower
  /// |R| or c is 1 to within 1e-6. The next solve's right-hand side is then
  /// the flow's, not mu(d_min)'s pressure left over, which a Krylov solve
  /// would have to cancel to ~1e-8.
  double rescale_stresses(Eigen::VectorXd& X) {
    update_structure();
    const int nv = DofLayout::fields_of(number_of_nodes());
    require(X.size() == pattern_.size(), detail::cat("X has ", X.size(), " entries, the system ", pattern_.size()),
            "FlowSystem::rescale_stresses");
    auto scaled = [&](double c) {
      Eigen::VectorXd Y = X;
      for (int a = 0; a < number_of_nodes(); ++a) Y[DofLayout::pressure(a)] *= c;
      Y.tail(Y.size() - nv) *= c;
      return Y;
    };
    auto momentum_dot = [&](const Eigen::VectorXd& u, const Eigen::VectorXd& v) {
      double d = 0.0;
      for (int k = 0; k < nv; ++k)
        if (k % DofLayout::per_node != 2) d += u[k] * v[k];
      return d;
    };
    Eigen::VectorXd R0, R1, Rc;
    residual(scaled(0.0), R0);
    residual(X, R1);
    const Eigen::VectorXd b = R1 - R0;
    const double bb = momentum_dot(b, b);
    const double c = bb > 0 ? -momentum_dot(R0, b) / bb : 1.0;
    // A factor within 1e-6 of 1 is round-off of a stress scale that is right
    // already (a Newtonian flow's iterate from rest): nothing to rescale.
    if (c > 0 && std::abs(c - 1.0) > 1e-6) {
      Eigen::VectorXd Y = scaled(c);
      residual(Y, Rc);
      if (momentum_dot(Rc, Rc) < momentum_dot(R1, R1)) {
        X = std::move(Y);
        return c;
      }
    }
    residual(X, R1);  // the force scale of X
    return 1.0;
  }

  /// |momentum residual| / force scale (|internal force| + |traction|) of the last evaluation.
  double relative_residual(const Eigen::VectorXd& R) const {
    const int nv = DofLayout::fields_of(number_of_nodes());
    double r2 = 0.0;
    for (int k = 0; k < nv; ++k)
      if (k % DofLayout::per_node != 2) r2 += R[k] * R[k];
    return std::sqrt(r2) / force_scale_;
  }
  /// Max-norm of the velocity part of X.
  double velocity_norm(const Eigen::VectorXd& X) const {
    double m = 0.0;
    for (int a = 0; a < number_of_nodes(); ++a)
      m = std::max({m, std::abs(X[velocity_dof(a, 0)]), std::abs(X[velocity_dof(a, 1)])});
    return m;
  }
  double force_scale() const { return force_scale_; }

  /// Gauss-point fields at X (strain rate, viscosity, tau, pressure, div v).
  FlowPointState point_state(const Eigen::VectorXd& X) const {
    FlowPointState s;
    Eigen::VectorXd R = Eigen::VectorXd::Zero(DofLayout::fields_of(number_of_nodes()));
    assembler_.assemble(X, Linearization::picard, pattern_, nullptr, R, nullptr, &s);
    return s;
  }

  /// The power balance of X: Eq. (21) times X. At a solution (no body
  /// force) the power delivered through the boundary equals the dissipation,
  /// `plastic + volumetric`, to the solver's tolerance (PowerBalance).
  PowerBalance power_balance(const Eigen::VectorXd& X) const {
    PowerBalance b;
    const FlowPointState st = point_state(X);
    for (Eigen::Index g = 0; g < st.d.size(); ++g) {
      const double w = disc_->weight(static_cast<int>(g));
      b.plastic += w * 3.0 * st.mu[g] * st.d[g] * st.d[g];  // 2 mu D:D, d^2 = (2/3) D:D
      b.volumetric -= w * st.p[g] * st.div[g];
    }
    const int nv = DofLayout::fields_of(number_of_nodes());
    const auto& rows = constraints_.rows();
    for (std::size_t i = 0; i < rows.size(); ++i) b.constraints -= X[nv + static_cast<Eigen::Index>(i)] * rows[i].rhs;
    b.tractions = traction_.dot(X.head(nv));
    for_each_traction_point(X, [&](const VelocityTractionTerm&, const TractionGauss& g) {
      b.tractions += g.w * g.vt.t.dot(g.state.v);
    });
    return b;
  }

  /// Force the workpiece exerts on a constraint part.
  Eigen::Vector2d reaction(const std::string& part, const Eigen::VectorXd& X) const {
    return constraints_.reaction(constraints_.find_part(part), X, number_of_nodes());
  }

 private:
  void update_structure() {
    if (!structure_dirty_) return;
    structure_dirty_ = false;
    link_traction_multipliers();
    pattern_.set_constraints(constraints_.rows());
    entry_pos_ = constraint_positions(pattern_);
    entry_coef_.clear();
    for (const auto& r : constraints_.rows()) entry_coef_.insert(entry_coef_.end(), r.coef.begin(), r.coef.end());
    layout_.fields = DofLayout::fields_of(number_of_nodes());
    layout_.multipliers.clear();
    for (const auto& r : constraints_.rows()) layout_.multipliers.push_back(r.key());
  }

  void add_constraint_entries(Matrix& A, const std::vector<std::pair<int, int>>& pos) const {
    double* v = A.valuePtr();
    for (std::size_t k = 0; k < pos.size(); ++k) {
      v[pos[k].first] += entry_coef_[k];   // L in the momentum rows
      v[pos[k].second] += entry_coef_[k];  // L^T in the multiplier rows
    }
  }

  // Value positions of each constraint coefficient in A (both blocks), in row order.
  std::vector<std::pair<int, int>> constraint_positions(const SystemPattern& pat) const {
    const int nv = DofLayout::fields_of(number_of_nodes());
    std::vector<std::pair<int, int>> pos;
    auto position = [&](int row, int col) { return pat.position(row, col); };
    const auto& rows = constraints_.rows();
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const int li = nv + static_cast<int>(i);
      for (std::size_t k = 0; k < rows[i].dof.size(); ++k) {
        const int d = rows[i].dof[k];
        require(d >= 0 && d < nv, detail::cat("constraint dof ", d, " out of range"),
                detail::cat("FlowSystem, constraint row ", i));
        pos.emplace_back(position(li, d), position(d, li));
      }
    }
    return pos;
  }

  void residual_impl(const Eigen::VectorXd& X, Linearization kind, Matrix* A, Eigen::VectorXd& R) {
    const int nv = DofLayout::fields_of(number_of_nodes());
    R.setZero(pattern_.size());
    Eigen::VectorXd fint = Eigen::VectorXd::Zero(nv);
    assembler_.assemble(X, kind, pattern_, A, R, &fint);
    R.head(nv) -= traction_;
    add_velocity_tractions(X, A, R);
    add_multiplier_terms(X, true, R);
    force_scale_ = fint.norm() + traction_.norm();
    if (!(force_scale_ > 0)) force_scale_ = 1.0;
    MAXENTFLOW_REQUIRE(R.allFinite(), "the residual is not finite (NaN or Inf in the fields)",
                       "FlowSystem::residual");
  }

  // The multiplier rows of Eq. (21) applied to Y: out_fields += L^T lambda and
  // out_i = L_i Y (- rhs_i for the residual, not for the tangent).
  void add_multiplier_terms(const Eigen::VectorXd& Y, bool minus_rhs, Eigen::VectorXd& out) const {
    const int nv = DofLayout::fields_of(number_of_nodes());
    const auto& rows = constraints_.rows();
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const double lambda = Y[nv + static_cast<Eigen::Index>(i)];
      double g = minus_rhs ? -rows[i].rhs : 0.0;
      for (std::size_t k = 0; k < rows[i].dof.size(); ++k) {
        out[rows[i].dof[k]] += rows[i].coef[k] * lambda;
        g += rows[i].coef[k] * Y[rows[i].dof[k]];
      }
      out[nv + static_cast<Eigen::Index>(i)] = g;
    }
  }

  struct VelocityTractionTerm {
    int part;
    int segment;
    int cell;  // the segment's triangle
    VelocityTractionLaw law;
    int multiplier_part;  // whose role-0 multipliers the law reads (-1: none)
    int end[2];           // the edge's end nodes (hat order)
    int row[2];           // their rows of multiplier_part (-1: none)
  };
  // Resolves each traction's multiplier rows and gives them both velocity
  // components of the segment's basis nodes (dt/dlambda is not along the
  // rows' direction).
  void link_traction_multipliers() {
    std::map<std::pair<int, int>, int> row_of;  // (part, node) -> role-0 row
    auto& rows = constraints_.rows();
    for (std::size_t i = 0; i < rows.size(); ++i)
      if (rows[i].role == 0 && rows[i].node >= 0)  // the first: a corner node's second row is a point row
        row_of.try_emplace({rows[i].part, rows[i].node}, static_cast<int>(i));
    const int ne = disc_->points_per_edge();
    for (auto& term : velocity_tractions_) {
      for (int e = 0; e < 2; ++e) {
        term.row[e] = -1;
        if (term.multiplier_part < 0) continue;
        const auto it = row_of.find({term.multiplier_part, term.end[e]});
        if (it == row_of.end()) continue;
        term.row[e] = it->second;
        ConstraintRow& r = rows[static_cast<std::size_t>(it->second)];
        std::map<int, double> c;
        for (std::size_t j = 0; j < r.dof.size(); ++j) c[r.dof[j]] = r.coef[j];
        const int edge = mesh_->boundary_segments()[static_cast<std::size_t>(term.segment)].edge;
        for (int k = 0; k < ne; ++k)
          for (int node : disc_->edge_basis().nodes(edge * ne + k))
            for (int d = 0; d < 2; ++d) c.try_emplace(DofLayout::velocity(node, d), 0.0);
        r.dof.clear();
        r.coef.clear();
        for (const auto& [dof, cf] : c) {
          r.dof.push_back(dof);
          r.coef.push_back(cf);
        }
      }
    }
  }
  // The shear flow stress k = sqrt(3) mu(d) d of a triangle at X, from its
  // mean strain rate (Gauss-weighted), and dk/dV over its nodes U_T.
  struct CellFlowStress {
    std::span<const int> u;
    std::vector<double> dk_dv;  // (dk/dv_x, dk/dv_y) per node of u
    double k = 0.0;
  };
  CellFlowStress cell_flow_stress(int t, const Eigen::VectorXd& X, const Eigen::Vector2d& x) const {
    CellFlowStress c;
    c.u = disc_->nodes(t);
    const std::size_t n = c.u.size();
    std::vector<double> gx(n, 0.0), gy(n, 0.0), hr(n, 0.0);  // mean d/dx, d/dy, 1/r (hoop)
    const bool axi = disc_->axisymmetric();
    double W = 0.0;
    for (int q = 0; q < disc_->points_per_cell(); ++q) {
      const int g = t * disc_->points_per_cell() + q;
      const double w = disc_->weight(g), r = disc_->points()(0, g);
      const double* p = disc_->values(t, q);
      const double* dp = disc_->gradients(t, q);
      W += w;
      for (std::size_t i = 0; i < n; ++i) {
        gx[i] += w * dp[2 * i];
        gy[i] += w * dp[2 * i + 1];
        if (axi) hr[i] += w * p[i] / r;
      }
    }
    double ex = 0.0, ey = 0.0, et = 0.0, gam = 0.0;  // D_xx, D_yy, D_tt, 2 D_xy
    for (std::size_t i = 0; i < n; ++i) {
      gx[i] /= W;
      gy[i] /= W;
      hr[i] /= W;
      const double vx = X[DofLayout::velocity(c.u[i], 0)], vy = X[DofLayout::velocity(c.u[i], 1)];
      ex += gx[i] * vx;
      ey += gy[i] * vy;
      et += hr[i] * vx;
      gam += gy[i] * vx + gx[i] * vy;
    }
    const double d = std::sqrt(2.0 / 3.0 * (ex * ex + ey * ey + et * et + 0.5 * gam * gam));
    const Viscosity visc = assembler_.material().viscosity(MaterialPoint{d, x});
    constexpr double sqrt3 = 1.7320508075688772935;
    c.k = sqrt3 * visc.mu * d;
    c.dk_dv.assign(2 * n, 0.0);
    if (d > 0) {  // dk/dd (2/3) Q D / d
      const double a = sqrt3 * (visc.mu + d * d * visc.dmu_dd_over_d) * (2.0 / 3.0) / d;
      for (std::size_t i = 0; i < n; ++i) {
        c.dk_dv[2 * i] = a * (ex * gx[i] + et * hr[i] + 0.5 * gam * gy[i]);
        c.dk_dv[2 * i + 1] = a * (ey * gy[i] + 0.5 * gam * gx[i]);
      }
    }
    return c;
  }
  // A Gauss point of a velocity traction: weight (2 pi r dGamma
  // axisymmetric), the edge parameter s from end[0], basis nodes and values,
  // what the law read and gave, the cell's k, and dlambda/dLambda_end.
  struct TractionGauss {
    double w, s;
    std::span<const int> nodes;
    std::span<const double> p;
    TractionPointState state;
    VelocityTraction vt;
    const CellFlowStress* k;
    double dlambda[2];
  };
  // f(term, gauss) at every Gauss point of every velocity traction's
  // segment, with the fields of X there.
  template <class F>
  void for_each_traction_point(const Eigen::VectorXd& X, F&& f) const {
    const int nv = DofLayout::fields_of(number_of_nodes());
    constexpr double two_pi = 6.283185307179586476925;
    for (const auto& term : velocity_tractions_) {
      const BoundarySegment& seg = mesh_->boundary_segments()[static_cast<std::size_t>(term.segment)];
      const CellFlowStress k = cell_flow_stress(term.cell, X, 0.5 * (mesh_->nodes().col(seg.a) + mesh_->nodes().col(seg.b)));
      for_each_segment_point(seg, [&](const Eigen::Vector2d& x, double w, double s, auto nodes, auto p) {
        TractionGauss g{w, s, nodes, p, {}, {}, &k, {0.0, 0.0}};
        g.state.x = x;
        g.state.v = interpolate_fields(nodes, p, X).template head<2>();
        g.state.k = k.k;
        // The hat multipliers are per unit arc length (ConstraintSet::add_velocity).
        const double per_area = disc_->axisymmetric() ? 1.0 / (two_pi * x.x()) : 1.0;
        const double hat[2] = {1.0 - s, s};
        for (int e = 0; e < 2; ++e)
          if (term.row[e] >= 0) {
            g.dlambda[e] = hat[e] * per_area;
            g.state.lambda += g.dlambda[e] * X[nv + term.row[e]];
          }
        g.vt = term.law(g.state);
        f(term, g);
      });
    }
  }
  // f(x, w, s, nodes, p) at each Gauss point of a boundary segment: the point,
  // its weight (2 pi r dGamma axisymmetric), its parameter along the edge
  // (from edge.a), the basis nodes and values there.
  template <class F>
  void for_each_segment_point(const BoundarySegment& seg, F&& f) const {
    const int ne = disc_->points_per_edge();
    const auto& tab = disc_->edge_basis();
    constexpr double two_pi = 6.283185307179586476925;
    for (int k = 0; k < ne; ++k) {
      const int ge = seg.edge * ne + k;
      const Eigen::Vector2d x = disc_->edge_points().col(ge);
      const double w = disc_->edge_weights()(ge) * (disc_->axisymmetric() ? two_pi * x.x() : 1.0);
      f(x, w, disc_->edge_parameter(k), tab.nodes(ge), tab.values(ge));
    }
  }
  // R -= int phi t, and A -= int phi (dt/dv phi^T + dt/dk dk/dV + dt/dlambda
  // dlambda/dLambda) (both linearizations: the friction law is part of the
  // operator Picard freezes).
  void add_velocity_tractions(const Eigen::VectorXd& X, Matrix* A, Eigen::VectorXd& R) const {
    const int nv = DofLayout::fields_of(number_of_nodes());
    for_each_traction_point(X, [&](const VelocityTractionTerm& term, const TractionGauss& g) {
      const VelocityTraction& vt = g.vt;
      const CellFlowStress& k = *g.k;
      const double w = g.w;
      for (std::size_t i = 0; i < g.nodes.size(); ++i)
        for (int c = 0; c < 2; ++c) {
          const int row = DofLayout::velocity(g.nodes[i], c);
          const double wp = w * g.p[i];
          R[row] -= wp * vt.t[c];
          if (!A) continue;
          for (std::size_t j = 0; j < g.nodes.size(); ++j)
            for (int d = 0; d < 2; ++d) entry(*A, row, DofLayout::velocity(g.nodes[j], d)) -= wp * g.p[j] * vt.dt_dv(c, d);
          if (vt.dt_dk[c] != 0.0)
            for (std::size_t j = 0; j < k.u.size(); ++j)
              for (int d = 0; d < 2; ++d)
                entry(*A, row, DofLayout::velocity(k.u[j], d)) -= wp * vt.dt_dk[c] * k.dk_dv[2 * j + d];
          if (vt.dt_dlambda[c] != 0.0)
            for (int e = 0; e < 2; ++e)
              if (term.row[e] >= 0) entry(*A, row, nv + term.row[e]) -= wp * vt.dt_dlambda[c] * g.dlambda[e];
        }
    });
  }
  // A(row, col), which the pattern must hold.
  static double& entry(Matrix& A, int row, int col) {
    const int* b = A.innerIndexPtr() + A.outerIndexPtr()[col];
    const int* e = A.innerIndexPtr() + A.outerIndexPtr()[col + 1];
    const int* it = std::lower_bound(b, e, row);
    MAXENTFLOW_REQUIRE(it != e && *it == row, detail::cat("entry (", row, ", ", col, ") is not in the pattern"),
                       "FlowSystem::add_velocity_tractions");
    return A.valuePtr()[it - A.innerIndexPtr()];
  }

  const Mesh* mesh_;
  const FlowDiscretization* disc_;
  Assembler assembler_;
  ConstraintSet constraints_;
  SystemPattern pattern_;
  Eigen::VectorXd traction_;
  std::vector<VelocityTractionTerm> velocity_tractions_;
  std::vector<std::pair<int, int>> entry_pos_;
  std::vector<double> entry_coef_;
  struct LinearCompanion {
    FlowDiscretization disc;
    std::optional<Assembler> assembler;
    SystemPattern pattern;
    std::vector<std::pair<int, int>> entry_pos;
    long generation = -1;  // pattern_ generation its constraints match
  };
  std::unique_ptr<LinearCompanion> linear_;  // heap: its assembler points at its disc
  bool structure_dirty_ = true;
  DofLayout layout_;
  Eigen::VectorXd linearized_at_;  // the X of the assembler's last linearize()
  long generation_of_A_ = -1, generation_of_P_ = -1;
  double force_scale_ = 1.0;
};

}  // namespace maxentflow

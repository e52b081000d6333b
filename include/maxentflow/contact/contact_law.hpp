// maxentflow: contact laws, the policy that says what a rigid tool imposes at
// the workpiece nodes it touches (docs/architecture.md).
#pragma once

#include <algorithm>
#include <cmath>
#include <concepts>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/flow/velocity_traction.hpp>

namespace maxentflow {

/// A node put back at a fixed place before the step (an Eulerian zone's),
/// with its state against a tool at the end of the last step.
enum class PutBack : char {
  no,       ///< a material node
  unknown,  ///< put back, its last state unknown: as any node
  held,     ///< put back, held by the tool at the end of the last step
  free      ///< put back, free of the tool at the end of the last step
};

/// One boundary node's state against one tool.
struct ContactPoint {
  int node = -1;
  ToolProjection projection;
  double h = 0.0;  ///< nodal spacing, the scale of the gap tolerances
  bool active = false;
  int releases = 0;  ///< times the active set released it this step (at most once)
  /// An Eulerian zone's node, put back in place before the next step: released
  /// when tensile even inside a contact zone, and not taken back in this step
  /// (its penetration does not build up).
  bool put_back = false;
  int prev = -1, next = -1;  ///< neighbouring boundary nodes (indices into points())
  /// At a concave tool corner (ToolContact::params::corner_tol): the normal
  /// of the corner's second face, which gets a condition of its own.
  std::optional<Eigen::Vector2d> second_normal;
  /// The tool's tangent at the projection: the normal turned by +90 degrees.
  Eigen::Vector2d tangent() const { return {-projection.normal.y(), projection.normal.x()}; }
};

/// A velocity condition a law imposes at an active contact node, weakly with a
/// hat multiplier as Eq. (15): v . direction = target. Role 0 is the normal
/// condition, which the active set reads (a tensile multiplier releases the
/// node); role 1 a tangential one (sticking).
struct ContactCondition {
  Eigen::Vector2d direction = Eigen::Vector2d::Zero();
  double target = 0.0;
  int role = 0;
};

/// What a contact law supplies: a name and, for an active node of `tool` in a
/// step of dt, the conditions its multipliers impose, the normal one first.
/// Every active node of a tool gets the same roles in the same order.
template <class L>
concept ContactLaw = requires(const L& law, const ContactPoint& c, const RigidTool& tool, double dt,
                              std::vector<ContactCondition>& out) {
  { law.name() } -> std::convertible_to<std::string>;
  law.conditions(c, tool, dt, out);
};

/// What a traction law reads at a Gauss point of a contact segment (a segment
/// whose two ends are active on the tool).
struct ContactTractionPoint {
  Eigen::Vector2d x = Eigen::Vector2d::Zero();       ///< the point
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();  ///< the tool's outward normal there
  Eigen::Vector2d v = Eigen::Vector2d::Zero();       ///< the workpiece's velocity
  Eigen::Vector2d v_tool = Eigen::Vector2d::Zero();  ///< the tool's velocity
  /// The workpiece's shear flow stress there, sigma_eq / sqrt(3) (TractionPointState::k).
  double k = 0.0;
  /// The contact pressure there, -lambda of the normal hat multipliers
  /// (TractionPointState::lambda; > 0 compressive), for a law that reads it
  /// (reads_pressure); 0 for the others.
  double p_n = 0.0;
  /// The tool's tangent: the normal turned by +90 degrees.
  Eigen::Vector2d tangent() const { return {-normal.y(), normal.x()}; }
  /// The slip velocity: the tangential part of v - v_tool.
  Eigen::Vector2d slip() const { return (v - v_tool) - (v - v_tool).dot(normal) * normal; }
};

/// A law that also acts by a traction on its contact segments (friction
/// stress, not a multiplier): traction(point) gives t on the workpiece and
/// dt/dv, dt/dk (and dt/dp_n if it reads the contact pressure), integrated
/// over the contact segments by FlowSystem.
template <class L>
concept TractionContactLaw = ContactLaw<L> && requires(const L& law, const ContactTractionPoint& q) {
  { law.traction(q) } -> std::convertible_to<VelocityTraction>;
};

/// Whether a traction law reads ContactTractionPoint::p_n (a member
/// `bool reads_pressure() const`): its traction then couples to the normal
/// multipliers.
template <class L>
bool reads_contact_pressure(const L& law) {
  if constexpr (requires { { law.reads_pressure() } -> std::convertible_to<bool>; })
    return law.reads_pressure();
  else
    return false;
}

namespace detail {
// The regularized slip direction of Chen & Kobayashi: g(v_s) = f(|v_s|) v_s
// with f(s) = (2/pi) atan(s / v0) / s, and dg/dv = f P + f'(s)/s v_s v_s^T
// (P = I - n n^T), so that a friction stress tau gives t = -tau g.
struct SlipDirection {
  Eigen::Vector2d g = Eigen::Vector2d::Zero();
  Eigen::Matrix2d dg_dv = Eigen::Matrix2d::Zero();
  double magnitude = 0.0;  ///< |g| = (2/pi) atan(|v_s| / v0), in [0, 1)
};
inline SlipDirection slip_direction(const ContactTractionPoint& q, double v0) {
  constexpr double two_over_pi = 0.63661977236758134308;
  const Eigen::Vector2d vs = q.slip();
  const double s = vs.norm(), r = s / v0;
  double f = 0.0, df_over_s = 0.0;
  if (r < 1e-4) {  // series: atan(r)/r = 1 - r^2/3 + ...
    f = two_over_pi / v0 * (1.0 - r * r / 3.0);
    df_over_s = -two_over_pi * 2.0 / (3.0 * v0 * v0 * v0);
  } else {
    f = two_over_pi * std::atan(r) / s;
    df_over_s = (two_over_pi / (v0 * (1.0 + r * r)) - f) / (s * s);
  }
  const Eigen::Matrix2d P = Eigen::Matrix2d::Identity() - q.normal * q.normal.transpose();
  return {f * vs, f * P + df_over_s * vs * vs.transpose(), f * s};
}
inline void require_smoothing(double v0, const char* where) {
  MAXENTFLOW_REQUIRE(std::isfinite(v0) && v0 > 0.0,
                     detail::cat("the smoothing slip velocity v0 must be > 0, got ", v0), where);
}
}  // namespace detail

/// The normal condition of Eqs. (16)-(17) over a step: the gap at the step end
/// is zero, g + dt (v - v_tool) . n = 0, so (v . n) = v_tool . n - g / dt (a
/// small gap or penetration left by the last step is closed, errors do not add up).
inline ContactCondition normal_contact(const ContactPoint& c, const RigidTool& tool, double dt) {
  const Eigen::Vector2d& n = c.projection.normal;
  return {n, tool.velocity().dot(n) - c.projection.gap / dt, 0};
}

/// The paper's law: no friction, only the normal velocity is constrained.
struct Frictionless {
  static std::string name() { return "frictionless"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
  }
};

/// Full sticking: the node moves with the tool, normal and tangential
/// velocities both by multipliers (the tangential multiplier is the friction
/// stress, unbounded).
struct Sticking {
  static std::string name() { return "sticking"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
    const Eigen::Vector2d t = c.tangent();
    out.push_back({t, tool.velocity().dot(t), 1});
  }
};

/// Tresca friction with shear factor m: the friction stress m k opposes the
/// slip v_s, with k = sigma_eq / sqrt(3) of the material at the contact
/// (ContactTractionPoint::k), smoothed at small slip as flow-formulation codes
/// do (Chen & Kobayashi):
///   t = -m k (2/pi) atan(|v_s| / v0) v_s / |v_s|,
/// v0 a small slip velocity (e.g. 1e-2 of the tool speed): below it the
/// stress falls linearly to zero, so the law is smooth and Newton converges.
/// The normal condition is the frictionless one.
struct Tresca {
  double m = 0.0;   ///< shear factor in [0, 1]
  double v0 = 0.0;  ///< slip velocity scale of the smoothing (> 0)
  Tresca(double m_, double v0_) : m(m_), v0(v0_) {
    MAXENTFLOW_REQUIRE(std::isfinite(m) && m >= 0.0 && m <= 1.0,
                       detail::cat("shear factor m must be in [0, 1], got ", m), "Tresca");
    detail::require_smoothing(v0, "Tresca");
  }
  static std::string name() { return "tresca"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
  }
  /// t = -m k g(v_s) (detail::slip_direction), dt/dv = -m k dg/dv, dt/dk = -m g.
  VelocityTraction traction(const ContactTractionPoint& q) const {
    const detail::SlipDirection g = detail::slip_direction(q, v0);
    VelocityTraction out;
    out.t = -m * q.k * g.g;
    out.dt_dv = -m * q.k * g.dg_dv;
    out.dt_dk = -m * g.g;
    return out;
  }
};

/// Coulomb friction with coefficient mu, capped by the material's shear flow
/// stress: the friction stress tau = min(mu p_n, k) opposes the slip, with the
/// Tresca law's smoothing,
///   t = -min(mu p_n, k) (2/pi) atan(|v_s| / v0) v_s / |v_s|,
/// p_n >= 0 the contact pressure (the normal multiplier; a tensile value
/// counts as 0). Where mu p_n < k the stress follows the pressure (dt/dp_n),
/// elsewhere it is Tresca's with m = 1 (dt/dk).
struct Coulomb {
  double mu = 0.0;  ///< friction coefficient (>= 0)
  double v0 = 0.0;  ///< slip velocity scale of the smoothing (> 0)
  Coulomb(double mu_, double v0_) : mu(mu_), v0(v0_) {
    MAXENTFLOW_REQUIRE(std::isfinite(mu) && mu >= 0.0,
                       detail::cat("friction coefficient mu must be >= 0, got ", mu), "Coulomb");
    detail::require_smoothing(v0, "Coulomb");
  }
  static std::string name() { return "coulomb"; }
  /// mu = 0 reads nothing: the frictionless system, not even structural zeros.
  bool reads_pressure() const { return mu > 0.0; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
  }
  VelocityTraction traction(const ContactTractionPoint& q) const {
    const detail::SlipDirection g = detail::slip_direction(q, v0);
    const double p = std::max(q.p_n, 0.0);
    const bool capped = mu * p >= q.k;
    const double tau = capped ? q.k : mu * p;
    VelocityTraction out;
    out.t = -tau * g.g;
    out.dt_dv = -tau * g.dg_dv;
    // dt/dp_n; the system's dt/dlambda = -dt/dp_n (FlowSystem reads lambda).
    if (capped)
      out.dt_dk = -g.g;
    else if (q.p_n > 0.0)
      out.dt_dlambda = mu * g.g;
    return out;
  }
};

static_assert(ContactLaw<Frictionless> && ContactLaw<Sticking> && TractionContactLaw<Tresca> &&
              TractionContactLaw<Coulomb>);

/// Any ContactLaw, held by value semantics so that each tool of one simulation
/// can carry its own law type (the concept is checked where a law is given).
class AnyContactLaw {
 public:
  AnyContactLaw() : AnyContactLaw(Frictionless{}) {}
  template <ContactLaw L>
    requires(!std::same_as<std::decay_t<L>, AnyContactLaw>)
  AnyContactLaw(L law)  // NOLINT(google-explicit-constructor): a law converts to "any law"
      : self_(std::make_shared<const Model<L>>(std::move(law))) {}

  std::string name() const { return self_->name(); }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    self_->conditions(c, tool, dt, out);
  }
  /// Whether the held law is a TractionContactLaw; traction() is zero if not.
  bool has_traction() const { return self_->has_traction(); }
  /// Whether its traction reads the contact pressure (reads_contact_pressure).
  bool reads_pressure() const { return self_->reads_pressure(); }
  VelocityTraction traction(const ContactTractionPoint& q) const { return self_->traction(q); }

 private:
  struct Interface {
    virtual ~Interface() = default;
    virtual std::string name() const = 0;
    virtual void conditions(const ContactPoint&, const RigidTool&, double,
                            std::vector<ContactCondition>&) const = 0;
    virtual bool has_traction() const = 0;
    virtual bool reads_pressure() const = 0;
    virtual VelocityTraction traction(const ContactTractionPoint&) const = 0;
  };
  template <class L>
  struct Model final : Interface {
    explicit Model(L l) : law(std::move(l)) {}
    std::string name() const override { return law.name(); }
    void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                    std::vector<ContactCondition>& out) const override {
      law.conditions(c, tool, dt, out);
    }
    bool has_traction() const override { return TractionContactLaw<L>; }
    bool reads_pressure() const override { return reads_contact_pressure(law); }
    VelocityTraction traction(const ContactTractionPoint& q) const override {
      if constexpr (TractionContactLaw<L>)
        return law.traction(q);
      else
        return {};
    }
    L law;
  };
  std::shared_ptr<const Interface> self_;  // immutable: copies share it
};

static_assert(TractionContactLaw<AnyContactLaw>);

}  // namespace maxentflow

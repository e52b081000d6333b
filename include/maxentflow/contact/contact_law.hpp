// maxentflow: contact laws, the policy that says what a rigid tool imposes at
// the workpiece nodes it touches (docs/architecture.md).
#pragma once

#include <cmath>
#include <concepts>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/core/error.hpp>
#include <maxentflow/flow/velocity_traction.hpp>

namespace maxentflow {

/// One boundary node's state against one tool.
struct ContactPoint {
  int node = -1;
  ToolProjection projection;
  double h = 0.0;  ///< nodal spacing, the scale of the gap tolerances
  bool active = false;
  int releases = 0;  ///< times the active set released it this step (at most once)
  int prev = -1, next = -1;  ///< neighbouring boundary nodes (indices into points())
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
  /// The tool's tangent: the normal turned by +90 degrees.
  Eigen::Vector2d tangent() const { return {-normal.y(), normal.x()}; }
  /// The slip velocity: the tangential part of v - v_tool.
  Eigen::Vector2d slip() const { return (v - v_tool) - (v - v_tool).dot(normal) * normal; }
};

/// A law that also acts by a traction on its contact segments (friction
/// stress, not a multiplier): traction(point) gives t on the workpiece and
/// dt/dv, integrated over the contact segments by FlowSystem.
template <class L>
concept TractionContactLaw = ContactLaw<L> && requires(const L& law, const ContactTractionPoint& q) {
  { law.traction(q) } -> std::convertible_to<VelocityTraction>;
};

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
    MAXENTFLOW_REQUIRE(std::isfinite(v0) && v0 > 0.0,
                       detail::cat("the smoothing slip velocity v0 must be > 0, got ", v0), "Tresca");
  }
  static std::string name() { return "tresca"; }
  void conditions(const ContactPoint& c, const RigidTool& tool, double dt,
                  std::vector<ContactCondition>& out) const {
    out.push_back(normal_contact(c, tool, dt));
  }
  /// t = -m k f(|v_s|) v_s with f(s) = (2/pi) atan(s / v0) / s, and
  /// dt/dv = -m k (f P + f'(s)/s v_s v_s^T), P = I - n n^T; dt/dk = -m f v_s.
  VelocityTraction traction(const ContactTractionPoint& q) const {
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
    VelocityTraction out;
    out.t = -m * q.k * f * vs;
    out.dt_dv = -m * q.k * (f * P + df_over_s * vs * vs.transpose());
    out.dt_dk = -m * f * vs;
    return out;
  }
};

static_assert(ContactLaw<Frictionless> && ContactLaw<Sticking> && TractionContactLaw<Tresca>);

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
  VelocityTraction traction(const ContactTractionPoint& q) const { return self_->traction(q); }

 private:
  struct Interface {
    virtual ~Interface() = default;
    virtual std::string name() const = 0;
    virtual void conditions(const ContactPoint&, const RigidTool&, double,
                            std::vector<ContactCondition>&) const = 0;
    virtual bool has_traction() const = 0;
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

// maxentflow: viscosity laws of the flow formulation (paper Eqs. 7-9).
#pragma once

#include <cmath>
#include <concepts>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

/// The viscosity at an equivalent strain rate d = sqrt(2/3 D:D), and mu'(d)/d,
/// the factor the consistent tangent needs (finite at d = 0 for a regularized law).
struct Viscosity {
  double mu = 0.0;
  double dmu_dd_over_d = 0.0;
};

/// What a viscosity law reads at one integration point: the equivalent strain
/// rate and where the point is (a part made of zones of different material).
/// State a law may need later (temperature, effective strain) is added here,
/// filled by the assembler, without changing the laws that ignore it.
struct MaterialPoint {
  double d = 0.0;                             ///< sqrt(2/3 D:D)
  Eigen::Vector2d x = Eigen::Vector2d::Zero();  ///< position (r, z) or (x, y)
};

/// A material policy: sigma' = 2 mu D (Eq. 7) with mu from the point's state.
/// The Newton tangent is then 2 mu I + 2 D (x) dmu/dD with
/// dmu/dD = mu'(d) (2/3) D / d.
template <class M>
concept ViscosityLaw = requires(const M& m, const MaterialPoint& point) {
  { m.viscosity(point) } -> std::convertible_to<Viscosity>;
};

/// Norton-Hoff power law, Eq. (9): mu = mu0 (sqrt(3) d)^(n-1), so the flow
/// stress is 3 mu d = sqrt(3) mu0 (sqrt(3) d)^n.
///
/// For n < 1, mu blows up where d -> 0 (rigid zones). The law is regularized as
/// mu = mu0 (sqrt(3) d_eff)^(n-1) with d_eff = sqrt(d^2 + d_min^2), smooth so that
/// Newton keeps its quadratic rate. Where d >> d_min the law is unchanged
/// (relative change of mu ~ (1-n) d_min^2 / (2 d^2)); in a rigid zone (d ~ 0) mu
/// is capped at mu0 (sqrt(3) d_min)^(n-1), so the zone creeps at a rate of order
/// d_min. Take d_min a few decades below the process strain rate (V / H):
/// the forces then change by O(d_min / (V/H)) at most, and the conditioning of
/// the system grows like (V/H / d_min)^(1-n).
struct NortonHoff {
  double mu0 = 150.0;
  double n = 0.2;
  double d_min = 1e-6;

  NortonHoff() = default;
  NortonHoff(double mu0_, double n_, double d_min_ = 1e-6) : mu0(mu0_), n(n_), d_min(d_min_) {
    require(std::isfinite(mu0) && mu0 > 0, detail::cat("mu0 must be positive, got ", mu0),
            "NortonHoff");
    require(std::isfinite(n) && n > 0, detail::cat("n must be positive, got ", n), "NortonHoff");
    require(std::isfinite(d_min) && d_min >= 0 && (n == 1.0 || d_min > 0),
            detail::cat("d_min must be positive for n != 1, got ", d_min), "NortonHoff");
  }

  Viscosity viscosity(const MaterialPoint& point) const { return viscosity(point.d); }
  /// The law at a bare strain rate (formulas, exact solutions).
  Viscosity viscosity(double d) const {
    const double d2 = d * d + d_min * d_min;
    if (n == 1.0) return {mu0, 0.0};
    const double mu = mu0 * std::pow(3.0 * d2, 0.5 * (n - 1.0));
    return {mu, mu * (n - 1.0) / d2};  // d mu / d d = mu (n-1) d / d_eff^2
  }
  /// Flow stress (equivalent stress) at the strain rate d: sqrt(3/2 s:s) = 3 mu d.
  double flow_stress(double d) const { return 3.0 * viscosity(d).mu * d; }
};

/// A Newtonian fluid (mu constant): Stokes flow, the n = 1 Norton-Hoff law.
struct Newtonian {
  double mu = 1.0;
  Viscosity viscosity(const MaterialPoint&) const { return {mu, 0.0}; }
  Viscosity viscosity(double) const { return {mu, 0.0}; }
};

static_assert(ViscosityLaw<NortonHoff> && ViscosityLaw<Newtonian>);

}  // namespace maxentflow

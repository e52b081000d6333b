// maxentflow: a boundary traction that depends on the velocity, the
// material's flow stress and a contact multiplier (friction): what
// FlowSystem integrates and a contact law supplies.
#pragma once

#include <functional>

#include <Eigen/Core>

namespace maxentflow {

/// What a velocity-dependent traction reads at a boundary Gauss point.
struct TractionPointState {
  Eigen::Vector2d x = Eigen::Vector2d::Zero();  ///< the point
  Eigen::Vector2d v = Eigen::Vector2d::Zero();  ///< the workpiece's velocity there
  /// The material's shear flow stress k = sigma_eq / sqrt(3) = sqrt(3) mu(d) d
  /// (incompressible, s = 2 mu D, d = sqrt(2/3 D:D)), with D the mean strain
  /// rate of the boundary segment's triangle.
  double k = 0.0;
  /// The multiplier traction of a linked constraint part at the point (the
  /// workpiece feels -lambda e there, e its rows' direction): the hat
  /// multipliers of the segment's ends interpolated, per unit area (divided
  /// by 2 pi r when axisymmetric). Zero with no linked part. A contact normal
  /// e points into the workpiece, so the contact pressure is p_n = -lambda.
  double lambda = 0.0;
};

/// t, the traction on the workpiece at a boundary point, and its derivatives
/// with respect to the velocity there and to k (Newton's tangent).
struct VelocityTraction {
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  Eigen::Matrix2d dt_dv = Eigen::Matrix2d::Zero();
  Eigen::Vector2d dt_dk = Eigen::Vector2d::Zero();
  Eigen::Vector2d dt_dlambda = Eigen::Vector2d::Zero();
};

/// t(state) at a boundary point.
using VelocityTractionLaw = std::function<VelocityTraction(const TractionPointState&)>;

}  // namespace maxentflow

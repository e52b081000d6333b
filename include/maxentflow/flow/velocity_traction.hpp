// maxentflow: a boundary traction that depends on the velocity (friction),
// what FlowSystem integrates and a contact law supplies.
#pragma once

#include <functional>

#include <Eigen/Core>

namespace maxentflow {

/// t, the traction on the workpiece at a boundary point, and dt/dv, its
/// derivative with respect to the velocity there (Newton's tangent).
struct VelocityTraction {
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  Eigen::Matrix2d dt_dv = Eigen::Matrix2d::Zero();
};

/// t(x, v) at a boundary point x where the workpiece moves with v.
using VelocityTractionLaw = std::function<VelocityTraction(const Eigen::Vector2d& x, const Eigen::Vector2d& v)>;

}  // namespace maxentflow

// maxentflow: the two linearizations of the nonlinear flow problem, shared by
// the systems that assemble them and the solver that chooses between them.
#pragma once

namespace maxentflow {

/// Picard (direct iteration: mu and tau frozen at the current iterate) or
/// Newton (consistent tangent, including d tau / d v).
enum class Linearization { picard, newton };

}  // namespace maxentflow

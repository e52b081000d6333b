// maxentflow: the two linearizations of the nonlinear flow problem, shared by
// the systems that assemble them and the solver that chooses between them.
#pragma once

namespace maxentflow {

/// Picard (direct iteration: mu and tau frozen at the current iterate),
/// Newton (consistent tangent, including d tau / d v), or Newton's tangent
/// without d tau / d v, which is symmetric where Picard's matrix is: not a
/// linearization to iterate with, but the matrix whose L D L^T
/// preconditions Newton's (half the work of an LU of Newton's tangent).
enum class Linearization { picard, newton, newton_symmetric };

}  // namespace maxentflow

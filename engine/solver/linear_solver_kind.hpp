// The linear solver of the linearised step ("solver.linear" in a scene; linearized_step.hpp).
#pragma once

#include <cstdint>

namespace nexdyn {

enum class LinearSolverKind : uint8_t {
  cholmod,  // one CHOLMOD factorisation of the step's matrix
  pcg,      // matrix-free Jacobi-preconditioned conjugate gradients
};

}  // namespace nexdyn

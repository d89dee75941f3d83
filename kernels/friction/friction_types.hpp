// The value types of IPC's lagged friction (kernels/friction/friction.hpp has the math and the
// conventions): the stencil kinds, a contact's lagged basis, and its Coulomb coefficients. Apart
// from the kernels so that headers which only store these (engine/contact/friction_potential.hpp,
// and through it most of the engine) do not parse the distance and friction kernels: that cost
// every file including the simulation about 8 s of compiling.
#pragma once

#include <Eigen/Core>

#include <cstdint>

namespace nexdyn {

using Vector12d = Eigen::Matrix<double, 12, 1>;

// The closest feature pair of a contact stencil (mirrors the barrier's stencil kinds; a mollified
// edge-edge stencil uses edge_edge with the closest features of its case, see friction_basis).
enum class FrictionStencil : uint8_t {
  vertex_plane, point_point, point_edge, point_triangle, edge_edge
};

// Number of stencil vertices n: the meaningful part of the padded 12-DOF values is the first 3 n.
inline int friction_stencil_size(FrictionStencil kind) {
  switch (kind) {
    case FrictionStencil::vertex_plane: return 1;
    case FrictionStencil::point_point: return 2;
    case FrictionStencil::point_edge: return 3;
    case FrictionStencil::point_triangle: return 4;
    case FrictionStencil::edge_edge: return 4;
  }
  return 4;
}

// Lagged geometry of one contact, computed once per lagging iteration (112 bytes).
struct FrictionBasis {
  Eigen::Matrix<double, 3, 2> P;  // orthonormal basis of the tangent plane at x^t
  Eigen::Vector4d w;              // closest-point weights: Gamma = w^T (x) I3, zero past n
  int num_points = 0;             // stencil vertices n
};

// Coulomb coefficients of a contact (see the top): static, below the sticking speed, and
// kinetic, above twice it. mu_s = mu_k is plain IPC friction.
struct FrictionCoefficients {
  double mu_s = 0.0;
  double mu_k = 0.0;
};

}  // namespace nexdyn

// What an MPM scene holds besides its settings (issue 23): the background grid, the particles at
// the start, and the grid's boundary conditions. Built once by the scene reader
// (engine/scene/mpm_scene.cpp); the MPM step (engine/mpm/mpm_step.hpp) only reads it.
#pragma once

#include "engine/model.hpp"
#include "engine/mpm/particles.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace nexdyn {

// How a plane obstacle acts on the grid nodes on or behind it (docs/scenes.md, "MPM").
enum class PlaneCondition : uint8_t {
  separating,  // the node may not move into the plane but may leave it (the default)
  slip,        // the node keeps its normal position: it slides along the plane and never leaves
  sticky,      // the node is held
};

struct MpmPlane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    // [m]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();  // unit length, pointing to the free side
  PlaneCondition condition = PlaneCondition::separating;
  double signed_distance(const Eigen::Vector3d& x) const { return normal.dot(x - point); }
};

// A "boundary" box: the grid nodes inside the box, carried by its rigid motion, follow that
// motion (a fixed box holds them).
struct MpmBox {
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero();  // [m], at t = 0
  Eigen::Vector3d box_max = Eigen::Vector3d::Zero();  // [m]
  DirichletMotion motion;
};

struct MpmModel {
  double grid_spacing = 0.0;                              // h [m]
  Eigen::Vector3d domain_min = Eigen::Vector3d::Zero();   // [m]
  Eigen::Vector3d domain_max = Eigen::Vector3d::Zero();   // [m]
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();      // [m/s^2]
  std::vector<Material> materials;
  Particles initial;                   // the particles at t = 0 (rest shape: F = I, C = 0)
  std::vector<int32_t> particle_body;  // (num_particles) the "bodies" entry of each particle
  int32_t num_bodies = 0;
  std::vector<MpmPlane> planes;
  std::vector<MpmBox> boxes;
  double friction = 0.0;               // Coulomb coefficient of separating planes (contact.friction)
};

}  // namespace nexdyn

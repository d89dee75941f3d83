// Model: everything about the world that stays constant while it steps.
//
// MuJoCo-style flat buffers: one contiguous array per attribute, indexed by global vertex or tet
// id, each declared once here with its shape and units. Bodies are ranges of those arrays, not
// objects. Only scene loading writes it (engine/scene/: load_scene sets gravity and materials, the
// model builder build_model.cpp appends everything else); every stage of a step reads the Model
// through a const reference.
#pragma once

#include "engine/integrator.hpp"
#include "kernels/elasticity/material.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace nexdyn {

// Rayleigh damping D = stiffness K(x_n) + mass M (seed 004): the force -D v_{n+1}.
struct RayleighDamping {
  double mass = 0.0;       // a2 [1/s]
  double stiffness = 0.0;  // a1 [s]
  bool any() const { return mass > 0.0 || stiffness > 0.0; }
};

struct Material {
  std::string name;
  MaterialModel model = MaterialModel::neohookean;
  // "arap": Psi = mu ||F - R||^2 (Wang 2015), which is the corotated model with lambda = 0; it
  // runs the corotated kernels with lame.lambda = 0.
  bool arap = false;
  RayleighDamping damping;
  LameParameters lame;
  double youngs = 0.0;   // [Pa]
  double poisson = 0.0;  // [-]
  double density = 0.0;  // [kg/m^3]
  // "affine": the bodies of this material are affine bodies (AffineBody below), held to a rotation
  // by the orthogonality potential of this stiffness instead of deforming by the elastic model.
  bool affine = false;
  double stiffness = 0.0;  // [Pa] kappa of kappa V ||A A^T - I||^2 (affine only)
};

// The orthogonality stiffness of an affine material that gives none [Pa]: 1e8, Lan et al. 2022's
// choice for stiff bodies (the body's strain under its own contact forces is about force / (kappa
// area), so 1e8 keeps centimetre bodies' shape to well under a micrometre).
inline constexpr double kAffineStiffness = 1e8;

// A body is a range of vertices, tets and surface triangles/edges in the flat arrays.
struct BodyRange {
  int32_t vertex_begin = 0, vertex_count = 0;
  int32_t tet_begin = 0, tet_count = 0;
  int32_t triangle_begin = 0, triangle_count = 0;
  int32_t edge_begin = 0, edge_count = 0;
  int32_t scene_entry = 0;  // index of the "bodies" entry of the scene file it came from
                            // (of the "obstacles" entry when obstacle is true)
  bool obstacle = false;    // a static obstacle mesh: no tets, every vertex fixed, mass 0
  int32_t material = -1;    // index into materials (an obstacle's optional "material": -1 = none);
                            // friction coefficients are looked up per material pair
};

// An analytic obstacle plane {x : (x - point) . normal = 0}; bodies stay on the side the normal
// points to.
struct ObstaclePlane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   // [m]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY(); // unit length
  int32_t scene_entry = 0;                           // index of its "obstacles" entry
  int32_t material = -1;                             // its optional "material" (friction), -1 = none
};

// Consecutive tets sharing one material: the unit over which kernels dispatch on the model.
struct MaterialBatch {
  int32_t tet_begin = 0, tet_end = 0;
  int32_t material = 0;
};

// A prescribed rigid motion of a set of vertices (a "boundary" entry of the scene):
//   p(t) = center + v t + R(axis, omega t) (p(0) - center)
// "fix" is the motion with v = 0 and omega = 0.
//
// Kinematic motions (moving ones in a scene with contact) drive vertices that must push bodies
// out of their way: those vertices stay unknowns of the step, pulled to their targets by an
// augmented Lagrangian (engine/potential/kinematic_targets.hpp) so that CCD sweeps their motion like any
// other. Other held vertices are eliminated from the Newton system.
struct DirichletMotion {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // [m/s]
  Eigen::Vector3d center = Eigen::Vector3d::Zero();    // [m], a point on the rotation axis at t=0
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();     // unit vector
  double angular_velocity = 0.0;                       // [rad/s] about axis (right-hand rule)
  bool kinematic = false;                              // see above

  bool moves() const { return velocity != Eigen::Vector3d::Zero() || angular_velocity != 0.0; }

  // The point that started at p0, at time t: its position, velocity and acceleration.
  struct Point {
    Eigen::Vector3d x, v, a;
  };
  Point at(const Eigen::Vector3d& p0, double t) const {
    const Eigen::Vector3d r = Eigen::AngleAxisd(angular_velocity * t, axis) * (p0 - center);
    const Eigen::Vector3d w = angular_velocity * axis;
    return {center + velocity * t + r, velocity + w.cross(r), w.cross(w.cross(r))};
  }
  // The start point p0 that the motion carries to x at time t (at() inverted).
  Eigen::Vector3d origin(const Eigen::Vector3d& x, double t) const {
    return center + Eigen::AngleAxisd(-angular_velocity * t, axis) * (x - center - velocity * t);
  }
};

// A joint (DESIGN.md section 5, "joints"; issue 4). Its constraint is linear in the positions:
//   c(x) = sum_k coefficient[k] x[vertex[k]] + offset = 0   (3 equations).
// A joint point is carried by a tet of its body with fixed barycentric weights w (extrapolated
// when the point lies outside the tet), or on an affine body by its four nodes with weights
// 1, y_0, y_1, y_2 (the point's rest coordinates in the body's principal frame). A pin holds it at its start position: the first 4 terms
// are +w and offset = -point. A ball joint holds the two bodies' copies together: +w of the first
// body's tet, then -w of the second's, and offset = 0.
enum class JointType : uint8_t { pin, ball };

struct Joint {
  JointType type = JointType::pin;
  int count = 4;                    // terms: 4 (pin) or 8 (ball)
  int32_t vertex[8] = {};           // tet corners
  double coefficient[8] = {};       // +w, then -w
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // [m]
  int32_t scene_entry = 0;          // index of its "joints" entry
};

// An affine body (kernels/affine/affine_body.hpp; issue 40): a stiff body as 12 coordinates, held
// in four node vertices of its own, p (its centre of mass) and c_0, c_1, c_2 (the columns of
// A R, R its principal frame at rest), whose masses are the body's mass m and its principal
// second moments L_j = integral rho y_j^2 dV (the mass matrix is diagonal in these coordinates).
// Its surface vertices follow the nodes: x = p + y_0 c_0 + y_1 c_1 + y_2 c_2 with y their rest
// coordinates in the principal frame (Model::follower_rest; engine/coordinate_map.hpp).
struct AffineBody {
  int32_t body = -1;            // index into bodies
  int32_t node = -1;            // its node vertices: node (p), node + 1 .. node + 3 (c_0 .. c_2)
  int32_t follower_begin = 0;   // its followers: vertices [follower_begin, + follower_count)
  int32_t follower_count = 0;
  double volume = 0.0;          // [m^3]
  double stiffness = 0.0;       // kappa of the orthogonality potential kappa V ||A A^T - I||^2 [Pa]
  Eigen::Matrix3d frame = Eigen::Matrix3d::Identity();  // R: the principal axes at rest (columns)
};

struct Model {
  // ---- per vertex (num_vertices) -----------------------------------------------------------
  int32_t num_vertices = 0;
  std::vector<double> rest_positions;  // (num_vertices x 3) X [m], the scene's start positions
  std::vector<double> mass;            // (num_vertices) lumped mass [kg]: density * volume / 4
  std::vector<int32_t> vertex_body;    // (num_vertices) owning body id
  std::vector<int32_t> dirichlet;      // (num_vertices) index into dirichlet_motions, -1 = free

  // ---- per tet (num_tets) ------------------------------------------------------------------
  int32_t num_tets = 0;
  std::vector<int32_t> tets;         // (num_tets x 4) vertex ids, det[X1-X0, X2-X0, X3-X0] > 0
  std::vector<double> Dm_inv;        // (num_tets x 9) inverse rest edge matrix, column-major [1/m]
  std::vector<double> rest_volume;   // (num_tets) [m^3]
  std::vector<int32_t> tet_material; // (num_tets) index into materials

  // ---- surface: the collision mesh and the OBJ output ---------------------------------------
  // Static obstacle meshes are bodies too (BodyRange::obstacle): their vertices sit in the vertex
  // arrays with mass 0 and a fixed Dirichlet motion, their triangles and edges in these arrays.
  std::vector<int32_t> surface_triangles;  // (num_triangles x 3) outward-wound vertex ids
  std::vector<int32_t> surface_edges;      // (num_edges x 2) vertex ids, a < b
  std::vector<int32_t> surface_vertices;   // (num_surface_vertices) sorted vertex ids

  // ---- bodies, materials, conditions -------------------------------------------------------
  std::vector<BodyRange> bodies;
  std::vector<Material> materials;
  std::vector<MaterialBatch> material_batches;     // covers [0, num_tets) in order
  std::vector<DirichletMotion> dirichlet_motions;  // one per "boundary" entry, then one shared
                                                   // fixed motion for obstacle meshes
  std::vector<ObstaclePlane> obstacle_planes;
  std::vector<Joint> joints;
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, -9.81, 0.0);  // [m/s^2]

  // ---- affine bodies (empty in a scene without them) ---------------------------------------
  std::vector<AffineBody> affine_bodies;
  // (num_vertices) the affine body vertex v follows (>= 0), or what it is: kOwnNode (a tet or
  // obstacle vertex), kCentreNode (an affine body's p), kAxisNode (its c_0, c_1 or c_2)
  std::vector<int32_t> follows;
  std::vector<double> follower_rest;   // (num_vertices x 3) a follower's y (principal frame) [m]
  std::vector<int32_t> affine_tets;    // (x 4) the affine bodies' tets, follower ids: for frames only

  int64_t num_dofs() const { return 3 * int64_t{num_vertices}; }
  bool has_dirichlet() const { return !dirichlet_motions.empty(); }
  // Held out of the Newton system: on a Dirichlet motion that is not kinematic.
  bool eliminated(int32_t v) const { return dirichlet[v] >= 0 && !dirichlet_motions[dirichlet[v]].kinematic; }

  static constexpr int32_t kOwnNode = -1, kCentreNode = -2, kAxisNode = -3;
  // A vertex that follows an affine body's nodes: no unknown of its own (engine/coordinate_map.hpp).
  bool follows_body(int32_t v) const { return !follows.empty() && follows[v] >= 0; }
  // An affine body's axis node c_j: its "mass" is a second moment [kg m^2], its position a column
  // of A R, so gravity does not act on it and it carries no linear momentum.
  bool axis_node(int32_t v) const { return !follows.empty() && follows[v] == kAxisNode; }
  // The mass gravity pulls and linear momentum counts at vertex v [kg].
  double translational_mass(int32_t v) const { return axis_node(v) ? 0.0 : mass[v]; }
};

}  // namespace nexdyn

// Intersection checks of triangle surfaces: an independent referee for contact simulation.
//
// IPC promises that surfaces never intersect (Li et al., "Incremental Potential Contact",
// SIGGRAPH 2020), so a test can check every output frame, and `nexdyn check` / `nexdyn run`
// refuse a scene whose bodies already intersect at the start (a barrier cannot separate them).
// The checker must therefore not share code with the contact pipeline (distances, CCD): it only
// uses exact orientation predicates.
//
// Exactness. orient3d / orient2d are evaluated in double with Shewchuk's static error bound
// ("Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997,
// bound A); when the bound cannot decide, they are recomputed exactly with floating-point
// expansions. With exact signs, triangles_intersect is exact unless a product of three
// coordinate differences (or of their rounding errors) underflows or overflows, which needs
// coordinates or their differences of order 1e-100 or beyond 1e100; scenes in metres are far
// from both. So:
//  - touching counts: closed triangles sharing one point (a vertex on the other's interior, a
//    shared vertex or edge, coplanar neighbours) intersect;
//  - coplanar triangles are tested in 2D and intersect when they overlap or touch;
//  - a zero-area triangle (three collinear vertices) is the union of its edges and is handled as
//    such against a proper triangle; two zero-area triangles are reported as NOT intersecting
//    (segment-segment contact in 3D is not checked, mesh surfaces never contain such pairs).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "bvh/broad_phase.hpp"

namespace nexdyn {

// Sign of det[b - a, c - a, d - a]: +1 when d lies on the side of triangle (a, b, c) that its
// right-hand normal points to, -1 on the other side, 0 exactly when the four points are coplanar.
int orient3d_sign(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  const Eigen::Vector3d& d);

// Closed triangles (a0,a1,a2) and (b0,b1,b2) share at least one point. Exact (see above).
bool triangles_intersect(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                         const Eigen::Vector3d& a2, const Eigen::Vector3d& b0,
                         const Eigen::Vector3d& b1, const Eigen::Vector3d& b2);

// Closed triangles (v, p1, p2) and (v, q1, q2), which share the corner v, have a point other
// than v in common: they cross, touch elsewhere, or overlap from v on (in one plane, their
// corners at v overlapping). Exact like triangles_intersect; both triangles must have non-zero
// area. For the surface check (engine/mesh/self_intersection.hpp), where two triangles around a
// vertex may fold through each other although they always touch at the vertex.
bool triangles_overlap_beyond_vertex(const Eigen::Vector3d& v, const Eigen::Vector3d& p1,
                                     const Eigen::Vector3d& p2, const Eigen::Vector3d& q1,
                                     const Eigen::Vector3d& q2);

// All pairs (i, j), i < j, of triangles that share NO vertex id and intersect; sorted.
//   x: (num_vertices x 3) packed xyz positions; triangles: (num_triangles x 3) vertex ids.
// Triangles sharing a vertex always touch there, so they are skipped: an intersection of two
// neighbours elsewhere (a fold through a shared vertex) is not detected. Broad phase: Embree
// (bvh/broad_phase.hpp) on the exact triangle boxes, so no candidate is lost.
// Throws std::invalid_argument when num_triangles does not fit in int32.
std::vector<IndexPair> intersecting_triangle_pairs(const double* x, const int32_t* triangles,
                                                   int64_t num_triangles);

// Generalised winding number of the triangle surface around p (Jacobson et al., "Robust
// Inside-Outside Segmentation using Generalized Winding Numbers", SIGGRAPH 2013): the sum of the
// signed solid angles of the triangles seen from p, over 4 pi. 1 inside and 0 outside a closed
// outward-wound surface, -1 inside an inward-wound one; about 1/2 on the surface.
double winding_number(const Eigen::Vector3d& p, const double* x, const int32_t* triangles,
                      int64_t num_triangles);

// True when p lies inside the closed surface (|winding_number| > 1/2). Points on the surface,
// or within round-off of it, may go either way.
bool point_inside_surface(const Eigen::Vector3d& p, const double* x, const int32_t* triangles,
                          int64_t num_triangles);

}  // namespace nexdyn

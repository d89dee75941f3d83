// Narrow-phase continuous collision detection (CCD) for linearly moving primitives over t in
// [0, 1]: point-triangle, edge-edge and point-plane. Used by the IPC line search to cap a Newton
// step so that no pair reaches distance 0 (DESIGN.md section 5), and by `nexdyn ccd`.
//
// Method: additive CCD (Li, Kaufman, Jiang, "Codimensional Incremental Potential Contact",
// ACM TOG 2021, section 4 / Algorithm 1). Subtracting the mean displacement, lp = max |p_i| over
// one primitive + max |p_j| over the other bounds how fast the distance can shrink, so from a
// certified lower bound d of the distance at time t the interval [t, t + 0.9 d / lp] is free of
// contact (the distance stays >= 0.1 d). Repeating this advances monotonically toward the first
// contact, never past it. Our own variations:
//   * every distance is a certified lower bound (kernels/ccd/ccd_distance.hpp subtracts a rounding
//     error bound), so rounding can only make the answer more cautious, never a false negative;
//   * positions are recomputed as x0 + t (x1 - x0) at each step instead of accumulated;
//   * the stop gap is g = min(min_distance, 0.1 d(0)): the reported toi has distance in about
//     [0.1 g, g] (> 0), so a step capped at toi never ends touching, even when d(0) is already
//     below min_distance;
//   * a query already touching at t = 0 (lower bound <= 0, i.e. within rounding) reports toi = 0.
//
// Contract of all three functions: returns true iff a time toi in [0, tmax] was found where the
// distance is <= the gap (a possible contact; false positives allowed, false negatives never);
// then toi <= the first contact time and the distance is > 0 on [0, toi) (and at toi unless
// toi = 0 because the primitives already touch). Returns false only if the primitives certainly
// stay apart on [0, tmax]. After kCcdMaxIterations advancement steps (grazing motions), or once
// a step no longer changes t in double precision, the current, still safe, time is returned as a
// collision. Pure math: no allocation, threads, I/O or
// exceptions.
#pragma once

#include <Eigen/Core>

namespace nexdyn {

// Advancement steps before giving up conservatively (returning the current safe time).
inline constexpr int kCcdMaxIterations = 1'000'000;

// Point p against triangle (t0, t1, t2); suffix _0 = position at t = 0, _1 = at t = 1.
bool point_triangle_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& t0_0, const Eigen::Vector3d& t1_0,
                        const Eigen::Vector3d& t2_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& t0_1,
                        const Eigen::Vector3d& t1_1, const Eigen::Vector3d& t2_1, double min_distance,
                        double tmax, double& toi);

// Edge (ea0, ea1) against edge (eb0, eb1).
bool edge_edge_ccd(const Eigen::Vector3d& ea0_0, const Eigen::Vector3d& ea1_0, const Eigen::Vector3d& eb0_0,
                   const Eigen::Vector3d& eb1_0, const Eigen::Vector3d& ea0_1, const Eigen::Vector3d& ea1_1,
                   const Eigen::Vector3d& eb0_1, const Eigen::Vector3d& eb1_1, double min_distance, double tmax,
                   double& toi);

// Whether the primitives may touch (distance 0) on [0, tmax]: the question of the CCD benchmark
// queries (`nexdyn ccd`), asked with no gap. Same contract as above with min_distance = 0, and
// false positives only for near misses within the long-double rounding slack (64 eps = 7e-18 of
// the coordinates' scale) or motions that stay so close that 1,000 long-double steps do not get
// past them.
// Method: the double CCD above with a gap of 1e-11 of the query's size; if it reports, the
// query is continued from its toi (the primitives are certified apart up to there) in long double
// (64-bit mantissa on x86-64) with gap 0. Only the reported queries pay for the second pass.
bool point_triangle_touch_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& t0_0, const Eigen::Vector3d& t1_0,
                              const Eigen::Vector3d& t2_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& t0_1,
                              const Eigen::Vector3d& t1_1, const Eigen::Vector3d& t2_1, double tmax, double& toi);
bool edge_edge_touch_ccd(const Eigen::Vector3d& ea0_0, const Eigen::Vector3d& ea1_0, const Eigen::Vector3d& eb0_0,
                         const Eigen::Vector3d& eb1_0, const Eigen::Vector3d& ea0_1, const Eigen::Vector3d& ea1_1,
                         const Eigen::Vector3d& eb0_1, const Eigen::Vector3d& eb1_1, double tmax, double& toi);

// Moving point against a static plane (obstacle), plane_unit_normal of length 1. The signed
// distance is linear in t, so this one is closed form; "distance" is |signed distance|.
bool point_plane_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& plane_point,
                     const Eigen::Vector3d& plane_unit_normal, double min_distance, double tmax, double& toi);

}  // namespace nexdyn

// Self-intersections of a triangle surface: pairs of its triangles that touch where they should
// not. The last topological-geometric test before a closed surface is handed to tetrahedralisation
// (surface_check.hpp), which needs a surface that bounds a volume without touching itself.
//
// Which pairs count (the exact tests of engine/mesh/intersection.hpp decide each):
//  - sharing no vertex id: any common point (crossing or touching);
//  - sharing exactly one vertex id: any common point other than that vertex;
//  - sharing an edge: never. Neighbours across an edge always meet along it, and the only way
//    they can overlap more is to fold onto each other in one plane (a dihedral angle of 0). That
//    fold is not detected here; it leaves the surface's orientation consistent and its volume
//    unchanged, so none of the other checks catch it either.
// Vertices are compared by id: two ids at one position are two vertices that touch. Touching
// counts, with no tolerance, because the tests are exact.
//
// This is intersecting_triangle_pairs (the contact module's referee, which skips every pair
// that shares a vertex) plus the pairs around a shared vertex, with another broad phase: a
// BoxTree (bvh/box_tree.hpp) over the triangles' exact double boxes, queried with each triangle's
// box for the triangles after it. That finds exactly the pairs of an O(n^2) loop over closed
// boxes, in O(n log n) for a surface (5e9 pair tests become 10^6 for 100k triangles), about twice
// as fast as Embree's rtcCollide here and without its list of all pairs. A sweep along one axis
// would not do: on a face normal to that axis (a box, a mat) every triangle has the same interval
// on it, so all pairs of the face would be tested.
// Triangles are handled in chunks of consecutive ids, in parallel, each chunk's pairs tested in
// (i, j) order, so "the first" pair is the same on every run and thread count.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <utility>
#include <vector>

namespace nexdyn {

using TrianglePair = std::pair<int32_t, int32_t>;  // (i, j) 0-based triangle indices, i < j

// positions: (num_vertices x 3) [m], finite; triangles: (num_triangles x 3) ids in range, no
// degenerate (zero-area) triangle.

// Triangles i and j of the surface touch in a way listed above.
bool triangles_collide(std::span<const double> positions, std::span<const int32_t> triangles, int32_t i,
                       int32_t j);

// The lexicographically first pair (i < j) that collides, or nullopt.
std::optional<TrianglePair> first_self_intersection(std::span<const double> positions,
                                                    std::span<const int32_t> triangles);

// Every colliding pair, sorted.
std::vector<TrianglePair> self_intersections(std::span<const double> positions,
                                             std::span<const int32_t> triangles);

// The same by testing all n (n - 1) / 2 pairs: the reference for tests.
std::vector<TrianglePair> self_intersections_brute_force(std::span<const double> positions,
                                                         std::span<const int32_t> triangles);

}  // namespace nexdyn

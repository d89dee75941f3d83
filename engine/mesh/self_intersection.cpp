// Self-intersection search: box queries on a BoxTree, then the exact pair tests of the contact
// module's intersection checker (see self_intersection.hpp).
#include "engine/mesh/self_intersection.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <atomic>

#include "bvh/box_tree.hpp"
#include "engine/mesh/intersection.hpp"
#include "engine/parallel.hpp"

namespace nexdyn {
namespace {

// Triangles per chunk of the parallel search: a few hundred box queries amortise the scheduling.
constexpr int64_t kChunk = 512;

Eigen::Vector3d vertex(std::span<const double> positions, int32_t id) {
  return Eigen::Vector3d::Map(&positions[3 * static_cast<std::size_t>(id)]);
}

// The colliding pairs (i < j), sorted; with `first_only`, at least the first of them and maybe a
// few more (the caller takes the first). Every pair whose closed boxes overlap is tested: touching
// triangles have touching boxes, so none is missed.
std::vector<TrianglePair> colliding_pairs(std::span<const double> positions, std::span<const int32_t> triangles,
                                          bool first_only) {
  const auto n = static_cast<int32_t>(triangles.size() / 3);
  std::vector<double> lower(3 * static_cast<std::size_t>(n)), upper(3 * static_cast<std::size_t>(n));
  for (int32_t t = 0; t < n; ++t) {
    const Eigen::Vector3d a = vertex(positions, triangles[3 * t]);
    const Eigen::Vector3d b = vertex(positions, triangles[3 * t + 1]);
    const Eigen::Vector3d c = vertex(positions, triangles[3 * t + 2]);
    Eigen::Vector3d::Map(&lower[3 * t]) = a.cwiseMin(b).cwiseMin(c);
    Eigen::Vector3d::Map(&upper[3 * t]) = a.cwiseMax(b).cwiseMax(c);
  }
  BoxTree tree;
  tree.build(lower.data(), upper.data(), 0, n);
  const int64_t num_chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::vector<TrianglePair>> found(static_cast<std::size_t>(num_chunks));
  // With first_only, a chunk after one that has found a pair cannot hold the first: skip it. The
  // first is still that of the lowest chunk with a pair, whatever the threads did.
  std::atomic<int64_t> first_chunk_found{num_chunks};
  for_each_chunk(n, kChunk, [&](int64_t chunk, int64_t begin, int64_t end) {
    std::vector<int32_t> others;
    for (auto i = static_cast<int32_t>(begin); i < end; ++i) {
      if (first_only && chunk > first_chunk_found.load(std::memory_order_relaxed)) return;
      others.clear();
      tree.query_above(&lower[3 * i], &upper[3 * i], i, [&](int32_t j) { others.push_back(j); });
      std::sort(others.begin(), others.end());
      for (const int32_t j : others) {
        if (!triangles_collide(positions, triangles, i, j)) continue;
        found[chunk].emplace_back(i, j);
        if (first_only) {
          int64_t known = first_chunk_found.load();
          while (chunk < known && !first_chunk_found.compare_exchange_weak(known, chunk)) {
          }
          return;
        }
      }
    }
  });
  std::vector<TrianglePair> pairs;
  for (const auto& chunk_pairs : found) {
    pairs.insert(pairs.end(), chunk_pairs.begin(), chunk_pairs.end());
    if (first_only && !pairs.empty()) break;
  }
  return pairs;
}

}  // namespace

bool triangles_collide(std::span<const double> positions, std::span<const int32_t> triangles, int32_t i,
                       int32_t j) {
  const int32_t* s = &triangles[3 * static_cast<std::size_t>(i)];
  const int32_t* t = &triangles[3 * static_cast<std::size_t>(j)];
  int shared = 0, corner_s = 0, corner_t = 0;
  for (int x = 0; x < 3; ++x)
    for (int y = 0; y < 3; ++y)
      if (s[x] == t[y]) {
        ++shared;
        corner_s = x;
        corner_t = y;
      }
  if (shared >= 2) return false;  // neighbours across an edge: not tested (see the header)
  auto corner = [&](const int32_t* tri, int k) { return vertex(positions, tri[k % 3]); };
  if (shared == 0)
    return triangles_intersect(corner(s, 0), corner(s, 1), corner(s, 2), corner(t, 0), corner(t, 1),
                               corner(t, 2));
  return triangles_overlap_beyond_vertex(corner(s, corner_s), corner(s, corner_s + 1), corner(s, corner_s + 2),
                                         corner(t, corner_t + 1), corner(t, corner_t + 2));
}

std::optional<TrianglePair> first_self_intersection(std::span<const double> positions,
                                                    std::span<const int32_t> triangles) {
  const std::vector<TrianglePair> pairs = colliding_pairs(positions, triangles, /*first_only=*/true);
  if (pairs.empty()) return std::nullopt;
  return pairs.front();
}

std::vector<TrianglePair> self_intersections(std::span<const double> positions,
                                             std::span<const int32_t> triangles) {
  return colliding_pairs(positions, triangles, /*first_only=*/false);
}

std::vector<TrianglePair> self_intersections_brute_force(std::span<const double> positions,
                                                         std::span<const int32_t> triangles) {
  const auto n = static_cast<int32_t>(triangles.size() / 3);
  std::vector<TrianglePair> pairs;
  for (int32_t i = 0; i < n; ++i)
    for (int32_t j = i + 1; j < n; ++j)
      if (triangles_collide(positions, triangles, i, j)) pairs.emplace_back(i, j);
  return pairs;
}

}  // namespace nexdyn

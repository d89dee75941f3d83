// Boundary extraction by bucketing faces on their smallest vertex id.
//
// Each of the 4 * num_tets faces is keyed by its sorted vertex triple (a < b < c). A counting
// sort on a puts every copy of a face in the same bucket, buckets hold only the faces around one
// vertex (a few dozen), and sorting each bucket by (b, c, face id) brings copies together. The
// order depends only on the ids, never on hashing or threads, so the surface is reproducible.
#include "engine/mesh/surface.hpp"

#include <algorithm>
#include <array>
#include <utility>

namespace nexdyn {
namespace {

// Faces of a positively oriented tet (x0, x1, x2, x3), wound so the right-hand normal points
// away from the opposite vertex. Check on the unit tet: face (0,2,1) has normal e2 x e1 = -e3.
constexpr std::array<std::array<int, 3>, 4> kOutwardFaces = {{
    {1, 2, 3},
    {0, 3, 2},
    {0, 1, 3},
    {0, 2, 1},
}};

struct FaceRecord {
  uint64_t key;     // (middle id << 32) | largest id: one integer compare instead of two
  int32_t face_id;  // 4 * tet + local face: finds the winding and breaks ties deterministically
};

// Counting sort of keys on `bucket_of(key)` in [0, num_buckets): returns bucket offsets
// (num_buckets + 1) and fills `sorted` with items in bucket order, stable within a bucket.
template <typename Item, typename BucketOf>
std::vector<int64_t> bucket_sort(const std::vector<Item>& items, int32_t num_buckets,
                                 BucketOf bucket_of, std::vector<Item>& sorted) {
  std::vector<int64_t> offsets(static_cast<std::size_t>(num_buckets) + 1, 0);
  for (const Item& item : items) ++offsets[bucket_of(item) + 1];
  for (int32_t v = 0; v < num_buckets; ++v) offsets[v + 1] += offsets[v];
  std::vector<int64_t> cursor(offsets.begin(), offsets.end() - 1);
  sorted.resize(items.size());
  for (const Item& item : items) sorted[cursor[bucket_of(item)]++] = item;
  return offsets;
}

}  // namespace

SurfaceMesh extract_surface(std::span<const int32_t> tets, int32_t num_vertices) {
  SurfaceMesh surface;
  const int64_t num_tets = static_cast<int64_t>(tets.size() / 4);
  if (num_tets == 0 || num_vertices <= 0) return surface;

  // Pass 1: every face into the bucket of its smallest vertex.
  std::vector<int64_t> offsets(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (int64_t f = 0; f < 4 * num_tets; ++f) {
    const int32_t* t = &tets[4 * (f / 4)];
    const auto& local = kOutwardFaces[f % 4];
    ++offsets[std::min({t[local[0]], t[local[1]], t[local[2]]}) + 1];
  }
  for (int32_t v = 0; v < num_vertices; ++v) offsets[v + 1] += offsets[v];
  std::vector<FaceRecord> records(static_cast<std::size_t>(4 * num_tets));
  {
    std::vector<int64_t> cursor(offsets.begin(), offsets.end() - 1);
    for (int64_t f = 0; f < 4 * num_tets; ++f) {
      const int32_t* t = &tets[4 * (f / 4)];
      const auto& local = kOutwardFaces[f % 4];
      std::array<int32_t, 3> ids = {t[local[0]], t[local[1]], t[local[2]]};
      std::sort(ids.begin(), ids.end());
      const uint64_t key = (static_cast<uint64_t>(ids[1]) << 32) | static_cast<uint32_t>(ids[2]);
      records[cursor[ids[0]]++] = {key, static_cast<int32_t>(f)};
    }
  }

  // Pass 2: within each bucket, copies of a face are adjacent after sorting; a face seen once is
  // on the boundary. Buckets come in vertex order and are sorted, so triangles come out sorted.
  std::vector<int32_t> boundary_faces;
  for (int32_t a = 0; a < num_vertices; ++a) {
    const auto begin = records.begin() + offsets[a];
    const auto end = records.begin() + offsets[a + 1];
    std::sort(begin, end, [](const FaceRecord& x, const FaceRecord& y) {
      return x.key != y.key ? x.key < y.key : x.face_id < y.face_id;
    });
    for (auto run = begin; run != end;) {
      auto next = run + 1;
      while (next != end && next->key == run->key) ++next;
      if (next - run == 1) boundary_faces.push_back(run->face_id);
      run = next;
    }
  }

  // Triangles keep the tet's outward winding, rotated so the smallest id comes first (a
  // canonical form that keeps the orientation).
  surface.triangles.reserve(3 * boundary_faces.size());
  std::vector<uint8_t> on_surface(static_cast<std::size_t>(num_vertices), 0);
  for (const int32_t f : boundary_faces) {
    const int32_t* t = &tets[4 * (f / 4)];
    const auto& local = kOutwardFaces[f % 4];
    std::array<int32_t, 3> tri = {t[local[0]], t[local[1]], t[local[2]]};
    std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end());
    surface.triangles.insert(surface.triangles.end(), tri.begin(), tri.end());
    for (const int32_t v : tri) on_surface[v] = 1;
  }

  for (int32_t v = 0; v < num_vertices; ++v)
    if (on_surface[v]) surface.vertices.push_back(v);

  // Edges: 3 per triangle, bucketed on the smaller id, sorted and deduplicated per bucket.
  std::vector<std::pair<int32_t, int32_t>> edge_list;
  edge_list.reserve(surface.triangles.size());
  for (std::size_t i = 0; i < surface.triangles.size(); i += 3) {
    for (int k = 0; k < 3; ++k) {
      const int32_t p = surface.triangles[i + k];
      const int32_t q = surface.triangles[i + (k + 1) % 3];
      edge_list.emplace_back(std::min(p, q), std::max(p, q));
    }
  }
  std::vector<std::pair<int32_t, int32_t>> sorted_edges;
  const std::vector<int64_t> edge_offsets = bucket_sort(
      edge_list, num_vertices, [](const std::pair<int32_t, int32_t>& e) { return e.first; },
      sorted_edges);
  // On a closed surface every edge is listed twice: E edges of 2 ids = edge_list.size() ids.
  surface.edges.reserve(edge_list.size());
  for (int32_t a = 0; a < num_vertices; ++a) {
    const auto begin = sorted_edges.begin() + edge_offsets[a];
    const auto end = sorted_edges.begin() + edge_offsets[a + 1];
    std::sort(begin, end);
    for (auto it = begin; it != end; ++it) {
      if (it != begin && it->second == (it - 1)->second) continue;
      surface.edges.push_back(it->first);
      surface.edges.push_back(it->second);
    }
  }
  return surface;
}

SurfaceMesh extract_surface(const TetMesh& mesh) {
  return extract_surface(mesh.tets, mesh.num_vertices());
}

}  // namespace nexdyn

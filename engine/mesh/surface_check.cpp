// The closed-surface checks, one function per check, in the order of surface_check.hpp.
//
// The topological checks share one table: the 3 n half-edges (directed edges of the triangles,
// id 3 t + k for the edge leaving corner k of triangle t), sorted by their undirected edge and
// then by id. A run of equal edges is the set of triangles using that edge, listed in triangle
// order, so "the first failure in triangle order" is the smallest id in a failing run. Fans
// around vertices are found by joining, for every edge of two triangles, the two triangles'
// corners at each end of the edge (union-find on corners): the corners at a vertex then fall into
// one class per fan. Everything is sorting and linear passes, and does not depend on hashing or
// threads.
#include "engine/mesh/surface_check.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "engine/mesh/obj_reader.hpp"
#include "engine/mesh/self_intersection.hpp"

namespace nexdyn {
namespace {

constexpr std::string_view kIds = " (ids 1-based)";

[[noreturn]] void refuse(std::string_view name, const std::string& what) {
  throw MeshError(std::string(name) + ": " + what);
}

// Names of a 0-based vertex or triangle id in messages.
std::string id_name(int64_t id) { return std::to_string(id + 1); }

Eigen::Vector3d vertex(const TriangleSurface& s, int32_t id) {
  return Eigen::Vector3d::Map(&s.positions[3 * static_cast<std::size_t>(id)]);
}

// The arrays must be a surface at all before any check can speak of triangles and edges.
void check_arrays(const TriangleSurface& s, std::string_view name) {
  if (s.positions.size() % 3 != 0)
    refuse(name, "positions hold " + std::to_string(s.positions.size()) + " numbers, not a multiple of 3");
  if (s.triangles.size() % 3 != 0)
    refuse(name, "triangles hold " + std::to_string(s.triangles.size()) + " vertex ids, not a multiple of 3");
  if (static_cast<int64_t>(s.positions.size() / 3) > kMaxSurfaceVertices ||
      static_cast<int64_t>(s.triangles.size() / 3) > kMaxSurfaceTriangles)
    refuse(name, "too many vertices or triangles");
  for (std::size_t k = 0; k < s.positions.size(); ++k)
    if (!std::isfinite(s.positions[k]))
      refuse(name, "non-finite position, vertex " + id_name(static_cast<int64_t>(k / 3)) + std::string(kIds));
  const int32_t num_vertices = s.num_vertices();
  for (std::size_t k = 0; k < s.triangles.size(); ++k)
    if (s.triangles[k] < 0 || s.triangles[k] >= num_vertices)
      refuse(name, "vertex id out of range, triangle " + id_name(static_cast<int64_t>(k / 3)) +
                       " has 0-based id " + std::to_string(s.triangles[k]) + " and there are " +
                       std::to_string(num_vertices) + " vertices");
}

std::string corners_of(const TriangleSurface& s, int32_t t) {
  return id_name(s.triangles[3 * t]) + " " + id_name(s.triangles[3 * t + 1]) + " " +
         id_name(s.triangles[3 * t + 2]);
}

void check_degenerate(const TriangleSurface& s, std::string_view name) {
  for (int32_t t = 0; t < s.num_triangles(); ++t) {
    const int32_t a = s.triangles[3 * t], b = s.triangles[3 * t + 1], c = s.triangles[3 * t + 2];
    if (a == b || b == c || c == a || is_degenerate_triangle(vertex(s, a), vertex(s, b), vertex(s, c)))
      refuse(name, "degenerate (zero-area) triangle, triangle " + id_name(t) + " of vertices " +
                       corners_of(s, t) + std::string(kIds));
  }
}

void check_duplicates(const TriangleSurface& s, std::string_view name) {
  struct Key {
    int32_t v[3];
    int32_t triangle;
  };
  std::vector<Key> keys(static_cast<std::size_t>(s.num_triangles()));
  for (int32_t t = 0; t < s.num_triangles(); ++t) {
    Key& key = keys[t];
    std::copy_n(&s.triangles[3 * t], 3, key.v);
    std::sort(key.v, key.v + 3);
    key.triangle = t;
  }
  auto same_vertices = [](const Key& x, const Key& y) { return std::equal(x.v, x.v + 3, y.v); };
  std::sort(keys.begin(), keys.end(), [](const Key& x, const Key& y) {
    return std::lexicographical_compare(x.v, x.v + 3, y.v, y.v + 3) ||
           (std::equal(x.v, x.v + 3, y.v) && x.triangle < y.triangle);
  });
  // Each run's second triangle is the first to repeat an earlier one; report the earliest such.
  int32_t repeat = -1, original = -1;
  for (std::size_t k = 1; k < keys.size(); ++k)
    if (same_vertices(keys[k - 1], keys[k]) && (k < 2 || !same_vertices(keys[k - 2], keys[k])) &&
        (repeat < 0 || keys[k].triangle < repeat)) {
      repeat = keys[k].triangle;
      original = keys[k - 1].triangle;
    }
  if (repeat >= 0)
    refuse(name, "duplicate triangles, triangle " + id_name(repeat) + " repeats triangle " +
                     id_name(original) + ", vertices " + corners_of(s, original) + std::string(kIds));
}

// The half-edge table of the file comment.
class HalfEdges {
 public:
  explicit HalfEdges(const TriangleSurface& s) : triangles_(s.triangles) {
    const auto n = static_cast<int32_t>(s.triangles.size());
    sorted_.resize(static_cast<std::size_t>(n));
    for (int32_t h = 0; h < n; ++h) {
      const auto a = static_cast<uint32_t>(from(h)), b = static_cast<uint32_t>(to(h));
      sorted_[h] = {uint64_t{std::min(a, b)} << 32 | std::max(a, b), h};
    }
    std::sort(sorted_.begin(), sorted_.end(), [](const Entry& x, const Entry& y) {
      return x.edge != y.edge ? x.edge < y.edge : x.half_edge < y.half_edge;
    });
  }

  int32_t from(int32_t h) const { return triangles_[h]; }
  int32_t to(int32_t h) const { return triangles_[next(h)]; }
  // The next half-edge of the same triangle, which starts where h ends.
  static int32_t next(int32_t h) { return h - h % 3 + (h % 3 + 1) % 3; }

  // Calls visit(first, last) for every run [first, last) of half-edges of one edge, in edge order;
  // entry k of a run is half_edge(k).
  template <typename Visit>
  void for_each_edge(Visit&& visit) const {
    for (std::size_t first = 0; first < sorted_.size();) {
      std::size_t last = first + 1;
      while (last < sorted_.size() && sorted_[last].edge == sorted_[first].edge) ++last;
      visit(first, last);
      first = last;
    }
  }
  int32_t half_edge(std::size_t k) const { return sorted_[k].half_edge; }

 private:
  struct Entry {
    uint64_t edge;      // (smaller vertex id << 32) | larger
    int32_t half_edge;  // 3 t + k
  };
  const std::vector<int32_t>& triangles_;
  std::vector<Entry> sorted_;
};

constexpr int32_t kNone = std::numeric_limits<int32_t>::max();

void check_closed(const HalfEdges& edges, std::string_view name) {
  int32_t open = kNone;
  edges.for_each_edge([&](std::size_t first, std::size_t last) {
    if (last - first == 1) open = std::min(open, edges.half_edge(first));
  });
  if (open != kNone)
    refuse(name, "not closed, edge " + id_name(edges.from(open)) + "-" + id_name(edges.to(open)) +
                     " is used by triangle " + id_name(open / 3) + " only" + std::string(kIds));
}

void check_manifold_edges(const HalfEdges& edges, std::string_view name) {
  int32_t crowded = kNone;
  std::size_t crowded_first = 0, crowded_last = 0;
  edges.for_each_edge([&](std::size_t first, std::size_t last) {
    if (last - first > 2 && edges.half_edge(first) < crowded) {
      crowded = edges.half_edge(first);
      crowded_first = first;
      crowded_last = last;
    }
  });
  if (crowded == kNone) return;
  std::string users;
  for (std::size_t k = crowded_first; k < crowded_last && k < crowded_first + 6; ++k)
    users += (k == crowded_first ? "" : ", ") + id_name(edges.half_edge(k) / 3);
  if (crowded_last - crowded_first > 6) users += ", ...";
  const int32_t a = edges.from(crowded), b = edges.to(crowded);
  refuse(name, "not manifold, edge " + id_name(std::min(a, b)) + "-" + id_name(std::max(a, b)) +
                   " is shared by " + std::to_string(crowded_last - crowded_first) + " triangles: " + users +
                   std::string(kIds));
}

// Every edge has exactly two triangles here (the two checks above passed).
void check_manifold_vertices(const TriangleSurface& s, const HalfEdges& edges, std::string_view name) {
  const auto num_corners = static_cast<int32_t>(s.triangles.size());
  std::vector<int32_t> parent(static_cast<std::size_t>(num_corners));
  for (int32_t c = 0; c < num_corners; ++c) parent[c] = c;
  auto find = [&](int32_t c) {
    while (parent[c] != c) c = parent[c] = parent[parent[c]];
    return c;
  };
  auto join = [&](int32_t x, int32_t y) {
    x = find(x);
    y = find(y);
    if (x != y) parent[std::max(x, y)] = std::min(x, y);
  };
  edges.for_each_edge([&](std::size_t first, std::size_t) {
    const int32_t h = edges.half_edge(first), g = edges.half_edge(first + 1);
    // Corner ids equal half-edge ids: corner h is where half-edge h starts.
    const int32_t g_at_from = edges.from(g) == edges.from(h) ? g : HalfEdges::next(g);
    const int32_t g_at_to = g_at_from == g ? HalfEdges::next(g) : g;
    join(h, g_at_from);
    join(HalfEdges::next(h), g_at_to);
  });
  std::vector<int32_t> fan(static_cast<std::size_t>(s.num_vertices()), -1);  // first fan seen
  std::vector<int32_t> first_triangle(fan.size(), -1);
  for (int32_t c = 0; c < num_corners; ++c) {
    const int32_t v = s.triangles[c], root = find(c);
    if (fan[v] < 0) {
      fan[v] = root;
      first_triangle[v] = c / 3;
      continue;
    }
    if (root == fan[v]) continue;
    std::vector<int32_t> roots;
    for (int32_t d = 0; d < num_corners; ++d)
      if (s.triangles[d] == v) roots.push_back(find(d));
    std::sort(roots.begin(), roots.end());
    const auto fans = std::unique(roots.begin(), roots.end()) - roots.begin();
    refuse(name, "not manifold, vertex " + id_name(v) + " joins " + std::to_string(fans) +
                     " separate fans of triangles, e.g. triangles " + id_name(first_triangle[v]) + " and " +
                     id_name(c / 3) + std::string(kIds));
  }
}

void check_orientation(const HalfEdges& edges, std::string_view name) {
  int32_t first = kNone, second = kNone;
  edges.for_each_edge([&](std::size_t k, std::size_t) {
    const int32_t h = edges.half_edge(k), g = edges.half_edge(k + 1);
    if (edges.from(h) == edges.from(g) && h < first) {
      first = h;
      second = g;
    }
  });
  if (first != kNone)
    refuse(name, "not consistently oriented, triangles " + id_name(first / 3) + " and " +
                     id_name(second / 3) + " both traverse edge " + id_name(edges.from(first)) + "->" +
                     id_name(edges.to(first)) + std::string(kIds));
}

void check_self_intersection(const TriangleSurface& s, std::string_view name) {
  const auto pair = first_self_intersection(s.positions, s.triangles);
  if (!pair) return;
  const auto [i, j] = *pair;
  std::string how = " intersect";
  for (int x = 0; x < 3; ++x)
    for (int y = 0; y < 3; ++y)
      if (s.triangles[3 * i + x] == s.triangles[3 * j + y])
        how = " overlap beyond their shared vertex " + id_name(s.triangles[3 * i + x]);
  refuse(name, "self-intersecting, triangles " + id_name(i) + " and " + id_name(j) + how + std::string(kIds));
}

void check_volume(const TriangleSurface& s, std::string_view name) {
  const double volume = enclosed_volume(s);
  if (volume > 0.0) return;
  char text[64];
  std::snprintf(text, sizeof text, "%.6g", volume);
  refuse(name, std::string("inverted, enclosed volume ") + text + " m^3 <= 0: the normals point inward");
}

// Keeps the vertices some triangle uses, in their order, and renumbers the triangles.
void drop_unused_vertices(TriangleSurface& s) {
  std::vector<int32_t> new_id(static_cast<std::size_t>(s.num_vertices()), -1);
  for (const int32_t v : s.triangles) new_id[v] = 0;
  int32_t kept = 0;
  for (int32_t v = 0; v < s.num_vertices(); ++v) {
    if (new_id[v] < 0) continue;
    new_id[v] = kept;
    std::copy_n(&s.positions[3 * static_cast<std::size_t>(v)], 3,
                &s.positions[3 * static_cast<std::size_t>(kept)]);
    ++kept;
  }
  s.positions.resize(3 * static_cast<std::size_t>(kept));
  for (int32_t& v : s.triangles) v = new_id[v];
}

}  // namespace

double enclosed_volume(const TriangleSurface& surface) {
  if (surface.triangles.empty()) return 0.0;
  const Eigen::Vector3d origin = vertex(surface, surface.triangles[0]);
  double six_volume = 0.0;
  for (int32_t t = 0; t < surface.num_triangles(); ++t) {
    const Eigen::Vector3d a = vertex(surface, surface.triangles[3 * t]) - origin;
    const Eigen::Vector3d b = vertex(surface, surface.triangles[3 * t + 1]) - origin;
    const Eigen::Vector3d c = vertex(surface, surface.triangles[3 * t + 2]) - origin;
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6.0;
}

TriangleSurface checked_closed_surface(TriangleSurface surface, std::string_view name) {
  check_arrays(surface, name);
  if (surface.triangles.empty()) refuse(name, "empty surface, no triangles");
  check_degenerate(surface, name);
  check_duplicates(surface, name);
  const HalfEdges edges(surface);
  check_closed(edges, name);
  check_manifold_edges(edges, name);
  check_manifold_vertices(surface, edges, name);
  check_orientation(edges, name);
  check_self_intersection(surface, name);
  check_volume(surface, name);
  drop_unused_vertices(surface);
  return surface;
}

}  // namespace nexdyn

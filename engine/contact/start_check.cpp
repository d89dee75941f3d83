// Start-state validation of contact scenes (see start_check.hpp).
#include "engine/contact/start_check.hpp"

#include "bvh/broad_phase.hpp"
#include "engine/mesh/intersection.hpp"

#include <Eigen/Core>

#include <limits>

namespace nexdyn {

std::string body_label(const Model& model, int32_t body) {
  const BodyRange& b = model.bodies[body];
  std::string label = (b.obstacle ? "obstacles[" : "bodies[") + std::to_string(b.scene_entry) + "]";
  int32_t copy = 0, copies = 0;
  for (int32_t i = 0; i < static_cast<int32_t>(model.bodies.size()); ++i) {
    const BodyRange& o = model.bodies[i];
    if (o.obstacle != b.obstacle || o.scene_entry != b.scene_entry) continue;
    if (i < body) ++copy;
    ++copies;
  }
  if (copies > 1) label += " (copy " + std::to_string(copy) + " of its array)";
  return label;
}

std::string initial_contact_problem(const Model& model) {
  const double* x = model.rest_positions.data();
  // Planes: every free surface vertex strictly in front.
  for (int32_t v : model.surface_vertices) {
    if (model.dirichlet[v] >= 0) continue;
    for (size_t p = 0; p < model.obstacle_planes.size(); ++p) {
      const ObstaclePlane& plane = model.obstacle_planes[p];
      if ((Eigen::Vector3d::Map(x + 3 * int64_t{v}) - plane.point).dot(plane.normal) <= 0.0)
        return body_label(model, model.vertex_body[v]) + " starts on or behind obstacles[" +
               std::to_string(plane.scene_entry) + "] (a plane)";
    }
  }
  // Surfaces: touching or crossing triangles (exact test).
  const int64_t num_triangles = static_cast<int64_t>(model.surface_triangles.size() / 3);
  for (const IndexPair& pair : intersecting_triangle_pairs(x, model.surface_triangles.data(), num_triangles)) {
    const int32_t a = model.vertex_body[model.surface_triangles[3 * int64_t{pair.first}]];
    const int32_t b = model.vertex_body[model.surface_triangles[3 * int64_t{pair.second}]];
    if (model.bodies[a].obstacle && model.bodies[b].obstacle) continue;  // obstacles never move
    if (a == b)
      return body_label(model, a) + " touches or intersects itself at the start";
    return body_label(model, a) + " and " + body_label(model, b) +
           " touch or intersect at the start (IPC needs a positive gap)";
  }
  // Nesting: with no surface crossing, a body is inside another iff one of its vertices is.
  const int32_t nb = static_cast<int32_t>(model.bodies.size());
  std::vector<double> lo(3 * nb, std::numeric_limits<double>::infinity());
  std::vector<double> hi(3 * nb, -std::numeric_limits<double>::infinity());
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    if (model.axis_node(v)) continue;  // a column of an affine body's A R, not a point of it
    for (int d = 0; d < 3; ++d) {
      const int32_t b = model.vertex_body[v];
      lo[3 * b + d] = std::min(lo[3 * b + d], x[3 * v + d]);
      hi[3 * b + d] = std::max(hi[3 * b + d], x[3 * v + d]);
    }
  }
  for (const IndexPair& pair : self_overlapping_pairs(lo.data(), hi.data(), nb)) {
    for (int side = 0; side < 2; ++side) {
      const int32_t inner = side ? pair.second : pair.first;
      const int32_t outer = side ? pair.first : pair.second;
      const BodyRange& o = model.bodies[outer];
      if (o.obstacle || o.triangle_count == 0) continue;  // obstacle meshes may be open
      const Eigen::Vector3d p = Eigen::Vector3d::Map(x + 3 * int64_t{model.bodies[inner].vertex_begin});
      if (point_inside_surface(p, x, model.surface_triangles.data() + 3 * int64_t{o.triangle_begin},
                               o.triangle_count))
        return body_label(model, inner) + " starts inside " + body_label(model, outer);
    }
  }
  return {};
}

}  // namespace nexdyn

// The "joints" of a scene (DESIGN.md section 5; engine/model.hpp, Joint): each joint point is
// carried by the tet of its body nearest to it, with fixed barycentric weights, or on an affine
// body by its four nodes (x = p + y_0 c_0 + y_1 c_1 + y_2 c_2: weights 1, y_0, y_1, y_2).
#include "engine/scene/build_model.hpp"

#include "kernels/distance/point_triangle_distance.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <limits>
#include <string>

namespace nexdyn::scene_io {

namespace {

// The tet of body `b` nearest to `point` (distance 0 when inside; the lowest index on ties) and
// the point's barycentric weights in it, extrapolated when it lies outside.
void attach_to_body(const Model& model, const BodyRange& body, const Eigen::Vector3d& point, int32_t (&vertex)[4],
                    double (&weight)[4]) {
  auto X = [&](int32_t v) { return Eigen::Vector3d::Map(&model.rest_positions[3 * int64_t{v}]); };
  const int32_t body_index = static_cast<int32_t>(&body - model.bodies.data());
  for (const AffineBody& affine : model.affine_bodies) {
    if (affine.body != body_index) continue;
    // The point's rest coordinates in the body's principal frame, about its centre of mass.
    const Eigen::Vector3d y = affine.frame.transpose() * (point - X(affine.node));
    const double w[4] = {1.0, y[0], y[1], y[2]};
    for (int k = 0; k < 4; ++k) {
      vertex[k] = affine.node + k;
      weight[k] = w[k];
    }
    return;
  }
  double best = std::numeric_limits<double>::infinity();
  int32_t best_tet = body.tet_begin;
  for (int32_t t = body.tet_begin; t < body.tet_begin + body.tet_count && best > 0.0; ++t) {
    const int32_t* c = &model.tets[4 * int64_t{t}];
    // Inside: every face sees the point on its inner side; else the nearest face's distance.
    double d = 0.0;
    bool inside = true;
    constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    double nearest_face = std::numeric_limits<double>::infinity();
    for (const auto& f : kFace) {
      const Eigen::Vector3d a = X(c[f[0]]), b = X(c[f[1]]), e = X(c[f[2]]);
      inside = inside && (b - a).cross(e - a).dot(point - a) <= 0.0;
      nearest_face = std::min(nearest_face, point_triangle_distance(point, a, b, e));
    }
    if (!inside) d = nearest_face;
    if (d < best) {
      best = d;
      best_tet = t;
    }
  }
  const int32_t* c = &model.tets[4 * int64_t{best_tet}];
  Eigen::Matrix3d edges;
  edges << X(c[1]) - X(c[0]), X(c[2]) - X(c[0]), X(c[3]) - X(c[0]);
  const Eigen::Vector3d l = edges.inverse() * (point - X(c[0]));
  weight[0] = 1.0 - l.sum();
  for (int k = 0; k < 3; ++k) weight[k + 1] = l[k];
  for (int k = 0; k < 4; ++k) vertex[k] = c[k];
}

// The one body made from "bodies" entry `entry` (an "array" entry makes several: ambiguous).
const BodyRange& joint_body(const json& value, const Where& w, const Model& model, int64_t num_scene_bodies) {
  const int64_t entry = integer(value, w, 0);
  if (entry >= num_scene_bodies) w.fail("no such body (the scene has " + std::to_string(num_scene_bodies) + ")", value);
  const BodyRange* found = nullptr;
  for (const BodyRange& body : model.bodies) {
    if (body.obstacle || body.scene_entry != entry) continue;
    if (found) w.fail("body " + std::to_string(entry) + " is an \"array\" of several bodies; a joint needs one", value);
    found = &body;
  }
  return *found;
}

// A ball joint's "bodies" (`pair`, at `w`): the first body's weights, then the second's negated.
void attach_ball(const json& pair, const Where& w, const Eigen::Vector3d& point, const Model& model,
                 int64_t num_scene_bodies, Joint& joint) {
  if (!pair.is_array() || pair.size() != 2) w.fail("expected two body indices", pair);
  const BodyRange& a = joint_body(pair[0], w[0], model, num_scene_bodies);
  const BodyRange& b = joint_body(pair[1], w[1], model, num_scene_bodies);
  if (&a == &b) w.fail("a ball joint needs two different bodies", pair);
  joint.type = JointType::ball;
  joint.count = 8;
  for (int side = 0; side < 2; ++side) {
    int32_t v[4];
    double weight[4];
    attach_to_body(model, side == 0 ? a : b, point, v, weight);
    for (int k = 0; k < 4; ++k) {
      joint.vertex[4 * side + k] = v[k];
      joint.coefficient[4 * side + k] = side == 0 ? weight[k] : -weight[k];
    }
  }
}

void read_joint(const json& j, const Where& w, int32_t scene_entry, Model& model, int64_t num_scene_bodies) {
  check_keys(j, w, {"type", "body", "bodies", "point"});
  if (!j.contains("type")) w.fail("missing key \"type\" (\"pin\" or \"ball\")");
  if (!j.contains("point")) w.fail("missing key \"point\"");
  const std::string type = string(j["type"], w["type"]);
  const Eigen::Vector3d point = vec3(j["point"], w["point"]);
  Joint joint;
  joint.scene_entry = scene_entry;
  if (type == "pin") {
    if (!j.contains("body") || j.contains("bodies")) w.fail("a pin takes \"body\" (one index), not \"bodies\"");
    joint.type = JointType::pin;
    joint.count = 4;
    int32_t v[4];
    double weight[4];
    attach_to_body(model, joint_body(j["body"], w["body"], model, num_scene_bodies), point, v, weight);
    for (int k = 0; k < 4; ++k) {
      joint.vertex[k] = v[k];
      joint.coefficient[k] = weight[k];
    }
    joint.offset = -point;
  } else if (type == "ball") {
    if (!j.contains("bodies") || j.contains("body")) w.fail("a ball joint takes \"bodies\" (two indices), not \"body\"");
    attach_ball(j["bodies"], w["bodies"], point, model, num_scene_bodies, joint);
  } else {
    w["type"].fail("expected \"pin\" or \"ball\"", j["type"]);
  }
  model.joints.push_back(joint);
}

}  // namespace

void append_joints(const json& joints, const Where& w, Model& model, int64_t num_scene_bodies) {
  if (!joints.is_array()) w.fail("expected an array", joints);
  for (size_t i = 0; i < joints.size(); ++i)
    read_joint(joints[i], w[i], static_cast<int32_t>(i), model, num_scene_bodies);
}

}  // namespace nexdyn::scene_io

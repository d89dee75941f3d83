// Pictures of a frame without ParaView: one ray per pixel through an Embree BVH of the body and
// obstacle surfaces (bvh/ray_scene.hpp), analytic obstacle planes drawn as a ground grid, Lambert
// shading from one light with shadows, bodies coloured by body or by a per-vertex value (speed).
//
// Every pixel is a function of the scene and the camera alone, computed in the same order
// whatever thread computes it: the bytes of a picture do not depend on the thread count.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace nexdyn {

struct RenderCamera {
  Eigen::Vector3d position = Eigen::Vector3d(0.0, 0.0, 5.0);  // [m]
  Eigen::Vector3d target = Eigen::Vector3d::Zero();           // [m], seen at the picture's centre
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();              // need not be unit or orthogonal
  double fov_deg = 40.0;                                       // vertical field of view
};

enum class ColorBy { body, value };

// What one picture shows.
struct RenderInput {
  std::vector<float> positions;        // (num_vertices x 3) [m]
  std::vector<uint32_t> triangles;     // (num_triangles x 3), outward winding
  std::vector<int32_t> triangle_body;  // (num_triangles) body id; -1: scenery (obstacle mesh), grey
  std::vector<float> vertex_value;     // (num_vertices) for ColorBy::value, e.g. speed [m/s]
  float value_max = 1.0f;              // the value shown in the colour ramp's last colour
  struct Plane {
    Eigen::Vector3d point, normal;     // normal: unit, toward the side the bodies are on
  };
  std::vector<Plane> planes;           // drawn as grids, seen only from their normal's side
  double grid_spacing = 0.1;           // [m] between grid lines on the planes
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();  // against gravity: where the light comes from
};

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // (height x width x 3), rows top to bottom
};

Image render_image(const RenderInput& input, const RenderCamera& camera, int width, int height, ColorBy color);

// A camera that sees the box [lower, upper] whole in a picture of the given aspect (width /
// height): from above the box's side, looking at its centre, `up` as the picture's up.
RenderCamera fit_camera(const Eigen::Vector3d& lower, const Eigen::Vector3d& upper, const Eigen::Vector3d& up,
                        double fov_deg, double aspect);

// A round grid spacing (1, 2 or 5 times a power of ten) giving about five cells across `extent`.
double round_grid_spacing(double extent);

// The colour of body `body` (a fixed palette, repeated) and of a value in [0, 1] on the ramp.
Eigen::Vector3f body_color(int32_t body);
Eigen::Vector3f ramp_color(float value);

}  // namespace nexdyn

// An Embree BVH over triangles for ray queries: what `nexdyn render` traces its pictures with.
//
// The broad phase (broad_phase.hpp) asks Embree which boxes overlap; pictures ask which triangle
// a ray meets first and whether anything lies between a point and the light. Both go through the
// one Embree device of the process (EmbreeDevice). Positions are floats: a picture needs no more,
// and it halves the memory Embree reads per ray.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <span>
#include <vector>

namespace nexdyn {

class RayScene {
 public:
  // positions: (num_vertices x 3), triangles: (num_triangles x 3) vertex ids. Both are copied.
  // An empty triangle list makes a scene no ray hits.
  RayScene(std::span<const float> positions, std::span<const uint32_t> triangles);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  struct Hit {
    float t = 0.0f;               // distance along the (unit) direction
    uint32_t triangle = kNoHit;   // kNoHit when nothing is hit before t_far
    float u = 0.0f, v = 0.0f;     // barycentric weights of the triangle's 2nd and 3rd vertex
  };
  static constexpr uint32_t kNoHit = RTC_INVALID_GEOMETRY_ID;

  // The first triangle along origin + t dir, t in [0, t_far].
  Hit first_hit(const float origin[3], const float direction[3], float t_far) const;
  // Whether any triangle lies on origin + t dir, t in [t_near, t_far].
  bool occluded(const float origin[3], const float direction[3], float t_near, float t_far) const;

 private:
  std::vector<float> positions_;  // padded by one float: Embree reads vertices 16 bytes at a time
  std::vector<uint32_t> triangles_;
  RTCScene scene_ = nullptr;
};

}  // namespace nexdyn

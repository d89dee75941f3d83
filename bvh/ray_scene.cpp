// Ray queries on an Embree triangle BVH (see ray_scene.hpp).
#include "bvh/ray_scene.hpp"

#include "bvh/broad_phase.hpp"

#include <limits>
#include <mutex>

namespace nexdyn {

namespace {

#if NEXDYN_PARALLEL_STD_THREADS
// ThreadSanitizer builds (engine/parallel.hpp): `nexdyn render --all` builds scenes on several
// threads at once, and Embree's allocator hands blocks between them under its own locks, which
// TSan cannot see (Embree is not instrumented) and reports as races. There the builds and
// releases take turns; the ray queries, which allocate nothing, stay parallel.
std::mutex& embree_build_mutex() {
  static std::mutex mutex;
  return mutex;
}
struct BuildTurn {
  std::lock_guard<std::mutex> lock{embree_build_mutex()};
};
#else
struct BuildTurn {};
#endif

}  // namespace

RayScene::RayScene(std::span<const float> positions, std::span<const uint32_t> triangles)
    : positions_(positions.begin(), positions.end()), triangles_(triangles.begin(), triangles.end()) {
  positions_.push_back(0.0f);
  [[maybe_unused]] const BuildTurn turn;
  const EmbreeDevice& device = EmbreeDevice::instance();
  scene_ = rtcNewScene(device.get());
  // Robust: rays through a shared edge or vertex still hit one of its triangles, so a picture has
  // no pinholes along the edges of a mesh.
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_MEDIUM);
  const size_t num_triangles = triangles_.size() / 3;
  if (num_triangles > 0) {
    RTCGeometry geometry = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, positions_.data(), 0,
                               3 * sizeof(float), (positions_.size() - 1) / 3);
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, triangles_.data(), 0,
                               3 * sizeof(uint32_t), num_triangles);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene_, geometry);
    rtcReleaseGeometry(geometry);
  }
  rtcCommitScene(scene_);
  device.check("RayScene");
}

RayScene::~RayScene() {
  [[maybe_unused]] const BuildTurn turn;
  if (scene_ != nullptr) rtcReleaseScene(scene_);
}

RayScene::Hit RayScene::first_hit(const float origin[3], const float direction[3], float t_far) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit query{};
  query.ray.org_x = origin[0];
  query.ray.org_y = origin[1];
  query.ray.org_z = origin[2];
  query.ray.dir_x = direction[0];
  query.ray.dir_y = direction[1];
  query.ray.dir_z = direction[2];
  query.ray.tnear = 0.0f;
  query.ray.tfar = t_far;
  query.ray.mask = 0xFFFFFFFFu;
  query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene_, &context, &query);
  Hit hit;
  if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.t = query.ray.tfar;
  hit.triangle = query.hit.primID;
  hit.u = query.hit.u;
  hit.v = query.hit.v;
  return hit;
}

bool RayScene::occluded(const float origin[3], const float direction[3], float t_near, float t_far) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray{};
  ray.org_x = origin[0];
  ray.org_y = origin[1];
  ray.org_z = origin[2];
  ray.dir_x = direction[0];
  ray.dir_y = direction[1];
  ray.dir_z = direction[2];
  ray.tnear = t_near;
  ray.tfar = t_far;
  ray.mask = 0xFFFFFFFFu;
  rtcOccluded1(scene_, &context, &ray);
  // Embree marks a blocked ray by setting tfar to -inf.
  return ray.tfar < 0.0f;
}

}  // namespace nexdyn

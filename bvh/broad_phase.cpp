// Broad phase on Embree: user geometries (one primitive per box) and rtcCollide. See the header
// for the contract and DESIGN.md section 1 for what rtcCollide reports on this Embree version.
#include "bvh/broad_phase.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

namespace nexdyn {

namespace {

// Last Embree error, written by the error callback (which may run on any thread, and must not
// throw through Embree's C frames) and turned into an exception by EmbreeDevice::check.
std::mutex g_error_mutex;
std::string g_error_message;
std::atomic<bool> g_error_pending{false};

void on_embree_error(void* /*user*/, RTCError code, const char* message) {
  std::lock_guard<std::mutex> lock(g_error_mutex);
  if (g_error_pending.load()) return;  // keep the first error: later ones are usually fallout
  g_error_message = "Embree error " + std::to_string(static_cast<int>(code)) + ": " +
                    (message != nullptr ? message : "(no message)");
  g_error_pending.store(true);
}

// Float box handed to Embree; encloses the double box it was made from.
struct FloatAabb {
  float lower[3];
  float upper[3];
};

// Nearest float <= x and nearest float >= x, so every float box contains its double box.
// (Round-to-nearest is monotone, so a plain cast would already keep every box-box overlap,
// touching ones included; containment is the stronger guarantee the BVH is meant to give, and
// it stays true if the float boxes are later used against anything else.)
float round_down(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
float round_up(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

std::vector<FloatAabb> to_float_boxes(const double* lower, const double* upper, int32_t n) {
  std::vector<FloatAabb> boxes(static_cast<size_t>(n));
  auto convert = [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      for (int d = 0; d < 3; ++d) {
        boxes[i].lower[d] = round_down(lower[3 * i + d]);
        boxes[i].upper[d] = round_up(upper[3 * i + d]);
      }
    }
  };
#if NEXDYN_PARALLEL_STD_THREADS
  convert(tbb::blocked_range<size_t>(0, boxes.size()));  // see EmbreeDevice()
#else
  tbb::parallel_for(tbb::blocked_range<size_t>(0, boxes.size(), kBoxConvertGrain), convert);
#endif
  return boxes;
}

void box_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* boxes = static_cast<const FloatAabb*>(args->geometryUserPtr);
  const FloatAabb& b = boxes[args->primID];
  RTCBounds* out = args->bounds_o;
  out->lower_x = b.lower[0];
  out->lower_y = b.lower[1];
  out->lower_z = b.lower[2];
  out->upper_x = b.upper[0];
  out->upper_y = b.upper[1];
  out->upper_z = b.upper[2];
}

// A committed Embree scene holding one user geometry over `boxes` (which must outlive it).
class BoxScene {
 public:
  BoxScene(const std::vector<FloatAabb>& boxes) {
    EmbreeDevice& device = EmbreeDevice::instance();
    scene_ = rtcNewScene(device.get());
    device.check("rtcNewScene");
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry geometry = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_USER);
    device.check("rtcNewGeometry");
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(boxes.size()));
    rtcSetGeometryUserData(geometry, const_cast<FloatAabb*>(boxes.data()));
    rtcSetGeometryBoundsFunction(geometry, box_bounds, nullptr);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene_, geometry);
    rtcReleaseGeometry(geometry);  // the scene holds its own reference
    device.check("building the box geometry");
    rtcCommitScene(scene_);
    device.check("rtcCommitScene");
  }
  ~BoxScene() {
    if (scene_ != nullptr) rtcReleaseScene(scene_);
  }
  BoxScene(const BoxScene&) = delete;
  BoxScene& operator=(const BoxScene&) = delete;
  RTCScene get() const { return scene_; }

 private:
  RTCScene scene_ = nullptr;
};

uint64_t pair_key(uint32_t i, uint32_t j) { return (uint64_t{i} << 32) | uint64_t{j}; }

// What the collide callback sees. Embree reports pairs whose float boxes (or, for a scene against
// itself, whose BVH leaves) overlap, on several threads at once; we keep only exact double
// overlaps, each in a per-thread list.
struct CollideContext {
  const double* lower0;
  const double* upper0;
  const double* lower1;
  const double* upper1;
  bool self;
  tbb::enumerable_thread_specific<std::vector<uint64_t>>* keys;
};

void collect_overlaps(void* user, RTCCollision* collisions, unsigned num_collisions) {
  const auto* ctx = static_cast<const CollideContext*>(user);
  std::vector<uint64_t>& out = ctx->keys->local();
  for (unsigned c = 0; c < num_collisions; ++c) {
    uint32_t i = collisions[c].primID0;
    uint32_t j = collisions[c].primID1;
    if (ctx->self) {
      if (i == j) continue;
      if (i > j) std::swap(i, j);  // a self pair may come as (j, i)
    }
    if (boxes_overlap(ctx->lower0, ctx->upper0, i, ctx->lower1, ctx->upper1, j))
      out.push_back(pair_key(i, j));
  }
}

// Concatenates the per-thread lists and sorts them: the result is the same set whatever thread
// found which pair, and sorted it is the same sequence. `unique` guards against a pair reported
// twice (e.g. once in each order).
std::vector<IndexPair> gather_sorted(tbb::enumerable_thread_specific<std::vector<uint64_t>>& keys) {
  size_t total = 0;
  for (const auto& k : keys) total += k.size();
  std::vector<uint64_t> all;
  all.reserve(total);
  for (const auto& k : keys) all.insert(all.end(), k.begin(), k.end());
#if NEXDYN_PARALLEL_STD_THREADS
  std::sort(all.begin(), all.end());  // see EmbreeDevice()
#else
  tbb::parallel_sort(all.begin(), all.end());
#endif
  all.erase(std::unique(all.begin(), all.end()), all.end());
  std::vector<IndexPair> pairs(all.size());
  for (size_t p = 0; p < all.size(); ++p) {
    pairs[p] = {static_cast<int32_t>(all[p] >> 32), static_cast<int32_t>(all[p] & 0xffffffffu)};
  }
  return pairs;
}

}  // namespace

EmbreeDevice& EmbreeDevice::instance() {
  static EmbreeDevice device;
  return device;
}

EmbreeDevice::EmbreeDevice() {
#if NEXDYN_PARALLEL_STD_THREADS
  // ThreadSanitizer builds (engine/parallel.hpp): Embree's threads and TBB's scheduler are not
  // instrumented, so TSan would see the callbacks' reads of data the caller wrote as races. The
  // broad phase runs on the calling thread there; the engine's own parallel kernels stay parallel.
  device_ = rtcNewDevice("threads=1");
#else
  device_ = rtcNewDevice(nullptr);
#endif
  if (device_ == nullptr) {
    throw std::runtime_error("rtcNewDevice failed: Embree error " +
                             std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))));
  }
  rtcSetDeviceErrorFunction(device_, on_embree_error, nullptr);
}

EmbreeDevice::~EmbreeDevice() {
  if (device_ != nullptr) rtcReleaseDevice(device_);
}

void EmbreeDevice::check(const char* where) const {
  if (!g_error_pending.load()) return;
  std::string message;
  {
    std::lock_guard<std::mutex> lock(g_error_mutex);
    message = std::move(g_error_message);
    g_error_message.clear();
    g_error_pending.store(false);
  }
  throw std::runtime_error(std::string(where) + ": " + message);
}

std::vector<IndexPair> overlapping_pairs(const double* a_lower, const double* a_upper, int32_t na,
                                         const double* b_lower, const double* b_upper,
                                         int32_t nb) {
  if (na <= 0 || nb <= 0) return {};
  const std::vector<FloatAabb> a_boxes = to_float_boxes(a_lower, a_upper, na);
  const std::vector<FloatAabb> b_boxes = to_float_boxes(b_lower, b_upper, nb);
  const BoxScene a_scene(a_boxes);
  const BoxScene b_scene(b_boxes);
  tbb::enumerable_thread_specific<std::vector<uint64_t>> keys;
  CollideContext ctx{a_lower, a_upper, b_lower, b_upper, /*self=*/false, &keys};
  // For two different scenes Embree reports (primitive of scene0, primitive of scene1).
  rtcCollide(a_scene.get(), b_scene.get(), collect_overlaps, &ctx);
  EmbreeDevice::instance().check("rtcCollide");
  return gather_sorted(keys);
}

std::vector<IndexPair> self_overlapping_pairs(const double* lower, const double* upper,
                                              int32_t n) {
  if (n <= 1) return {};
  const std::vector<FloatAabb> boxes = to_float_boxes(lower, upper, n);
  const BoxScene scene(boxes);
  tbb::enumerable_thread_specific<std::vector<uint64_t>> keys;
  CollideContext ctx{lower, upper, lower, upper, /*self=*/true, &keys};
  rtcCollide(scene.get(), scene.get(), collect_overlaps, &ctx);
  EmbreeDevice::instance().check("rtcCollide");
  return gather_sorted(keys);
}

std::vector<IndexPair> overlapping_pairs_brute_force(const double* a_lower, const double* a_upper,
                                                     int32_t na, const double* b_lower,
                                                     const double* b_upper, int32_t nb) {
  std::vector<IndexPair> pairs;
  for (int32_t i = 0; i < na; ++i)
    for (int32_t j = 0; j < nb; ++j)
      if (boxes_overlap(a_lower, a_upper, i, b_lower, b_upper, j)) pairs.emplace_back(i, j);
  return pairs;
}

std::vector<IndexPair> self_overlapping_pairs_brute_force(const double* lower, const double* upper,
                                                          int32_t n) {
  std::vector<IndexPair> pairs;
  for (int32_t i = 0; i < n; ++i)
    for (int32_t j = i + 1; j < n; ++j)
      if (boxes_overlap(lower, upper, i, lower, upper, j)) pairs.emplace_back(i, j);
  return pairs;
}

}  // namespace nexdyn

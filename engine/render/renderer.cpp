// Ray-traced pictures of a frame (see renderer.hpp).
#include "engine/render/renderer.hpp"

#include "bvh/ray_scene.hpp"
#include "engine/parallel.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace nexdyn {

namespace {

using Vec3f = Eigen::Vector3f;

// Light and material constants of the one shading model. Colours are display values in [0, 1].
constexpr float kAmbient = 0.40f;           // light everywhere, so faces turned away stay readable
constexpr float kDiffuse = 0.60f;           // the light's share; kAmbient + kDiffuse = 1 on a lit face
constexpr float kShadowOnGround = 0.62f;    // how much light a shadowed grid point keeps
const Vec3f kSceneryColor(0.62f, 0.63f, 0.66f);
const Vec3f kGridLight(0.86f, 0.86f, 0.84f), kGridDark(0.79f, 0.79f, 0.77f), kGridLine(0.55f, 0.56f, 0.58f);
const Vec3f kSkyTop(0.74f, 0.80f, 0.89f), kSkyBottom(0.96f, 0.97f, 0.98f);

float clamp01(float x) { return std::min(1.0f, std::max(0.0f, x)); }

uint8_t to_byte(float c) { return static_cast<uint8_t>(std::lround(clamp01(c) * 255.0f)); }

// An orthonormal pair spanning the plane with normal n (unit), the same for the same n.
std::pair<Eigen::Vector3d, Eigen::Vector3d> plane_axes(const Eigen::Vector3d& n) {
  int least = 0;
  for (int d = 1; d < 3; ++d)
    if (std::abs(n[d]) < std::abs(n[least])) least = d;
  const Eigen::Vector3d e1 = n.cross(Eigen::Vector3d::Unit(least)).normalized();
  return {e1, n.cross(e1)};
}

// Everything a pixel needs that is the same for every pixel.
struct Frame {
  Eigen::Vector3d eye, forward, right, up;  // camera basis
  double tan_half = 0.0, aspect = 1.0;
  Eigen::Vector3d light;                    // unit, toward the light
  Eigen::Vector3d center;                   // of the bodies' bounds
  double radius = 1.0;                      // of the bodies' bounds
  float offset = 1e-4f;                     // shadow rays start this far off the surface
};

Vec3f background(double sy) {
  const float s = clamp01(static_cast<float>(0.5 + 0.5 * sy));
  return kSkyBottom + s * (kSkyTop - kSkyBottom);
}

bool in_shadow(const RayScene& rays, const Eigen::Vector3d& p, const Eigen::Vector3d& n, const Frame& f) {
  const Eigen::Vector3f origin = (p.cast<float>() + f.offset * n.cast<float>());
  const Eigen::Vector3f direction = f.light.cast<float>();
  return rays.occluded(origin.data(), direction.data(), 0.0f, std::numeric_limits<float>::infinity());
}

Vec3f shade_triangle(const RenderInput& in, const RayScene& rays, const RayScene::Hit& hit,
                     const Eigen::Vector3d& d, const Frame& f, ColorBy color) {
  const uint32_t* tri = &in.triangles[3 * size_t{hit.triangle}];
  const auto vertex = [&](int c) { return Eigen::Map<const Vec3f>(&in.positions[3 * size_t{tri[c]}]); };
  Eigen::Vector3d n = (vertex(1) - vertex(0)).cross(vertex(2) - vertex(0)).cast<double>().normalized();
  if (n.dot(d) > 0.0) n = -n;  // the back of an open obstacle surface
  const int32_t body = in.triangle_body[hit.triangle];
  Vec3f base = kSceneryColor;
  if (body >= 0 && color == ColorBy::body) base = body_color(body);
  if (body >= 0 && color == ColorBy::value) {
    const float value = (1.0f - hit.u - hit.v) * in.vertex_value[tri[0]] + hit.u * in.vertex_value[tri[1]] +
                        hit.v * in.vertex_value[tri[2]];
    base = ramp_color(in.value_max > 0.0f ? value / in.value_max : 0.0f);
  }
  const Eigen::Vector3d p = f.eye + static_cast<double>(hit.t) * d;
  double lit = std::max(0.0, n.dot(f.light));
  if (lit > 0.0 && in_shadow(rays, p, n, f)) lit = 0.0;
  // A little sky light from above keeps the sides apart from the undersides.
  const float sky = 0.08f * static_cast<float>(n.dot(in.up));
  return base * (kAmbient + sky + kDiffuse * static_cast<float>(lit));
}

// The grid colour at p on plane `plane`; `footprint` is a pixel's size there in grid cells.
Vec3f grid_color(const RenderInput::Plane& plane, const Eigen::Vector3d& p, double spacing, double footprint) {
  const auto [e1, e2] = plane_axes(plane.normal);
  const double s = (p - plane.point).dot(e1) / spacing, w = (p - plane.point).dot(e2) / spacing;
  const bool dark = (static_cast<int64_t>(std::floor(s)) + static_cast<int64_t>(std::floor(w))) % 2 != 0;
  const double to_line = std::min(std::abs(s - std::round(s)), std::abs(w - std::round(w)));
  Vec3f c = dark ? kGridDark : kGridLight;
  if (to_line < std::max(0.015, 0.6 * footprint)) c = kGridLine;
  // Far away a pixel covers many cells: fade the pattern to its mean so it does not shimmer.
  const float fade = clamp01(static_cast<float>((footprint - 0.15) / 0.35));
  const Vec3f mean = 0.5f * (kGridLight + kGridDark);
  return c + fade * (mean - c);
}

Vec3f trace_pixel(const RenderInput& in, const RayScene& rays, const Frame& f, int i, int j, int width,
                  int height, ColorBy color) {
  const double sx = (2.0 * (i + 0.5) / width - 1.0) * f.tan_half * f.aspect;
  const double sy = (1.0 - 2.0 * (j + 0.5) / height) * f.tan_half;
  const Eigen::Vector3d d = (f.forward + sx * f.right + sy * f.up).normalized();
  const Eigen::Vector3f origin = f.eye.cast<float>(), direction = d.cast<float>();
  const RayScene::Hit hit = rays.first_hit(origin.data(), direction.data(), std::numeric_limits<float>::infinity());
  double t_near = hit.triangle == RayScene::kNoHit ? std::numeric_limits<double>::infinity() : hit.t;

  int plane_hit = -1;
  for (size_t k = 0; k < in.planes.size(); ++k) {
    const RenderInput::Plane& plane = in.planes[k];
    const double facing = d.dot(plane.normal);
    if (facing >= -1e-12) continue;  // seen from behind or edge-on
    const double t = (plane.point - f.eye).dot(plane.normal) / facing;
    if (t > 0.0 && t < t_near) {
      t_near = t;
      plane_hit = static_cast<int>(k);
    }
  }
  if (plane_hit >= 0) {
    const RenderInput::Plane& plane = in.planes[static_cast<size_t>(plane_hit)];
    const Eigen::Vector3d p = f.eye + t_near * d;
    const double pixel_angle = 2.0 * f.tan_half / height;
    const double footprint = t_near * pixel_angle / (std::abs(d.dot(plane.normal)) * in.grid_spacing);
    Vec3f c = grid_color(plane, p, in.grid_spacing, footprint);
    if (f.light.dot(plane.normal) <= 0.0 || in_shadow(rays, p, plane.normal, f)) c *= kShadowOnGround;
    // The grid ends softly a few scene sizes away instead of at a hard horizon.
    const double far = ((p - f.center) - (p - f.center).dot(plane.normal) * plane.normal).norm();
    const float fade = clamp01(static_cast<float>((far - 3.0 * f.radius) / (3.0 * f.radius)));
    return c + fade * (background(sy / f.tan_half) - c);
  }
  if (hit.triangle != RayScene::kNoHit) return shade_triangle(in, rays, hit, d, f, color);
  return background(sy / f.tan_half);
}

}  // namespace

Eigen::Vector3f body_color(int32_t body) {
  // Twelve colours far apart in hue and lightness, muted so shading stays readable.
  static const std::array<Vec3f, 12> palette = {
      Vec3f(0.90f, 0.45f, 0.20f), Vec3f(0.25f, 0.55f, 0.85f), Vec3f(0.40f, 0.72f, 0.35f),
      Vec3f(0.86f, 0.30f, 0.38f), Vec3f(0.60f, 0.45f, 0.80f), Vec3f(0.95f, 0.75f, 0.25f),
      Vec3f(0.30f, 0.72f, 0.72f), Vec3f(0.75f, 0.50f, 0.35f), Vec3f(0.85f, 0.50f, 0.70f),
      Vec3f(0.55f, 0.62f, 0.25f), Vec3f(0.35f, 0.40f, 0.70f), Vec3f(0.95f, 0.58f, 0.50f)};
  return palette[static_cast<size_t>(body) % palette.size()];
}

Eigen::Vector3f ramp_color(float value) {
  // Dark blue through teal, green and yellow to red: ordered in lightness up to yellow, so the
  // order of values reads even in grey.
  static const std::array<Vec3f, 5> stops = {Vec3f(0.16f, 0.18f, 0.50f), Vec3f(0.13f, 0.52f, 0.62f),
                                             Vec3f(0.38f, 0.74f, 0.36f), Vec3f(0.97f, 0.85f, 0.22f),
                                             Vec3f(0.85f, 0.22f, 0.15f)};
  const float x = clamp01(value) * static_cast<float>(stops.size() - 1);
  const size_t k = std::min(static_cast<size_t>(x), stops.size() - 2);
  const float s = x - static_cast<float>(k);
  return stops[k] + s * (stops[k + 1] - stops[k]);
}

double round_grid_spacing(double extent) {
  if (!(extent > 0.0) || !std::isfinite(extent)) return 1.0;
  const double raw = extent / 5.0;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double step : {1.0, 2.0, 5.0})
    if (raw <= step * decade * 1.5) return step * decade;
  return 10.0 * decade;
}

RenderCamera fit_camera(const Eigen::Vector3d& lower, const Eigen::Vector3d& upper, const Eigen::Vector3d& up,
                        double fov_deg, double aspect) {
  const Eigen::Vector3d u = up.normalized();
  const Eigen::Vector3d center = 0.5 * (lower + upper);
  const double radius = std::max(0.5 * (upper - lower).norm(), 1e-6);
  // The front is +z seen down -z (or -y when z is up), the side the one to its right: the view
  // most scene files are written for.
  Eigen::Vector3d front = Eigen::Vector3d::UnitZ();
  if (std::abs(u.dot(front)) > 0.9) front = -Eigen::Vector3d::UnitY();
  front = (front - front.dot(u) * u).normalized();
  const Eigen::Vector3d side = u.cross(front);
  const double azimuth = 30.0 * M_PI / 180.0, elevation = 25.0 * M_PI / 180.0;
  const Eigen::Vector3d direction = std::cos(elevation) * (std::cos(azimuth) * front + std::sin(azimuth) * side) +
                                    std::sin(elevation) * u;
  // The nearest distance at which every corner of the box is inside the picture: a corner q
  // (from the centre) at depth D + q.f needs |q.r| <= tan_x (D + q.f) and |q.u| <= tan_y (D + q.f).
  const Eigen::Vector3d forward = -direction;
  const Eigen::Vector3d right = forward.cross(u).normalized(), image_up = right.cross(forward);
  const double tan_y = std::tan(0.5 * fov_deg * M_PI / 180.0), tan_x = tan_y * aspect;
  double distance = radius;  // at least outside a sphere around the box's centre
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d q = Eigen::Vector3d((corner & 1) ? upper.x() : lower.x(), (corner & 2) ? upper.y() : lower.y(),
                                              (corner & 4) ? upper.z() : lower.z()) - center;
    distance = std::max({distance, std::abs(q.dot(right)) / tan_x - q.dot(forward),
                         std::abs(q.dot(image_up)) / tan_y - q.dot(forward)});
  }
  RenderCamera camera;
  camera.target = center;
  camera.position = center + direction * (1.08 * distance);  // a margin of a few per cent
  camera.up = u;
  camera.fov_deg = fov_deg;
  return camera;
}

Image render_image(const RenderInput& in, const RenderCamera& camera, int width, int height, ColorBy color) {
  RayScene rays(in.positions, in.triangles);
  Frame f;
  f.eye = camera.position;
  f.forward = (camera.target - camera.position).normalized();
  f.right = f.forward.cross(camera.up).normalized();
  f.up = f.right.cross(f.forward);
  f.tan_half = std::tan(0.5 * camera.fov_deg * M_PI / 180.0);
  f.aspect = static_cast<double>(width) / height;
  const Eigen::Vector3d up = in.up.normalized();
  f.light = (up + 0.5 * f.right - 1.2 * f.forward).normalized();  // above, right, behind the eye
  Eigen::Vector3d lower = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d upper = -lower;
  for (size_t v = 0; v + 2 < in.positions.size(); v += 3) {
    const Eigen::Vector3d p = Eigen::Map<const Vec3f>(&in.positions[v]).cast<double>();
    lower = lower.cwiseMin(p);
    upper = upper.cwiseMax(p);
  }
  if (in.positions.empty()) lower = upper = Eigen::Vector3d::Zero();
  f.center = 0.5 * (lower + upper);
  f.radius = std::max(0.5 * (upper - lower).norm(), 1e-3);
  f.offset = static_cast<float>(1e-4 * f.radius);

  Image image;
  image.width = width;
  image.height = height;
  image.rgb.resize(3 * size_t(width) * size_t(height));
  parallel_for(
      height,
      [&](int64_t begin, int64_t end) {
        for (int64_t j = begin; j < end; ++j)
          for (int i = 0; i < width; ++i) {
            const Vec3f c = trace_pixel(in, rays, f, i, static_cast<int>(j), width, height, color);
            uint8_t* out = &image.rgb[3 * (size_t(j) * size_t(width) + size_t(i))];
            for (int k = 0; k < 3; ++k) out[k] = to_byte(c[k]);
          }
      },
      4);
  return image;
}

}  // namespace nexdyn

// Tests of engine/mesh/intersection: the exact triangle-triangle test against references that
// compute the answer another way (parametric edge-triangle solves in long double, 2D separating
// axes), exact touching and 1e-12 near-miss cases, the mesh-level pair search against its O(n^2)
// definition on two box meshes, and the winding-number inside test on a box and a sphere.
#include "engine/mesh/intersection.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <random>
#include <vector>

#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/surface.hpp"

using namespace nexdyn;
using Eigen::Vector3d;

namespace {

using Triangle = std::array<Vector3d, 3>;

bool intersect(const Triangle& a, const Triangle& b) {
  return triangles_intersect(a[0], a[1], a[2], b[0], b[1], b[2]);
}

// Reference outcome: yes, no, or too close to a boundary for a rounded computation to tell.
enum class Reference { no, yes, ambiguous };

// Segment pq against triangle abc by solving p + t (q - p) = a + u (b - a) + v (c - a) with
// Cramer's rule in long double; the crossing is inside when t, 1 - t, u, v, 1 - u - v are all
// >= 0. Returns the smallest of those five (negative: miss); NaN when the segment is nearly
// parallel to the plane (not decidable this way).
long double crossing_margin(const Vector3d& p, const Vector3d& q, const Vector3d& a,
                            const Vector3d& b, const Vector3d& c) {
  using V = Eigen::Matrix<long double, 3, 1>;
  const V d = (q - p).cast<long double>();
  const V e1 = (b - a).cast<long double>();
  const V e2 = (c - a).cast<long double>();
  const V r = (p - a).cast<long double>();
  // [e1 e2 -d] (u v t)^T = r
  Eigen::Matrix<long double, 3, 3> m;
  m << e1, e2, -d;
  const long double det = m.determinant();
  if (std::abs(det) < 1e-9L * e1.norm() * e2.norm() * d.norm()) return NAN;
  auto replaced = [&](int column) {
    Eigen::Matrix<long double, 3, 3> mc = m;
    mc.col(column) = r;
    return mc.determinant() / det;
  };
  const long double u = replaced(0);
  const long double v = replaced(1);
  const long double t = replaced(2);
  return std::min({t, 1.0L - t, u, v, 1.0L - u - v});
}

// Non-coplanar triangles meet iff one of the 6 edges crosses the other triangle.
Reference edge_crossing_reference(const Triangle& a, const Triangle& b) {
  bool any = false;
  for (int side = 0; side < 2; ++side) {
    const Triangle& s = side == 0 ? a : b;
    const Triangle& t = side == 0 ? b : a;
    for (int i = 0; i < 3; ++i) {
      const long double margin = crossing_margin(s[i], s[(i + 1) % 3], t[0], t[1], t[2]);
      if (std::isnan(margin) || std::abs(margin) < 1e-9L) return Reference::ambiguous;
      any = any || margin > 0;
    }
  }
  return any ? Reference::yes : Reference::no;
}

// Two triangles of one plane, in 2D coordinates: disjoint iff some edge normal separates them.
Reference separating_axis_reference(const std::array<Eigen::Vector2d, 3>& a,
                                    const std::array<Eigen::Vector2d, 3>& b) {
  bool separated = false;
  for (int side = 0; side < 2; ++side) {
    const auto& s = side == 0 ? a : b;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector2d edge = s[(i + 1) % 3] - s[i];
      const Eigen::Vector2d axis = Eigen::Vector2d(-edge.y(), edge.x()).normalized();
      double lo_a = INFINITY, hi_a = -INFINITY, lo_b = INFINITY, hi_b = -INFINITY;
      for (int k = 0; k < 3; ++k) {
        lo_a = std::min(lo_a, axis.dot(a[k]));
        hi_a = std::max(hi_a, axis.dot(a[k]));
        lo_b = std::min(lo_b, axis.dot(b[k]));
        hi_b = std::max(hi_b, axis.dot(b[k]));
      }
      const double gap = std::max(lo_b - hi_a, lo_a - hi_b);  // > 0: separated on this axis
      if (std::abs(gap) < 1e-9) return Reference::ambiguous;
      separated = separated || gap > 0;
    }
  }
  return separated ? Reference::no : Reference::yes;
}

Triangle random_triangle(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Triangle t;
  for (auto& v : t) v = Vector3d(unit(rng), unit(rng), unit(rng));
  return t;
}

// The 6 vertex orders of a triangle (3 rotations, both windings).
std::array<Triangle, 6> vertex_orders(const Triangle& t) {
  return {{{t[0], t[1], t[2]},
           {t[1], t[2], t[0]},
           {t[2], t[0], t[1]},
           {t[0], t[2], t[1]},
           {t[2], t[1], t[0]},
           {t[1], t[0], t[2]}}};
}

// Several bodies in one buffer, as the engine holds them: positions concatenated, ids offset.
TetMesh concatenate(const TetMesh& a, const TetMesh& b, const Vector3d& shift_b) {
  TetMesh out = a;
  for (int32_t v = 0; v < b.num_vertices(); ++v)
    for (int d = 0; d < 3; ++d) out.positions.push_back(b.positions[3 * v + d] + shift_b[d]);
  for (int32_t id : b.tets) out.tets.push_back(id + a.num_vertices());
  return out;
}

// The definition: every pair i < j sharing no vertex id, tested directly.
std::vector<IndexPair> intersecting_pairs_brute_force(const TetMesh& mesh,
                                                      const SurfaceMesh& surface) {
  const auto& tri = surface.triangles;
  auto vertex = [&](int32_t id) {
    return Vector3d(mesh.positions[3 * id], mesh.positions[3 * id + 1], mesh.positions[3 * id + 2]);
  };
  std::vector<IndexPair> pairs;
  for (int32_t i = 0; i < surface.num_triangles(); ++i) {
    for (int32_t j = i + 1; j < surface.num_triangles(); ++j) {
      bool share = false;
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) share = share || tri[3 * i + k] == tri[3 * j + l];
      if (share) continue;
      if (triangles_intersect(vertex(tri[3 * i]), vertex(tri[3 * i + 1]), vertex(tri[3 * i + 2]),
                              vertex(tri[3 * j]), vertex(tri[3 * j + 1]), vertex(tri[3 * j + 2])))
        pairs.emplace_back(i, j);
    }
  }
  return pairs;
}

std::vector<IndexPair> intersecting_pairs(const TetMesh& mesh, const SurfaceMesh& surface) {
  return intersecting_triangle_pairs(mesh.positions.data(), surface.triangles.data(),
                                     surface.num_triangles());
}

}  // namespace

TEST_SUITE_BEGIN("contact");

TEST_CASE("intersection: orient3d_sign is exact on coplanar points of mixed scales") {
  // Points q = (x, y, x/2 + y/4) with x, y multiples of 2^-30 in [0, 1) lie exactly on the plane
  // z = x/2 + y/4 through the origin, and so do 2^-20 q1, 2^20 q2, q3, q4. Differences of
  // coordinates 2^40 apart round, so the double determinant is noise and only the exact fallback
  // finds 0, or, with d moved one ulp in z, the sign of the normal's z component: the 2D
  // orientation of a, b, c, computed exactly in integers.
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<int64_t> k(0, (int64_t{1} << 30) - 1);
  for (int trial = 0; trial < 2000; ++trial) {
    int64_t ix[4];
    int64_t iy[4];
    Vector3d q[4];
    for (int i = 0; i < 4; ++i) {
      ix[i] = k(rng);
      iy[i] = k(rng);
      const double x = static_cast<double>(ix[i]) * 0x1p-30;
      const double y = static_cast<double>(iy[i]) * 0x1p-30;
      q[i] = Vector3d(x, y, x / 2 + y / 4);
    }
    const Vector3d a = 0x1p-20 * q[0];
    const Vector3d b = 0x1p20 * q[1];
    const Vector3d c = q[2];
    const Vector3d d = q[3];
    REQUIRE(orient3d_sign(a, b, c, d) == 0);
    // 2^80 * ((b - a) x (c - a)).z = 2^40 K(q1, q2) + 2^20 K(q0, q1) + K(q2, q0), K in 2^-60 units.
    auto cross = [&](int i, int j) {
      return static_cast<__int128>(ix[i]) * iy[j] - static_cast<__int128>(iy[i]) * ix[j];
    };
    const __int128 nz = (cross(1, 2) << 40) + (cross(0, 1) << 20) + cross(2, 0);
    if (nz == 0) continue;
    const int expected = nz > 0 ? 1 : -1;
    const Vector3d above(d.x(), d.y(), std::nextafter(d.z(), INFINITY));
    const Vector3d below(d.x(), d.y(), std::nextafter(d.z(), -INFINITY));
    CHECK(orient3d_sign(a, b, c, above) == expected);
    CHECK(orient3d_sign(a, b, c, below) == -expected);
    // An even permutation keeps the sign, an odd one flips it.
    CHECK(orient3d_sign(b, c, a, above) == expected);
    CHECK(orient3d_sign(b, a, c, above) == -expected);
  }
}

TEST_CASE("intersection: random triangle pairs agree with an edge-crossing reference") {
  std::mt19937_64 rng(20240601);
  int yes = 0;
  int no = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Triangle a = random_triangle(rng);
    const Triangle b = random_triangle(rng);
    const Reference expected = edge_crossing_reference(a, b);
    if (expected == Reference::ambiguous) continue;
    const bool got = intersect(a, b);
    CHECK(got == (expected == Reference::yes));
    (got ? yes : no) += 1;
  }
  // Both outcomes are well represented, so neither "always true" nor "always false" passes.
  CHECK(yes > 1000);
  CHECK(no > 1000);
}

TEST_CASE("intersection: answer is symmetric and independent of vertex order and winding") {
  std::mt19937_64 rng(99);
  int yes = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Triangle a = random_triangle(rng);
    const Triangle b = random_triangle(rng);
    const bool expected = intersect(a, b);
    yes += expected;
    for (const Triangle& ao : vertex_orders(a)) {
      CHECK(intersect(ao, b) == expected);
      CHECK(intersect(b, ao) == expected);
    }
    for (const Triangle& bo : vertex_orders(b)) CHECK(intersect(a, bo) == expected);
  }
  CHECK(yes > 100);
}

TEST_CASE("intersection: random coplanar triangle pairs agree with separating axes") {
  // Exactly coplanar inputs: the planes z = 0.3, x = -2, and x + y + z = 1 with coordinates on a
  // 2^-10 grid (so the third coordinate 1 - u - v is exact).
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<int> grid(0, 1024);
  int yes = 0;
  int no = 0;
  for (int trial = 0; trial < 6000; ++trial) {
    std::array<Eigen::Vector2d, 3> a2;
    std::array<Eigen::Vector2d, 3> b2;
    for (auto& v : a2) v = Eigen::Vector2d(grid(rng), grid(rng)) * 0x1p-10;
    for (auto& v : b2) v = Eigen::Vector2d(grid(rng), grid(rng)) * 0x1p-10;
    auto area = [](const std::array<Eigen::Vector2d, 3>& t) {
      const Eigen::Vector2d e1 = t[1] - t[0];
      const Eigen::Vector2d e2 = t[2] - t[0];
      return std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    };
    if (area(a2) < 1e-3 || area(b2) < 1e-3) continue;  // the reference needs proper triangles
    const Reference expected = separating_axis_reference(a2, b2);
    if (expected == Reference::ambiguous) continue;
    auto lift = [&](const std::array<Eigen::Vector2d, 3>& t, int plane) {
      Triangle out;
      for (int k = 0; k < 3; ++k) {
        const double u = t[k].x();
        const double v = t[k].y();
        out[k] = plane == 0   ? Vector3d(u, v, 0.3)
                 : plane == 1 ? Vector3d(-2.0, u, v)
                              : Vector3d(u, v, 1.0 - u - v);
      }
      return out;
    };
    const int plane = trial % 3;
    const bool got = intersect(lift(a2, plane), lift(b2, plane));
    CHECK(got == (expected == Reference::yes));
    (got ? yes : no) += 1;
  }
  CHECK(yes > 500);
  CHECK(no > 500);
}

TEST_CASE("intersection: coplanar touching at a point is decided exactly") {
  // In the plane z = 0.3: A's edge runs along the line y = 0.75 x from 2^-20 D to 2^20 D with
  // D = (4h, 3h), and B touches that edge at its point D from the other side. The points are
  // exact (h has 50 significant bits), but the differences of coordinates 2^40 apart round, so
  // the double orientation of (a0, a1, D) is noise around 0 and only the exact fallback gets 0
  // (or the sign, when D moves by one ulp).
  std::mt19937_64 rng(13);
  std::uniform_int_distribution<int64_t> mantissa(0, (int64_t{1} << 50) - 1);
  std::uniform_real_distribution<double> unit(0.1, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const double h = 1.0 + static_cast<double>(mantissa(rng)) * 0x1p-50;
    const Vector3d d(4 * h, 3 * h, 0.3);
    const Vector3d a0(0x1p-20 * d.x(), 0x1p-20 * d.y(), 0.3);
    const Vector3d a1(0x1p20 * d.x(), 0x1p20 * d.y(), 0.3);
    const Vector3d a2(0.0, 0x1p19 * h, 0.3);  // above the line
    const double r = unit(rng);
    const Triangle a = {a0, a1, a2};
    const Triangle b = {d, d + Vector3d(r, -r, 0), d + Vector3d(2 * r, -0.5 * r, 0)};  // below
    CHECK(intersect(a, b));
    CHECK(intersect(b, a));
    // 1e-12 further below the line: apart.
    const Vector3d gap(3e-12, -4e-12, 0);
    const Triangle b_apart = {b[0] + gap, b[1] + gap, b[2] + gap};
    CHECK_FALSE(intersect(a, b_apart));
    CHECK_FALSE(intersect(b_apart, a));
    // One ulp below the line: apart too, a sign the double filter cannot certify.
    const Triangle b_ulp = {Vector3d(d.x(), std::nextafter(d.y(), 0.0), 0.3), b[1], b[2]};
    CHECK_FALSE(intersect(a, b_ulp));
    CHECK_FALSE(intersect(b_ulp, a));
  }
}

TEST_CASE("intersection: triangles sharing a vertex always intersect") {
  // The shared vertex is the same double triple, so its orientations are exactly 0; any rounding
  // in the predicates would make some of these fail.
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 3000; ++trial) {
    const Triangle a = random_triangle(rng);
    Triangle b = random_triangle(rng);
    b[trial % 3] = a[(trial / 3) % 3];
    CHECK(intersect(a, b));
    // Sharing a whole edge as well.
    b[(trial + 1) % 3] = a[(trial / 3 + 1) % 3];
    CHECK(intersect(a, b));
  }
}

TEST_CASE("intersection: touching configurations count as intersecting") {
  const Triangle floor = {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  SUBCASE("a vertex exactly on the other's interior") {
    const Triangle t = {Vector3d(0.25, 0.25, 0), Vector3d(0.3, 0.2, 1), Vector3d(0.1, 0.4, 2)};
    CHECK(intersect(floor, t));
    CHECK(intersect(t, floor));
  }
  SUBCASE("a vertex exactly on the other's edge") {
    const Triangle t = {Vector3d(0.5, 0.5, 0), Vector3d(0.8, 0.9, 1), Vector3d(0.9, 0.7, 1)};
    CHECK(intersect(floor, t));
  }
  SUBCASE("edges crossing in one point, planes not parallel") {
    // Triangle in the plane x = 0.5 whose vertical edge passes through the point (0.5, 0, 0) of
    // the floor's edge y = 0; everything else of it has y < 0.
    const Triangle t = {Vector3d(0.5, 0, -1), Vector3d(0.5, 0, 1), Vector3d(0.5, -1, 0)};
    CHECK(intersect(floor, t));
  }
  SUBCASE("coplanar neighbours sharing an edge") {
    const Triangle t = {Vector3d(1, 0, 0), Vector3d(1, 1, 0), Vector3d(0, 1, 0)};
    CHECK(intersect(floor, t));
  }
  SUBCASE("coplanar, an edge passing exactly through the other's vertex") {
    // Both ends of the edge (-1, 1.5) - (1, 0.5) are outside the floor; its midpoint is (0, 1).
    const Triangle t = {Vector3d(-1, 1.5, 0), Vector3d(1, 0.5, 0), Vector3d(0, 2, 0)};
    CHECK(intersect(floor, t));
    CHECK(intersect(t, floor));
    const Triangle lifted = {Vector3d(-1, 1.5 + 1e-12, 0), Vector3d(1, 0.5 + 1e-12, 0),
                             Vector3d(0, 2, 0)};
    CHECK_FALSE(intersect(floor, lifted));
  }
  SUBCASE("coplanar triangles touching at a vertex only") {
    const Triangle t = {Vector3d(1, 0, 0), Vector3d(2, 0, 0), Vector3d(2, 1, 0)};
    CHECK(intersect(floor, t));
  }
}

TEST_CASE("intersection: 1e-12 gaps separate") {
  const Triangle floor = {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  constexpr double kGap = 1e-12;
  SUBCASE("a vertex just above the interior") {
    const Triangle t = {Vector3d(0.25, 0.25, kGap), Vector3d(0.3, 0.2, 1), Vector3d(0.1, 0.4, 2)};
    CHECK_FALSE(intersect(floor, t));
  }
  SUBCASE("edges passing at 1e-12") {
    const Triangle t = {Vector3d(0.5, -kGap, -1), Vector3d(0.5, -kGap, 1), Vector3d(0.5, -1, 0)};
    CHECK_FALSE(intersect(floor, t));
  }
  SUBCASE("parallel copies, overlapping when projected") {
    for (const double z : {kGap, -kGap}) {
      const Triangle t = {Vector3d(0.1, 0.1, z), Vector3d(0.9, 0.05, z), Vector3d(0.2, 0.7, z)};
      CHECK_FALSE(intersect(floor, t));
      const Triangle same = {Vector3d(0, 0, z), Vector3d(1, 0, z), Vector3d(0, 1, z)};
      CHECK_FALSE(intersect(floor, same));
    }
  }
  SUBCASE("coplanar neighbours 1e-12 apart") {
    const Triangle t = {Vector3d(1 + kGap, 0, 0), Vector3d(1, 1 + kGap, 0), Vector3d(kGap, 1, 0)};
    CHECK_FALSE(intersect(floor, t));
  }
  SUBCASE("random parallel copies along a tilted normal") {
    std::mt19937_64 rng(11);
    for (int trial = 0; trial < 1000; ++trial) {
      const Triangle a = random_triangle(rng);
      const Vector3d n = (a[1] - a[0]).cross(a[2] - a[0]).normalized();
      Triangle up;
      Triangle down;
      for (int k = 0; k < 3; ++k) {
        up[k] = a[k] + kGap * n;
        down[k] = a[k] - kGap * n;
      }
      CHECK_FALSE(intersect(a, up));
      CHECK_FALSE(intersect(a, down));
      CHECK_FALSE(intersect(up, a));
    }
  }
}

TEST_CASE("intersection: coplanar overlapping triangles intersect") {
  const Triangle floor = {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  // Edges crossing in the plane.
  CHECK(intersect(floor, {Vector3d(0.2, -0.5, 0), Vector3d(0.7, 0.8, 0), Vector3d(-0.3, 0.5, 0)}));
  // One strictly inside the other (no edges cross): only the containment check finds it.
  const Triangle inner = {Vector3d(0.1, 0.1, 0), Vector3d(0.5, 0.1, 0), Vector3d(0.1, 0.5, 0)};
  CHECK(intersect(floor, inner));
  CHECK(intersect(inner, floor));
  CHECK(intersect(floor, floor));
  // In a tilted plane, x + y + z = 1, with exactly representable points.
  const Triangle tilted = {Vector3d(1, 0, 0), Vector3d(0, 1, 0), Vector3d(0, 0, 1)};
  const Triangle inside = {Vector3d(0.5, 0.25, 0.25), Vector3d(0.25, 0.5, 0.25),
                           Vector3d(0.25, 0.25, 0.5)};
  CHECK(intersect(tilted, inside));
  const Triangle beside = {Vector3d(1.5, -0.25, -0.25), Vector3d(2, -0.5, -0.5),
                           Vector3d(1.5, 0, -0.5)};
  CHECK_FALSE(intersect(tilted, beside));
}

TEST_CASE("intersection: zero-area triangles are the union of their edges") {
  const Triangle floor = {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  // A needle through the floor, and one hovering beside it.
  const Triangle needle = {Vector3d(0.2, 0.2, -1), Vector3d(0.2, 0.2, 0.5), Vector3d(0.2, 0.2, 1)};
  CHECK(intersect(floor, needle));
  CHECK(intersect(needle, floor));
  const Triangle away = {Vector3d(0.8, 0.8, -1), Vector3d(0.8, 0.8, 0), Vector3d(0.8, 0.8, 1)};
  CHECK_FALSE(intersect(floor, away));
}

TEST_CASE("intersection: triangle pairs of overlapping cubes equal the O(n^2) definition") {
  const TetMesh cube = make_box_mesh(Vector3d(1, 1, 1), {2, 2, 2});
  // A generic overlap, and one where the y and z faces of the two cubes are coplanar.
  for (const Vector3d& shift : {Vector3d(0.5, 0.3, 0.2), Vector3d(0.5, 0, 0)}) {
    CAPTURE(shift.transpose());
    const TetMesh both = concatenate(cube, cube, shift);
    const SurfaceMesh surface = extract_surface(both);
    const std::vector<IndexPair> pairs = intersecting_pairs(both, surface);
    CHECK(!pairs.empty());
    CHECK(pairs == intersecting_pairs_brute_force(both, surface));
    // Only triangles of different cubes can cross (each cube alone is a valid surface).
    const int32_t first_of_second = cube.num_vertices();
    for (const auto& [i, j] : pairs)
      CHECK((surface.triangles[3 * i] < first_of_second) !=
            (surface.triangles[3 * j] < first_of_second));
    // Independent of the thread count.
    for (int threads = 1; threads <= 2; ++threads) {
      test::ThreadsScope limit(threads);
      CHECK(intersecting_pairs(both, surface) == pairs);
    }
  }
}

TEST_CASE("intersection: separated or single cubes have no intersecting pairs") {
  const TetMesh cube = make_box_mesh(Vector3d(1, 1, 1), {3, 2, 2});
  CHECK(intersecting_pairs(cube, extract_surface(cube)).empty());
  const TetMesh apart = concatenate(cube, cube, Vector3d(1.5, 0.2, 0));
  CHECK(intersecting_pairs(apart, extract_surface(apart)).empty());
  // Faces 1e-12 apart are separated; faces exactly in contact touch, which counts.
  const TetMesh near = concatenate(cube, cube, Vector3d(1 + 1e-12, 0, 0));
  CHECK(intersecting_pairs(near, extract_surface(near)).empty());
  const TetMesh touching = concatenate(cube, cube, Vector3d(1, 0, 0));
  const SurfaceMesh touching_surface = extract_surface(touching);
  const std::vector<IndexPair> touching_pairs = intersecting_pairs(touching, touching_surface);
  CHECK(!touching_pairs.empty());
  CHECK(touching_pairs == intersecting_pairs_brute_force(touching, touching_surface));
}

TEST_CASE("intersection: point_inside_surface on a box mesh") {
  const TetMesh box = make_box_mesh(Vector3d(1, 2, 3), {2, 3, 4});
  const SurfaceMesh surface = extract_surface(box);
  auto inside = [&](const Vector3d& p) {
    return point_inside_surface(p, box.positions.data(), surface.triangles.data(),
                                surface.num_triangles());
  };
  auto winding = [&](const Vector3d& p) {
    return winding_number(p, box.positions.data(), surface.triangles.data(),
                          surface.num_triangles());
  };
  CHECK(inside(Vector3d(0, 0, 0)));
  CHECK(inside(Vector3d(0.49, 0.99, -1.49)));
  CHECK(inside(Vector3d(0.5 - 1e-9, 0, 0)));
  CHECK_FALSE(inside(Vector3d(0.5 + 1e-9, 0, 0)));
  CHECK_FALSE(inside(Vector3d(0, 0, 1.6)));
  CHECK_FALSE(inside(Vector3d(5, -3, 2)));
  CHECK(winding(Vector3d(0.1, 0.2, 0.3)) == nexdyn::test::relative(1.0, 1e-12));
  CHECK(winding(Vector3d(3, 0.2, 0.3)) == doctest::Approx(0.0).epsilon(1e-12));
  // Inward winding flips the sign, and the point is still inside.
  std::vector<int32_t> reversed = surface.triangles;
  for (size_t t = 0; t < reversed.size(); t += 3) std::swap(reversed[t + 1], reversed[t + 2]);
  CHECK(winding_number(Vector3d(0.1, 0.2, 0.3), box.positions.data(), reversed.data(),
                       surface.num_triangles()) == nexdyn::test::relative(-1.0, 1e-12));
  CHECK(point_inside_surface(Vector3d(0.1, 0.2, 0.3), box.positions.data(), reversed.data(),
                             surface.num_triangles()));
}

TEST_CASE("intersection: point_inside_surface on the sphere1K mesh") {
  const TetMesh sphere =
      read_msh(std::filesystem::path(NEXDYN_SOURCE_DIR) / "scenes" / "meshes" / "sphere1K.msh");
  const SurfaceMesh surface = extract_surface(sphere);
  REQUIRE(surface.num_triangles() > 100);
  auto vertex = [&](int32_t id) {
    return Vector3d(sphere.positions[3 * id], sphere.positions[3 * id + 1],
                    sphere.positions[3 * id + 2]);
  };
  // Centre of the bounding box; inner radius: closest triangle plane (a ball that fits inside a
  // convex polyhedron); outer radius: farthest surface vertex.
  Vector3d lo = vertex(surface.vertices[0]);
  Vector3d hi = lo;
  for (int32_t v : surface.vertices) {
    lo = lo.cwiseMin(vertex(v));
    hi = hi.cwiseMax(vertex(v));
  }
  const Vector3d centre = (lo + hi) / 2;
  double r_in = INFINITY;
  double r_out = 0.0;
  for (int32_t t = 0; t < surface.num_triangles(); ++t) {
    const Vector3d a = vertex(surface.triangles[3 * t]);
    const Vector3d n =
        (vertex(surface.triangles[3 * t + 1]) - a).cross(vertex(surface.triangles[3 * t + 2]) - a);
    r_in = std::min(r_in, n.normalized().dot(a - centre));  // positive: outward winding
  }
  for (int32_t v : surface.vertices) r_out = std::max(r_out, (vertex(v) - centre).norm());
  REQUIRE(r_in > 0.8 * r_out);  // a reasonable sphere, wound outward
  std::mt19937_64 rng(17);
  std::normal_distribution<double> gauss;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Vector3d dir = Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const Vector3d in = centre + (0.999 * r_in * unit(rng)) * dir;
    const Vector3d out = centre + (1.001 * r_out + 2.0 * r_out * unit(rng)) * dir;
    CHECK(point_inside_surface(in, sphere.positions.data(), surface.triangles.data(),
                               surface.num_triangles()));
    CHECK_FALSE(point_inside_surface(out, sphere.positions.data(), surface.triangles.data(),
                                     surface.num_triangles()));
  }
}

namespace {

// Integer geometry for the reference below: exact in int64 for small coordinates.
using IntPoint = std::array<int64_t, 3>;

IntPoint sub(const IntPoint& a, const IntPoint& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
IntPoint cross(const IntPoint& a, const IntPoint& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
int64_t dot(const IntPoint& a, const IntPoint& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
bool is_zero(const IntPoint& a) { return a[0] == 0 && a[1] == 0 && a[2] == 0; }
int64_t det3(const IntPoint& a, const IntPoint& b, const IntPoint& c) { return dot(a, cross(b, c)); }
Vector3d to_vector(const IntPoint& a) { return Vector3d(double(a[0]), double(a[1]), double(a[2])); }

bool one_sign(std::initializer_list<int64_t> values) {
  bool positive = true, negative = true;
  for (int64_t x : values) {
    positive = positive && x > 0;
    negative = negative && x < 0;
  }
  return positive || negative;
}

// Reference for triangles_overlap_beyond_vertex, by another route: near v each triangle is its
// wedge v + cone(p1 - v, p2 - v) and the intersection is convex, so the triangles share a point
// other than v iff the wedges do, iff some nonzero l >= 0 has l1 a1 + l2 a2 - l3 b1 - l4 b2 = 0
// (a = p - v, b = q - v). Such an l exists iff the kernel vector of some circuit (a minimal
// dependent set) of these four columns has one sign: two opposite parallel columns, three
// coplanar ones no two parallel, or all four with every three independent.
bool wedges_meet(const IntPoint& v, const IntPoint& p1, const IntPoint& p2, const IntPoint& q1,
                 const IntPoint& q2) {
  const IntPoint b1 = sub(q1, v), b2 = sub(q2, v);
  const std::array<IntPoint, 4> c = {sub(p1, v), sub(p2, v), IntPoint{-b1[0], -b1[1], -b1[2]},
                                     IntPoint{-b2[0], -b2[1], -b2[2]}};
  auto parallel = [](const IntPoint& x, const IntPoint& y) { return is_zero(cross(x, y)); };
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      if (parallel(c[i], c[j]) && dot(c[i], c[j]) < 0) return true;
  int64_t minor[4];
  for (int skip = 0; skip < 4; ++skip) {
    std::array<IntPoint, 3> t;
    for (int k = 0, m = 0; k < 4; ++k)
      if (k != skip) t[m++] = c[k];
    minor[skip] = det3(t[0], t[1], t[2]);
    if (minor[skip] != 0 || parallel(t[0], t[1]) || parallel(t[1], t[2]) || parallel(t[2], t[0]))
      continue;
    const IntPoint n = cross(t[0], t[1]);
    if (one_sign({dot(cross(t[1], t[2]), n), dot(cross(t[2], t[0]), n), dot(cross(t[0], t[1]), n)}))
      return true;
  }
  const bool all_independent = minor[0] != 0 && minor[1] != 0 && minor[2] != 0 && minor[3] != 0;
  return all_independent && one_sign({minor[0], -minor[1], minor[2], -minor[3]});
}

}  // namespace

TEST_CASE("intersection: triangles_overlap_beyond_vertex on handmade corners") {
  const Vector3d v(0, 0, 0), p1(2, 0, 0), p2(0, 2, 0);
  auto overlap = [&](const Vector3d& q1, const Vector3d& q2) {
    const bool result = triangles_overlap_beyond_vertex(v, p1, p2, q1, q2);
    CHECK(triangles_overlap_beyond_vertex(v, q2, q1, p2, p1) == result);  // symmetric
    return result;
  };
  // Neighbours around a vertex of a closed surface: only v in common.
  CHECK_FALSE(overlap(Vector3d(0, -2, 0), Vector3d(-2, 0, 1)));
  CHECK_FALSE(overlap(Vector3d(0, 0, 2), Vector3d(-1, -1, 0)));
  // Coplanar corners that overlap, that share a side's direction, that only meet at v.
  CHECK(overlap(Vector3d(2, 2, 0), Vector3d(-1, 3, 0)));
  CHECK(overlap(Vector3d(1, 0, 0), Vector3d(1, -1, 0)));
  CHECK_FALSE(overlap(Vector3d(-1, 0, 0), Vector3d(0, -1, 0)));
  CHECK_FALSE(overlap(Vector3d(-1, 0, 0), Vector3d(-1, -1, 0)));
  // Not coplanar: a side from v lies in the other's plane, inside its corner or outside it.
  CHECK(overlap(Vector3d(1, 1, 0), Vector3d(0, 0, 1)));
  CHECK_FALSE(overlap(Vector3d(-1, -1, 0), Vector3d(0, 0, 1)));
  // Piercing: the other triangle passes through this one away from v; or touches its far edge.
  CHECK(overlap(Vector3d(1, 1, 1), Vector3d(1, 1, -1)));
  CHECK(overlap(Vector3d(1, 1, 0.5), Vector3d(3, 3, -1)));
  // A side from v in this plane and into this corner overlaps near v, however far it reaches.
  CHECK(overlap(Vector3d(1, std::nextafter(1.0, 2.0), 0), Vector3d(2, 2, 2)));
  // Crossing this plane along the side v p1, or along a direction 1e-17 outside the corner.
  CHECK(overlap(Vector3d(1, 0, 1), Vector3d(1, 0, -1)));
  CHECK_FALSE(overlap(Vector3d(1, -1e-17, 1), Vector3d(1, -1e-17, -1)));
}

TEST_CASE("intersection: triangles_overlap_beyond_vertex equals the wedge circuits, random corners") {
  // Coordinates in 0..3: coplanar corners, collinear sides and coincident corner positions (two
  // ids at one place) are frequent.
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int64_t> coordinate(0, 3);
  auto random_point = [&]() { return IntPoint{coordinate(rng), coordinate(rng), coordinate(rng)}; };
  auto degenerate = [](const IntPoint& a, const IntPoint& b, const IntPoint& c) {
    return is_zero(cross(sub(b, a), sub(c, a)));
  };
  int hits = 0, trials = 0;
  while (trials < 40000) {
    const IntPoint v = random_point(), p1 = random_point(), p2 = random_point();
    const IntPoint q1 = random_point(), q2 = random_point();
    if (degenerate(v, p1, p2) || degenerate(v, q1, q2)) continue;
    ++trials;
    const bool expected = wedges_meet(v, p1, p2, q1, q2);
    hits += expected;
    const bool got = triangles_overlap_beyond_vertex(to_vector(v), to_vector(p1), to_vector(p2),
                                                     to_vector(q1), to_vector(q2));
    if (got != expected) {
      INFO("v " << v[0] << v[1] << v[2] << " p " << p1[0] << p1[1] << p1[2] << " " << p2[0] << p2[1] << p2[2]
                << " q " << q1[0] << q1[1] << q1[2] << " " << q2[0] << q2[1] << q2[2]);
      REQUIRE(got == expected);
    }
  }
  MESSAGE(hits << " of " << trials << " corner pairs overlap beyond their vertex");
  CHECK(hits > 2000);
  CHECK(hits < 38000);
}

TEST_SUITE_END();

// Tests of surface input (issue 21): read_triangle_surface and its STL and PLY readers, and
// checked_closed_surface. The corpus in tests/data/meshes/surfaces/ (written by
// scripts/make_test_surfaces.py) holds one closed box in seven encodings, which must all read to
// the same arrays, and one file per refusal, whose exact one-line message is asserted; smaller
// cases are written inline. The self-intersection search is compared with its O(n^2) reference
// on random triangle soups, and the IPC triMeshes are surveyed: which are accepted and why the
// others are refused (confirmed independently by docs/experiments/issue21_surface_check.py).
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/obj_reader.hpp"
#include "engine/mesh/self_intersection.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/mesh/surface_check.hpp"
#include "engine/mesh/surface_reader.hpp"
#include "tests/engine/mesh/closed_surfaces.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"
#include "tests/test_data.hpp"

#include <tbb/global_control.h>

namespace fs = std::filesystem;
using namespace nexdyn;
using nexdyn::test::mesh_error_of;

namespace {

const fs::path kSurfaces = fs::path(NEXDYN_SOURCE_DIR) / "tests" / "data" / "meshes" / "surfaces";

std::string stl_error(const std::string& bytes) {
  return mesh_error_of([&] { parse_stl(bytes, "in.stl"); });
}
std::string ply_error(const std::string& bytes) {
  return mesh_error_of([&] { parse_ply(bytes, "in.ply"); });
}
std::string check_error(TriangleSurface surface) {
  return mesh_error_of([&] { checked_closed_surface(std::move(surface), "in"); });
}

// The message of reading and checking `path`, without its "<path>: " prefix, which it must have,
// and on one line.
std::string refusal_of(const fs::path& path) {
  const std::string message =
      mesh_error_of([&] { checked_closed_surface(read_triangle_surface(path), path.string()); });
  CHECK(message.find('\n') == std::string::npos);
  const std::string prefix = path.string() + ": ";
  REQUIRE(message.substr(0, prefix.size()) == prefix);
  return message.substr(prefix.size());
}

// A little-endian binary STL: an 80-byte header and the triangles' corners (9 floats each).
std::string binary_stl(const std::string& header, const std::vector<std::vector<float>>& triangles) {
  std::string bytes = header;
  bytes.resize(80, ' ');
  const auto count = static_cast<uint32_t>(triangles.size());
  bytes.append(reinterpret_cast<const char*>(&count), 4);  // the test machine is little-endian
  for (const auto& corners : triangles) {
    const float normal[3] = {0, 0, 1};
    bytes.append(reinterpret_cast<const char*>(normal), 12);
    bytes.append(reinterpret_cast<const char*>(corners.data()), 36);
    bytes.append(2, '\0');
  }
  return bytes;
}

TriangleSurface cube() { return read_triangle_surface(kSurfaces / "cube.obj"); }

}  // namespace

TEST_SUITE_BEGIN("mesh");

TEST_CASE("read_triangle_surface: the box in every format reads to the same surface, volume 0.125") {
  const TriangleSurface reference = cube();
  REQUIRE(reference.num_vertices() == 8);
  REQUIRE(reference.num_triangles() == 12);
  for (const char* file : {"cube.obj", "cube_ascii.stl", "cube_binary.stl", "cube_binary_solid_header.stl",
                           "cube_ascii.ply", "cube_binary_le.ply", "cube_binary_be.ply"}) {
    INFO(file);
    const TriangleSurface surface = read_triangle_surface(kSurfaces / file);
    CHECK(surface.num_vertices() == 8);
    CHECK(surface.num_triangles() == 12);
    CHECK(surface.positions == reference.positions);
    CHECK(surface.triangles == reference.triangles);
    CHECK(enclosed_volume(surface) == 0.125);
    const TriangleSurface checked = checked_closed_surface(surface, file);
    CHECK(checked.positions == surface.positions);
    CHECK(checked.triangles == surface.triangles);
  }
}

TEST_CASE("checked_closed_surface: each refused file gives its one-line message") {
  const std::map<std::string, std::string> expected = {
      {"open_box.obj", "not closed, edge 1-2 is used by triangle 1 only (ids 1-based)"},
      {"nonmanifold_edge.obj", "not manifold, edge 6-7 is shared by 4 triangles: 3, 8, 14, 18 (ids 1-based)"},
      {"nonmanifold_vertex.obj",
       "not manifold, vertex 1 joins 2 separate fans of triangles, e.g. triangles 1 and 5 (ids 1-based)"},
      {"flipped_triangle.obj",
       "not consistently oriented, triangles 1 and 7 both traverse edge 2->3 (ids 1-based)"},
      {"self_intersecting.obj", "self-intersecting, triangles 3 and 18 intersect (ids 1-based)"},
      {"inverted.obj", "inverted, enclosed volume -0.125 m^3 <= 0: the normals point inward"},
      {"degenerate_triangle.ply",
       "degenerate (zero-area) triangle, triangle 13 of vertices 1 2 9 (ids 1-based)"},
      {"truncated_binary.stl",
       "binary STL of 12 triangles should have 84 + 50 * 12 = 684 bytes, but has 674 "
       "(truncated, or not an STL file)"},
      {"bad_header.ply", "line 6: unknown property type \"floot\""},
  };
  for (const auto& entry : expected) {  // not a structured binding: INFO captures it (clang 14)
    INFO(entry.first);
    CHECK(refusal_of(kSurfaces / entry.first) == entry.second);
  }
}

TEST_CASE("parse_stl: ASCII in any case, several solids, corners welded in order of first occurrence") {
  const std::string text =
      "solid first\n"
      "FACET NORMAL 0 0 1\n OUTER LOOP\n  VERTEX 0 0 0\n  VERTEX 1 0 0\n  VERTEX 0 1 0\n ENDLOOP\nENDFACET\n"
      "endsolid first\n"
      "solid second\r\n"
      "facet normal nan 0 0\r\n outer loop\r\n  vertex 1 0 0\r\n  vertex +1 1 0\r\n  vertex -0 1 -0.0\r\n"
      " endloop\r\nendfacet\r\n"
      "endsolid\r\n";
  const TriangleSurface surface = parse_stl(text, "in.stl");
  CHECK(surface.positions == std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
  CHECK(surface.triangles == std::vector<int32_t>{0, 1, 2, 1, 3, 2});
}

TEST_CASE("parse_stl: binary, told from ASCII by its size, welded") {
  const std::vector<std::vector<float>> triangles = {{0, 0, 0, 1, 0, 0, 0, 1, 0},
                                                     {1, 0, 0, 1, 1, 0, 0, 1, 0}};
  for (const std::string header : {"made by a binary writer", "solid but binary", "   SOLID too"}) {
    const TriangleSurface surface = parse_stl(binary_stl(header, triangles), "in.stl");
    CHECK(surface.positions == std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
    CHECK(surface.triangles == std::vector<int32_t>{0, 1, 2, 1, 3, 2});
  }
}

TEST_CASE("parse_stl: each rejection names the file and the line or the triangle") {
  const std::string head = "solid t\nfacet normal 0 0 1\nouter loop\n";
  const std::string corners = "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n";
  CHECK(stl_error(head + "vertex 0 0 0\nvertex 1 0 0\nendloop\n") ==
        "in.stl: line 6: expected \"vertex\", got \"endloop\"");
  CHECK(stl_error(head + "vertex 0 nan 0\n") == "in.stl: line 4: expected a finite number, got \"nan\"");
  CHECK(stl_error(head + "vertex 0 1e999 0\n") == "in.stl: line 4: expected a finite number, got \"1e999\"");
  CHECK(stl_error(head + "vertex 0 0\nvertex 1 0 0\n") ==
        "in.stl: line 5: expected a finite number, got \"vertex\"");
  CHECK(stl_error(head + "vertex 0 0\n") == "in.stl: line 5: expected a number, got the end of the file");
  CHECK(stl_error(head + corners + "endloop\nendfacet\n") ==
        "in.stl: line 9: expected \"facet\" or \"endsolid\", got the end of the file");
  CHECK(stl_error(head + corners + "endloop\n") ==
        "in.stl: line 8: expected \"endfacet\", got the end of the file");
  CHECK(stl_error("solid t\nfacet normal 0 x 1\n") == "in.stl: line 2: expected a number, got \"x\"");
  CHECK(stl_error("solid t\nfacet\n") == "in.stl: line 3: expected \"normal\", got the end of the file");
  CHECK(stl_error("solid t\nendsolid t\n") == "in.stl: no triangles (\"facet\" blocks)");
  CHECK(stl_error("solid t\nendsolid t\nfacet\n") == "in.stl: line 3: expected \"solid\", got \"facet\"");
  CHECK(
      stl_error("") ==
      "in.stl: not an STL file: 0 bytes, too short for a binary STL (84 at least), and no ASCII \"solid\" at "
      "the start");
  const std::string one = binary_stl("b", {{0, 0, 0, 1, 0, 0, 0, 1, 0}});
  CHECK(stl_error(one.substr(0, 130)) ==
        "in.stl: binary STL of 1 triangles should have 84 + 50 * 1 = 134 bytes, but has 130 (truncated, or "
        "not an "
        "STL file)");
  CHECK(stl_error(binary_stl("b", {})) == "in.stl: no triangles (binary STL with a triangle count of 0)");
  const float nan = std::nanf("");
  CHECK(stl_error(binary_stl("b", {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 1, 0, 0, 0, nan, 0}})) ==
        "in.stl: triangle 2 of 2: corner 3 has a non-finite coordinate");
  // A "solid" header on a binary file of the wrong size, with its NUL bytes, is a binary file.
  CHECK(stl_error(binary_stl("solid x", {{0, 0, 0, 1, 0, 0, 0, 1, 0}}) + "extra") ==
        "in.stl: binary STL of 1 triangles should have 84 + 50 * 1 = 134 bytes, but has 139 (truncated, or "
        "not an "
        "STL file)");
}

TEST_CASE("parse_ply: ASCII polygons fan-triangulated, elements in any order, unneeded values skipped") {
  const std::string text =
      "ply\r\nformat ascii 1.0\r\ncomment faces first\r\nobj_info nothing\r\n"
      "element face 2\r\nproperty uchar flag\r\nproperty list uint8 int32 vertex_index\r\n"
      "property list uchar float texcoord\r\n"
      "element vertex 5\r\nproperty double z\r\nproperty float x\r\nproperty short y\r\n"
      "element nothing 3\r\n"
      "end_header\r\n"
      "1 5 0 1 2 3 4 2 0.5 0.5\r\n"
      "\r\n"
      "0 3 4 3 0 0\r\n"
      "0 0 0\r\n1 1 0\r\n2 1 1\r\n3 0 1\r\n4 -1 +1\r\n";
  const TriangleSurface surface = parse_ply(text, "in.ply");
  CHECK(surface.positions == std::vector<double>{0, 0, 0, 1, 0, 1, 1, 1, 2, 0, 1, 3, -1, 1, 4});
  CHECK(surface.triangles == std::vector<int32_t>{0, 1, 2, 0, 2, 3, 0, 3, 4, 4, 3, 0});
}

TEST_CASE("parse_ply: binary of both byte orders, every integer type for lists") {
  auto put = [](std::string& bytes, auto value, bool big) {
    char raw[sizeof value];
    std::memcpy(raw, &value, sizeof value);
    if (big) std::reverse(raw, raw + sizeof value);
    bytes.append(raw, sizeof value);
  };
  for (const bool big : {false, true}) {
    for (const char* count_type : {"char", "uchar", "short", "ushort", "int", "uint"}) {
      std::string bytes = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                          " 1.0\nelement vertex 3\nproperty float x\nproperty double y\nproperty int8 z\n"
                          "element face 1\nproperty list " +
                          count_type + " " + count_type +
                          " vertex_indices\n"
                          "end_header\n";
      const double ys[3] = {0, 0, 1};
      for (int v = 0; v < 3; ++v) {
        put(bytes, float(v == 1), big);
        put(bytes, ys[v], big);
        put(bytes, int8_t(-v), big);
      }
      auto put_index = [&](int value) {
        const std::string type = count_type;
        if (type == "char")
          put(bytes, int8_t(value), big);
        else if (type == "uchar")
          put(bytes, uint8_t(value), big);
        else if (type == "short")
          put(bytes, int16_t(value), big);
        else if (type == "ushort")
          put(bytes, uint16_t(value), big);
        else if (type == "int")
          put(bytes, int32_t(value), big);
        else
          put(bytes, uint32_t(value), big);
      };
      for (int value : {3, 0, 1, 2}) put_index(value);
      INFO(big << " " << count_type);
      const TriangleSurface surface = parse_ply(bytes, "in.ply");
      CHECK(surface.positions == std::vector<double>{0, 0, 0, 1, 0, -1, 0, 1, -2});
      CHECK(surface.triangles == std::vector<int32_t>{0, 1, 2});
      // Cut anywhere in the body, the file is refused as ending inside an element.
      const std::size_t body = bytes.find("end_header\n") + 11;
      // (or, while the vertices' fixed bytes cannot fit, as declaring more than the file holds).
      for (std::size_t cut = body; cut < bytes.size(); cut += 3) {
        const std::string error = ply_error(bytes.substr(0, cut));
        CHECK((error.find("the file ends inside it") != std::string::npos ||
               error.find("bytes after the header can hold") != std::string::npos));
      }
      CHECK(ply_error(bytes + "xyz") == "in.ply: 3 bytes after the last element the header declares");
    }
  }
}

TEST_CASE("parse_ply: each rejection names the file and the line or the element") {
  const std::string head = "ply\nformat ascii 1.0\n";
  const std::string xyz = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  const std::string faces = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const std::string vertices = "0 0 0\n1 0 0\n0 1 0\n";
  const std::string good = head + xyz + faces + vertices;
  REQUIRE(parse_ply(good + "3 0 1 2\n", "in.ply").num_triangles() == 1);
  CHECK(ply_error("plx\n") == "in.ply: not a PLY file (its first line is not \"ply\")");
  CHECK(ply_error("ply\nformat binary 1.0\n") ==
        "in.ply: line 2: unknown format \"binary\" (ascii, binary_little_endian or binary_big_endian)");
  CHECK(ply_error("ply\nformat ascii 2.0\n") == "in.ply: line 2: unsupported PLY version \"2.0\" (1.0 only)");
  CHECK(ply_error("ply\nelement vertex 3\n") == "in.ply: line 2: \"element\" before the \"format\" line");
  CHECK(ply_error(head + "property float x\n") == "in.ply: line 3: \"property\" before any \"element\"");
  CHECK(ply_error(head + "element vertex -1\n") ==
        "in.ply: line 3: expected \"element <name> <count>\" with a count of 0 or more, got \"element vertex "
        "-1\"");
  CHECK(ply_error(head + xyz + "element face 1\nproperty list float int vertex_indices\n") ==
        "in.ply: line 8: a list's count type must be an integer type, got \"float\"");
  CHECK(ply_error(head + "element vertex 3\nproperty floot x\n") ==
        "in.ply: line 4: unknown property type \"floot\"");
  CHECK(ply_error(head + "element vertex 3\nproperty float\n") ==
        "in.ply: line 4: expected \"property <type> <name>\" or \"property list <count type> <item type> "
        "<name>\", "
        "got \"property float\"");
  CHECK(ply_error(head + "bogus line\n") == "in.ply: line 3: unknown header line \"bogus line\"");
  CHECK(ply_error(head + xyz) == "in.ply: the header has no \"end_header\" line");
  CHECK(ply_error("ply\nend_header\n") == "in.ply: the header has no \"format\" line");
  CHECK(ply_error(head + "element vertex 3\nproperty float x\nproperty float y\n" + faces) ==
        "in.ply: line 3: element \"vertex\" has no scalar property \"z\"");
  CHECK(ply_error(head + xyz + "element face 1\nproperty list uchar float vertex_indices\nend_header\n") ==
        "in.ply: line 7: element \"face\" has no list of integers \"vertex_indices\" (or \"vertex_index\")");
  CHECK(ply_error(head + xyz + "end_header\n" + vertices) ==
        "in.ply: no triangles (no \"face\" element, or 0 faces)");
  CHECK(ply_error(head + "element face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n") ==
        "in.ply: no \"vertex\" element in the header");
  CHECK(
      ply_error(head + "element vertex 1000000\nproperty float x\nproperty float y\nproperty float z\n" +
                faces + vertices + "3 0 1 2\n") ==
      "in.ply: line 3: element \"vertex\" declares 1000000 elements, more than the 26 bytes after the header "
      "can hold");
  CHECK(ply_error(head + xyz + faces + "0 0 0\n1 0\n0 1 0\n3 0 1 2\n") ==
        "in.ply: line 11: vertex 2 of 3: fewer values on the line than its properties declare");
  CHECK(ply_error(head + xyz + faces + "0 0 0 7\n1 0 0\n0 1 0\n3 0 1 2\n") ==
        "in.ply: line 10: vertex 1 of 3: more values on the line than its properties declare, from \"7\"");
  CHECK(ply_error(head + xyz + faces + "0 nan 0\n1 0 0\n0 1 0\n3 0 1 2\n") ==
        "in.ply: line 10: vertex 1 of 3: coordinate y is not a finite number");
  CHECK(ply_error(head + xyz + faces + "0 1e999 0\n1 0 0\n0 1 0\n3 0 1 2\n") ==
        "in.ply: line 10: vertex 1 of 3: coordinate y is not a finite number");
  CHECK(ply_error(head + xyz + faces + "0 x 0\n1 0 0\n0 1 0\n3 0 1 2\n") ==
        "in.ply: line 10: vertex 1 of 3: expected a number, got \"x\"");
  CHECK(ply_error(good + "3 0 1 3\n") ==
        "in.ply: line 13: face 1 of 1: vertex index 3 is out of range (3 vertices, indices from 0)");
  CHECK(ply_error(good + "3 0 1 -1\n") ==
        "in.ply: line 13: face 1 of 1: vertex index -1 is out of range (3 vertices, indices from 0)");
  CHECK(ply_error(good + "2 0 1\n") ==
        "in.ply: line 13: face 1 of 1: a face needs at least 3 vertices, this one has 2");
  CHECK(ply_error(good + "300 0 1 2\n") ==
        "in.ply: line 13: face 1 of 1: expected an integer of type uchar, got \"300\"");
  CHECK(ply_error(good + "3 0 1 2.0\n") ==
        "in.ply: line 13: face 1 of 1: expected an integer of type int, got \"2.0\"");
  CHECK(ply_error(good) == "in.ply: line 13: face 1 of 1: the file ends before it");
  CHECK(ply_error(good + "3 0 1 2\n3 0 1 2\n") ==
        "in.ply: line 14: data after the last element the header declares");
  CHECK(ply_error(head + xyz + "element face 1\nproperty list char int vertex_indices\nend_header\n" +
                  vertices + "-1 0 1 2\n") == "in.ply: line 13: face 1 of 1: a list of -1 items");
  // Names from the file are quoted with control bytes as '?': the message stays one printable line.
  CHECK(ply_error(head + "element e\x01" "d 1\nproperty int k\n" + xyz + faces + "x\n" + vertices +
                  "3 0 1 2\n") == "in.ply: line 12: e?d 1 of 1: expected an integer of type int, got \"x\"");
}

TEST_CASE("read_triangle_surface: the extension picks the reader in any case, and others are named") {
  const fs::path dir = test::temp_dir("surface_input");
  fs::copy_file(kSurfaces / "cube_binary.stl", dir / "CUBE.Stl");
  CHECK(read_triangle_surface(dir / "CUBE.Stl").triangles == cube().triangles);
  const std::string off = (dir / "cube.off").string();
  CHECK(mesh_error_of([&] { read_triangle_surface(off); }) ==
        off + ": unknown surface mesh format (extension \".off\"; supported: .obj, .stl, .ply)");
  const std::string bare = (dir / "cube").string();
  CHECK(mesh_error_of([&] { read_triangle_surface(bare); }) ==
        bare + ": unknown surface mesh format (no extension; supported: .obj, .stl, .ply)");
  const std::string missing = (dir / "missing.ply").string();
  CHECK(mesh_error_of([&] { read_triangle_surface(missing); }) ==
        missing + ": cannot open mesh file (no such file)");
  fs::remove_all(dir);
}

TEST_CASE("checked_closed_surface: unused vertices are dropped and the others keep their order") {
  const TriangleSurface box = cube();
  // Two unused vertices, before and among the used ones.
  TriangleSurface padded;
  padded.positions = {9, 9, 9};
  for (int v = 0; v < 8; ++v) {
    padded.positions.insert(padded.positions.end(), &box.positions[3 * v], &box.positions[3 * v + 3]);
    if (v == 4) padded.positions.insert(padded.positions.end(), {7, 7, 7});
  }
  for (int32_t v : box.triangles) padded.triangles.push_back(v + 1 + (v > 4));
  const TriangleSurface checked = checked_closed_surface(padded, "in");
  CHECK(checked.positions == box.positions);
  CHECK(checked.triangles == box.triangles);
}

TEST_CASE("checked_closed_surface: arrays that are no surface, empty and duplicate triangles") {
  TriangleSurface box = cube();
  TriangleSurface bad = box;
  bad.positions.push_back(1);
  CHECK(check_error(bad) == "in: positions hold 25 numbers, not a multiple of 3");
  bad = box;
  bad.triangles.push_back(1);
  CHECK(check_error(bad) == "in: triangles hold 37 vertex ids, not a multiple of 3");
  bad = box;
  bad.triangles[7] = 8;
  CHECK(check_error(bad) ==
        "in: vertex id out of range, triangle 3 has 0-based id 8 and there are 8 vertices");
  bad = box;
  bad.positions[4] = std::nan("");
  CHECK(check_error(bad) == "in: non-finite position, vertex 2 (ids 1-based)");
  CHECK(check_error({}) == "in: empty surface, no triangles");
  bad = box;
  bad.triangles.insert(bad.triangles.end(), {box.triangles[5], box.triangles[4], box.triangles[3]});
  CHECK(check_error(bad) ==
        "in: duplicate triangles, triangle 13 repeats triangle 2, vertices 1 3 4 (ids 1-based)");
  bad = box;
  bad.triangles[4] = bad.triangles[3];
  CHECK(check_error(bad) ==
        "in: degenerate (zero-area) triangle, triangle 2 of vertices 1 1 4 (ids 1-based)");
}

TEST_CASE("checked_closed_surface: a pleated fan, two corners overlapping at their shared vertex") {
  // Around vertex 1 (the origin) four triangles in the plane z = 0 turn through 405 degrees, so
  // the first and third overlap between 0 and 45 degrees; a cone to (0, 0, -2) closes it. Closed,
  // manifold and consistently wound, it is refused only by the geometric test.
  TriangleSurface pleat;
  pleat.positions = {0, 0, 0, 2, 0, 0, -2, 2, 0, 0, -2, 0, 2, 2, 0, 0, 0, -2};
  pleat.triangles = {0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1, 5, 2, 1, 5, 3, 2, 5, 4, 3, 5, 1, 4};
  CHECK(check_error(pleat) ==
        "in: self-intersecting, triangles 1 and 3 overlap beyond their shared vertex 1 "
        "(ids 1-based)");
}

TEST_CASE("self_intersections: the box pairs find what the O(n^2) loop finds, on random soups") {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> unit(0.0, 1.0), offset(-0.08, 0.08);
  std::uniform_int_distribution<int> small(0, 3);
  int64_t total_pairs = 0;
  int soups_with_pairs = 0;
  for (int soup = 0; soup < 60; ++soup) {
    TriangleSurface s;
    const int kind = soup % 3;
    if (kind == 0) {
      // Free triangles of size ~0.1 in a unit box: crossings, no shared vertices.
      for (int t = 0; t < 300; ++t) {
        const double c[3] = {unit(rng), unit(rng), unit(rng)};
        for (int k = 0; k < 9; ++k) s.positions.push_back(c[k % 3] + offset(rng));
        for (int k = 0; k < 3; ++k) s.triangles.push_back(3 * t + k);
      }
    } else {
      // Triangles on a shared pool of vertices: random points (kind 1) or points of a 4^3 grid
      // (kind 2), where coplanar, collinear and touching pairs abound.
      const int pool = kind == 1 ? 60 : 40;
      for (int v = 0; v < pool; ++v)
        for (int k = 0; k < 3; ++k) s.positions.push_back(kind == 1 ? unit(rng) : small(rng));
      std::uniform_int_distribution<int32_t> id(0, pool - 1);
      while (s.num_triangles() < 150) {
        const int32_t a = id(rng), b = id(rng), c = id(rng);
        auto p = [&](int32_t v) { return Eigen::Vector3d::Map(&s.positions[3 * v]); };
        if (a == b || b == c || c == a || is_degenerate_triangle(p(a), p(b), p(c))) continue;
        s.triangles.insert(s.triangles.end(), {a, b, c});
      }
    }
    const auto expected = self_intersections_brute_force(s.positions, s.triangles);
    CHECK(self_intersections(s.positions, s.triangles) == expected);
    const auto first = first_self_intersection(s.positions, s.triangles);
    CHECK(first.has_value() == !expected.empty());
    if (first && !expected.empty()) CHECK(*first == expected.front());
    total_pairs += static_cast<int64_t>(expected.size());
    soups_with_pairs += !expected.empty();
  }
  MESSAGE(std::string("random soups: ")
          << total_pairs << " colliding pairs in " << soups_with_pairs << " of 60 soups");
  CHECK(soups_with_pairs == 60);
}

TEST_CASE("self_intersections: the same pairs and the same first pair on any thread count") {
  // Two grid boxes pushed into each other: thousands of crossing pairs spread over many chunks.
  TriangleSurface a = test::grid_box(24), b = test::grid_box(24);
  for (std::size_t k = 0; k < b.positions.size(); k += 3) b.positions[k] += 0.5;
  for (int32_t& v : b.triangles) v += a.num_vertices();
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  a.triangles.insert(a.triangles.end(), b.triangles.begin(), b.triangles.end());
  std::vector<TrianglePair> pairs[2];
  std::optional<TrianglePair> first[2];
  for (int threads : {1, 2}) {
    test::ThreadsScope limit(threads);
    pairs[threads - 1] = self_intersections(a.positions, a.triangles);
    first[threads - 1] = first_self_intersection(a.positions, a.triangles);
  }
  CHECK(pairs[0].size() > 1000);
  CHECK(pairs[0] == pairs[1]);
  REQUIRE(first[0].has_value());
  CHECK(first[0] == first[1]);
  CHECK(*first[0] == pairs[0].front());
}

TEST_CASE("checked_closed_surface: spheres and grid boxes made in code, turned or not, are accepted") {
  const TriangleSurface sphere = test::icosphere(4);
  CHECK(checked_closed_surface(sphere, "sphere").num_triangles() == 5120);
  CHECK(enclosed_volume(sphere) > 0.99 * 4.0 / 3.0 * std::numbers::pi);
  CHECK(enclosed_volume(sphere) < 4.0 / 3.0 * std::numbers::pi);
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  for (const TriangleSurface& box : {test::grid_box(12), test::grid_box(12, turn)}) {
    const TriangleSurface checked = checked_closed_surface(box, "box");
    CHECK(checked.num_triangles() == 12 * 12 * 12);
    CHECK(enclosed_volume(checked) == test::relative(1.0, 1e-12));
  }
}

TEST_CASE("checked_closed_surface: the boundaries of the IPC tet meshes are accepted, with their volume") {
  // Real closed surfaces: a scanned shape and a thin mat whose flat faces make every pair of
  // neighbours exactly coplanar (the exact fallback of the orientation signs at work).
  for (const char* file : {"Armadillo13K.msh", "mat40x40.msh", "torus.msh"}) {
    INFO(file);
    const TetMesh mesh = read_msh(test::ipc_tet_mesh(file));
    const SurfaceMesh boundary = extract_surface(mesh);
    TriangleSurface surface{mesh.positions, boundary.triangles};
    const auto start = std::chrono::steady_clock::now();
    const TriangleSurface checked = checked_closed_surface(surface, file);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    MESSAGE(std::string(file) << ": " << checked.num_triangles() << " triangles checked in " << seconds * 1e3
                              << " ms");
    CHECK(checked.num_vertices() == static_cast<int32_t>(boundary.vertices.size()));
    CHECK(enclosed_volume(checked) == test::relative(mesh_volume(mesh), 1e-10));
  }
}

TEST_CASE("checked_closed_surface: the IPC triMeshes, which are closed and which are refused and why") {
  // Verdicts confirmed by docs/experiments/issue21_surface_check.py (exact integer geometry):
  // hole.obj is closed only to the eye: vertex 35 sits in the middle of the edge 6-11 (a T-junction),
  // so edges 11-35 and 35-6 have one triangle each, and 6-11 one on the other side. plane.obj is a
  // single open square (an obstacle surface, not a body).
  const std::map<std::string, std::string> expected = {
      {"cube.obj", "accepted, 8 vertices, 12 triangles, volume 1"},
      {"cylinder.obj", "accepted, 152 vertices, 300 triangles, volume 0.0300002"},
      {"erleben/cliff.obj", "accepted, 8 vertices, 12 triangles, volume 1.58333"},
      {"erleben/crack.obj", "accepted, 20 vertices, 36 triangles, volume 7"},
      {"erleben/hole.obj", "refused: not closed, edge 11-35 is used by triangle 8 only (ids 1-based)"},
      {"erleben/internal_edges.obj", "accepted, 14 vertices, 24 triangles, volume 4"},
      {"erleben/spike.obj", "accepted, 5 vertices, 6 triangles, volume 1"},
      {"erleben/wedge.obj", "accepted, 6 vertices, 8 triangles, volume 3"},
      {"plane.obj", "refused: not closed, edge 3-2 is used by triangle 1 only (ids 1-based)"},
      {"sphere1K.obj", "accepted, 1239 vertices, 2474 triangles, volume 0.518477"},
  };
  // The IPC triMeshes the scenes use are in scenes/meshes/, the others in tests/data/ipc-meshes/.
  const fs::path root = test::test_data("ipc-meshes/triMeshes");
  REQUIRE(fs::is_directory(root));
  std::vector<std::string> names = {"cube.obj", "cylinder.obj", "sphere1K.obj"};
  for (const auto& entry : fs::recursive_directory_iterator(root))
    if (entry.is_regular_file() && entry.path().extension() == ".obj")
      names.push_back(fs::relative(entry.path(), root).generic_string());
  std::sort(names.begin(), names.end());
  std::map<std::string, std::string> found;
  for (const std::string& name : names) {
    const fs::path path = test::ipc_tri_mesh(name);
    const TriangleSurface surface = read_triangle_surface(path);
    const auto start = std::chrono::steady_clock::now();
    std::string verdict;
    try {
      const TriangleSurface checked = checked_closed_surface(surface, name);
      char volume[32];
      std::snprintf(volume, sizeof volume, "%.6g", enclosed_volume(checked));
      verdict = "accepted, " + std::to_string(checked.num_vertices()) + " vertices, " +
                std::to_string(checked.num_triangles()) + " triangles, volume " + volume;
    } catch (const MeshError& error) {
      verdict = "refused: " + std::string(error.what()).substr(name.size() + 2);
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    MESSAGE(name << ": " << verdict << " (" << seconds * 1e3 << " ms)");
    found[name] = verdict;
  }
  CHECK(found == expected);
}

TEST_SUITE_END();

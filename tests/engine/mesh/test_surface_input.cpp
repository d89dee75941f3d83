// Tests of surface input (issue 21): read_triangle_surface and its STL and PLY readers. The
// corpus in tests/data/meshes/surfaces/ (written by scripts/make_test_surfaces.py) holds one
// closed box in seven encodings, which must all read to the same arrays; smaller cases, and the
// exact message of each rejection, are written inline.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "engine/mesh/surface_reader.hpp"
#include "tests/engine/test_support.hpp"

namespace fs = std::filesystem;
using namespace nexdyn;

namespace {

const fs::path kSurfaces = fs::path(NEXDYN_SOURCE_DIR) / "tests" / "data" / "meshes" / "surfaces";

template <typename Fn>
std::string mesh_error_of(Fn&& fn) {
  try {
    fn();
  } catch (const MeshError& error) {
    return error.what();
  }
  return "<no MeshError thrown>";
}

std::string stl_error(const std::string& bytes) {
  return mesh_error_of([&] { parse_stl(bytes, "in.stl"); });
}
std::string ply_error(const std::string& bytes) {
  return mesh_error_of([&] { parse_ply(bytes, "in.ply"); });
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

TEST_CASE("read_triangle_surface: the box in every format reads to the same surface") {
  const TriangleSurface reference = cube();
  REQUIRE(reference.num_vertices() == 8);
  REQUIRE(reference.num_triangles() == 12);
  for (const char* file : {"cube.obj", "cube_ascii.stl", "cube_binary.stl", "cube_binary_solid_header.stl",
                           "cube_ascii.ply", "cube_binary_le.ply", "cube_binary_be.ply"}) {
    INFO(file);
    const TriangleSurface surface = read_triangle_surface(kSurfaces / file);
    CHECK(surface.positions == reference.positions);
    CHECK(surface.triangles == reference.triangles);
  }
}

TEST_CASE("read_triangle_surface: malformed files are refused with one line naming the file") {
  const std::string truncated = (kSurfaces / "truncated_binary.stl").string();
  CHECK(mesh_error_of([&] { read_triangle_surface(truncated); }) ==
        truncated + ": binary STL of 12 triangles should have 84 + 50 * 12 = 684 bytes, but has 674 "
                    "(truncated, or not an STL file)");
  const std::string bad_header = (kSurfaces / "bad_header.ply").string();
  CHECK(mesh_error_of([&] { read_triangle_surface(bad_header); }) ==
        bad_header + ": line 6: unknown property type \"floot\"");
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

TEST_SUITE_END();

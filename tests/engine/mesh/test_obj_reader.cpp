// Tests of parse_obj: what it keeps of a valid file (fan triangulation, relative indices, ignored
// statements), and the exact message of each rejection.
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "engine/mesh/obj_reader.hpp"

using namespace nexdyn;

namespace {

std::string obj_error_of(const std::string& text) {
  try {
    parse_obj(text, "in.obj");
  } catch (const MeshError& error) {
    return error.what();
  }
  return "";
}

}  // namespace

TEST_SUITE_BEGIN("mesh");

TEST_CASE("parse_obj: vertices, fan triangulation, relative and slashed indices") {
  const std::string text =
      "# a unit square and a triangle\r\n"
      "o square\n"
      "v 0 0 0\n"
      "v 1 0 0 1.0\n"
      "vt 0.5 0.5\n"
      "v 1 1 0\n"
      "v 0 1 0\n"
      "\n"
      "f 1/1 2//1 3/1/1 4\n"
      "v 0 0 1\n"
      "f -5 -4 -1\n";
  const ObjMesh mesh = parse_obj(text, "in.obj");
  CHECK(mesh.positions == std::vector<double>{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1});
  CHECK(mesh.triangles == std::vector<int32_t>{0, 1, 2, 0, 2, 3, 0, 1, 4});
}

TEST_CASE("parse_obj: each rejection names the file, the line and the culprit") {
  const std::string square = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
  const std::string so_far = " (3 vertices defined so far)";
  CHECK(obj_error_of(square + "f 1 2 9\n") == "in.obj: line 4: bad vertex reference \"9\"" + so_far);
  CHECK(obj_error_of(square + "f 1 2 0\n") == "in.obj: line 4: bad vertex reference \"0\"" + so_far);
  CHECK(obj_error_of(square + "f 1 2 -4\n") == "in.obj: line 4: bad vertex reference \"-4\"" + so_far);
  CHECK(obj_error_of(square + "f 1 2 3/1/1/1\n") == "in.obj: line 4: bad vertex reference \"3/1/1/1\"" + so_far);
  CHECK(obj_error_of(square + "f 1 2 +3\n") == "in.obj: line 4: bad vertex reference \"+3\"" + so_far);
  CHECK(obj_error_of(square + "f 1 2\r\n") == "in.obj: line 4: a face needs at least 3 vertices, got \"f 1 2\"");
  CHECK(obj_error_of("v 0 0\n") == "in.obj: line 1: expected \"v x y z\", got \"v 0 0\"");
  CHECK(obj_error_of("\nv 0 1e999 0\n") == "in.obj: line 2: expected a finite number, got \"1e999\"");
  CHECK(obj_error_of("v 0 1e-999 0\n") == "in.obj: line 1: expected a finite number, got \"1e-999\"");
  CHECK(obj_error_of("v 0 +1 0\n") == "in.obj: line 1: expected a finite number, got \"+1\"");
  CHECK(obj_error_of("v 0 nan 0\n") == "in.obj: line 1: expected a finite number, got \"nan\"");
  CHECK(obj_error_of("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n") ==
        "in.obj: line 4: degenerate (zero-area) triangle 1 2 3");
  CHECK(obj_error_of(square) == "in.obj: no faces (\"f\" lines)");
  CHECK(obj_error_of("") == "in.obj: no faces (\"f\" lines)");
  // Quoted text: control bytes as '?', UTF-8 kept, cut at 40 characters.
  CHECK(obj_error_of("v 0 \x01\xc3\xa9 0\n") == "in.obj: line 1: expected a finite number, got \"?\xc3\xa9\"");
  CHECK(obj_error_of("v 0 " + std::string(50, '7') + "x 0\n") ==
        "in.obj: line 1: expected a finite number, got \"" + std::string(40, '7') + "...\"");
}

TEST_SUITE_END();

// The nasty-input corpus (tests/data/nasty/) as regression tests: every file there is refused by
// its reader with one line that names the file and the key or line at fault, and with the fault
// itself. The same files seed the fuzzers (scripts/fuzz.sh); fuzz_crash_* files are inputs the
// fuzzers found, kept once fixed. Inputs the older reader tests already cover (NaN and inf
// nodes, truncated sections, repeated and unknown vertices, zero-volume tets, unknown keys, bad
// OBJ indices: test_msh_reader.cpp, test_scene.cpp) are not repeated here.
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/obj_reader.hpp"
#include "engine/scene/scene.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

const fs::path kNasty = fs::path(NEXDYN_SOURCE_DIR) / "tests" / "data" / "nasty";

// The message of the exception the right reader throws for `file` ("<accepted>" when none).
std::string rejection_of(const fs::path& file) {
  try {
    const std::string extension = file.extension().string();
    if (extension == ".msh") read_msh(file);
    else if (extension == ".obj") read_obj(file);
    else load_scene(file);
  } catch (const MeshError& e) {
    return e.what();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "<accepted>";
}

struct Nasty {
  const char* file;
  std::vector<std::string> fault;  // every part must be in the message, after the file name
};

// Each file with what its message must say. Scenes name the key path; meshes the line.
const std::vector<Nasty> kCorpus = {
    // .msh: counts no file of this size can hold, and numbers beyond int64.
    {"huge_node_count_v22.msh", {"line 5: ", "$Nodes declares 99999999999 nodes", "bytes remain"}},
    {"huge_block_count.msh", {"line 17: ", "$Elements declares 1000000000 element blocks", "bytes remain"}},
    {"count_out_of_range.msh", {"line 12: ", "element count '99999999999999999999999' is out of range"}},
    {"truncated_header.msh", {"line 2: ", "unexpected end of file inside $MeshFormat", "truncated"}},
    {"negative_node_tag.msh", {"line 8: ", "node tag must not be negative, found -3", "after node 2"}},
    // Found by fuzz_msh: an unterminated section whose name holds 120 tabs; the name is quoted,
    // cut, its control bytes shown as '?'.
    {"fuzz_crash_tab_section.msh", {"line 14: ", "unexpected end of file inside '$Mes????", "...'", "truncated"}},
    // .obj: non-finite coordinates, a cut-off line, indices beyond int64 and at INT64_MIN.
    {"nan_vertex.obj", {"line 3: ", "expected a finite number, got \"nan\""}},
    {"inf_vertex.obj", {"line 3: ", "expected a finite number, got \"1e999\""}},
    {"truncated.obj", {"line 3: ", "expected \"v x y z\", got \"v 0 1\""}},
    {"huge_index.obj", {"line 4: ", "bad vertex reference \"99999999999999999999\" (3 vertices defined so far)"}},
    {"most_negative_index.obj", {"line 4: ", "bad vertex reference \"-9223372036854775808\""}},
    // Scenes: JSON that is not JSON.
    {"number_overflow.json", {"not valid JSON", "number overflow", "1e999"}},
    {"nan_literal.json", {"not valid JSON", "syntax error"}},
    {"truncated.json", {"not valid JSON", "unexpected end of input"}},
    // Scenes: sizes past the limits (SceneLimits), refused before anything is allocated.
    {"huge_box.json",
     {"bodies[0].box.cells: ", "[1000,1000,1000] cells", "6000000000 tets",
      "1003003001 vertices, more than the limit of 20000000"}},
    {"huge_array.json",
     {"bodies[0].array.count: ", "1000000 copies of a 1331-vertex, 6000-tet body",
      "1331000000 vertices, more than the limit of 20000000"}},
    {"overflowing_array_count.json",
     {"bodies[0].array.count: ", "more than 1,000,000 copies", "[4611686018427387904,4,1]"}},
    // Scenes: integers an int cannot hold, and one past int64.
    {"int_overflow_iterations.json", {"solver.max_iterations: ", "from 1 to 2147483647", "4294967297"}},
    {"wrapping_substep_halvings.json", {"solver.substep_halvings: ", "at most 16", "4294967296"}},
    {"uint64_steps.json", {"time.steps: ", "below 2^63", "18446744073709551615"}},
    // Scenes: placements that overflow positions or flatten tets (a unit box at x = 1e308 is flat
    // in double: its vertices round to the same x; a box of 1e-300 m has volume 0 in double).
    {"overflowing_scale.json", {"bodies[0]: ", "vertex 0 of the mesh is not finite once placed"}},
    {"far_translate.json", {"bodies[0]: ", "copy (0, 0, 0) of the array: tet 0 of the mesh is degenerate once placed"}},
    {"flat_scale.json", {"bodies[0]: ", "tet 0 of the mesh is degenerate once placed (volume 1.6666666666666667e-301)"}},
    {"tiny_box.json", {"bodies[0]: ", "tet 0 of the mesh is degenerate once placed (volume 0.0)"}},
    // Scenes: what could make a message long or break it over lines.
    {"deep_nesting.json", {"gravity: ", "expected an array of 3 numbers, got [[[[", "..."}},
    {"control_character_key.json", {"\"gra\\nvity\": ", "unknown key"}},
    {"long_mesh_name.json", {"bodies[0].mesh: ", "mesh file not found", "aaaa"}},
    {"dot_dot_name.json", {"name: ", "not \".\" or \"..\"", "got \"..\""}},
    // Scenes: wrong type, broken meshes seen through the scene (the mesh file and line named).
    {"bodies_not_an_array.json", {"bodies: ", "expected a non-empty array of bodies"}},
    {"zero_volume_body.json", {"bodies[0].mesh: ", "bad_zero_volume.msh: line 15: element 3 is a degenerate tet"}},
    {"nan_body.json", {"bodies[0].mesh: ", "bad_nan.msh: line 8: node 17 has a non-finite coordinate (nan)"}},
    {"nan_obstacle.json", {"obstacles[0].mesh: ", "nan_vertex.obj: line 3: expected a finite number"}},
    // Scenes: surfaces that intersect at the start (contact is on).
    {"self_intersecting_body.json", {"bodies[0] touches or intersects itself at the start"}},
    {"obstacle_through_body.json", {"bodies[0] and obstacles[0] touch or intersect at the start"}},
};

bool starts_with(const std::string& text, const std::string& prefix) { return text.rfind(prefix, 0) == 0; }

}  // namespace

TEST_SUITE_BEGIN("nasty");

TEST_CASE("nasty inputs: every file is refused with one line naming the file and the fault") {
  for (const Nasty& nasty : kCorpus) {
    const fs::path file = kNasty / nasty.file;
    REQUIRE(fs::exists(file));
    const std::string message = rejection_of(file);
    INFO("file: ", nasty.file, "\nmessage: ", message);
    CHECK(starts_with(message, file.string() + ": "));
    // One line: no line break, and no other control character (a tab from the file, say).
    CHECK(std::none_of(message.begin(), message.end(), [](char c) { return static_cast<unsigned char>(c) < 32; }));
    CHECK(message.size() < 1024);
    for (const std::string& part : nasty.fault) CHECK(message.find(part) != std::string::npos);
  }
}

TEST_CASE("nasty inputs: the table lists every file of the corpus that is not a helper") {
  // Helpers are the meshes the nasty scenes use; every other file must have its expectation.
  const std::vector<std::string> helpers = {"self_intersecting.msh", "quad_through_origin.obj"};
  for (const auto& entry : fs::directory_iterator(kNasty)) {
    const std::string name = entry.path().filename().string();
    const bool listed = std::any_of(kCorpus.begin(), kCorpus.end(), [&](const Nasty& n) { return name == n.file; });
    const bool helper = std::find(helpers.begin(), helpers.end(), name) != helpers.end();
    INFO("file: ", name);
    CHECK(listed != helper);
  }
}

TEST_CASE("nasty inputs: the helper meshes are valid on their own, so the scenes test the start check") {
  // Two interpenetrating tets with no shared vertex: a fine mesh, an impossible contact start.
  CHECK(read_msh(kNasty / "self_intersecting.msh").num_tets() == 2);
  CHECK(read_obj(kNasty / "quad_through_origin.obj").triangles.size() == 6);
  // Without contact the self-intersecting body loads: the refusal above is the start check's.
  const fs::path dir = test::temp_dir("nasty_no_contact");
  fs::copy_file(kNasty / "self_intersecting.msh", dir / "self_intersecting.msh");
  const std::string json = R"({ "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [{ "mesh": "self_intersecting.msh", "material": "m" }] })";
  CHECK(load_scene(test::write_text(dir / "scene.json", json)).model.num_tets == 2);
}

TEST_CASE("nasty inputs: a plane normal of huge components is normalised, not refused as zero") {
  // |[1e308, 1e308, 0]| overflows to inf; the loader divides by the largest component first.
  const Scene scene = test::scene_from_json(R"({ "contact": {},
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [{ "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" }],
    "obstacles": [{ "plane": { "point": [0, -10, 0], "normal": [1e308, 1e308, 0] } }] })",
                                            "huge_normal");
  REQUIRE(scene.model.obstacle_planes.size() == 1);
  CHECK(scene.model.obstacle_planes[0].normal.isApprox(Eigen::Vector3d(1, 1, 0).normalized()));
}

TEST_CASE("scene limits: a body past max_vertices, max_tets or max_materials is refused by key") {
  const fs::path dir = test::temp_dir("nasty_limits");
  const std::string materials = R"("materials": { "a": { "model": "linear", "youngs": 1e5, "poisson": 0.3, "density": 1 },
                                                  "b": { "model": "linear", "youngs": 1e5, "poisson": 0.3, "density": 1 } })";
  const fs::path file = test::write_text(dir / "scene.json", "{ " + materials + R"(,
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "b", "translate": [3, 0, 0],
                  "array": { "count": [2, 1, 1], "spacing": [3, 0, 0] } } ] })");
  auto error = [&](const SceneLimits& limits) {
    try {
      load_scene(file, limits);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("<accepted>");
  };
  // Box 0: 27 vertices, 48 tets; box 1: 2 copies of 8 vertices, 6 tets. 43 and 60 in all.
  CHECK(error({43, 60, 2}) == "<accepted>");
  CHECK(error({42, 60, 2}) == file.string() + ": bodies[1].array.count: 2 copies of a 8-vertex, 6-tet body would "
                                              "give the scene 43 vertices, more than the limit of 42");
  CHECK(error({43, 59, 2}) == file.string() + ": bodies[1].array.count: 2 copies of a 8-vertex, 6-tet body would "
                                              "give the scene 60 tets, more than the limit of 59");
  CHECK(error({26, 60, 2}) == file.string() + ": bodies[0].box.cells: a box of [2,2,2] cells (27 vertices, 48 tets) "
                                              "would give the scene 27 vertices, more than the limit of 26");
  CHECK(error({43, 60, 1}) == file.string() + ": materials: 2 materials, more than the limit of 1");
}

TEST_CASE("nasty inputs: nexdyn check and run exit 1 with one line and write nothing") {
  for (const char* name : {"huge_box.json", "number_overflow.json", "self_intersecting_body.json", "overflowing_scale.json",
                           "control_character_key.json"}) {
    const fs::path file = kNasty / name;
    const fs::path out = test::temp_dir("nasty_cli") / "out";
    for (const std::string& command : {"check " + file.string(), "run " + file.string() + " --out " + out.string()}) {
      const test::CommandResult result = test::run_cli(command);
      INFO("command: ", command, "\noutput: ", result.output);
      CHECK(result.exit_code == 1);
      CHECK(starts_with(result.output, "nexdyn: error: " + file.string() + ": "));
      CHECK(std::count(result.output.begin(), result.output.end(), '\n') == 1);
      CHECK(result.output.back() == '\n');
      CHECK_FALSE(fs::exists(out));
    }
  }
}

TEST_SUITE_END();

// Tests of read_msh / parse_msh: every IPC mesh in the repository against the independently
// computed mesh_info.jsonl and against its own $Surface block, hand-written 2.2 and 4.1 files
// exercising the format's corners, and one bad file per error class.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/surface.hpp"
#include "tests/engine/mesh/mesh_checks.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/test_data.hpp"

namespace fs = std::filesystem;
using namespace nexdyn;
using nexdyn::test::mesh_error_of;
using nexdyn::test::count_components;
using nexdyn::test::count_non_positive_tets;
using nexdyn::test::divergence_volume;
using nexdyn::test::edges_of;
using nexdyn::test::euler_characteristic;
using nexdyn::test::is_closed_and_consistently_wound;

namespace {

const fs::path kTestMeshes = fs::path(NEXDYN_SOURCE_DIR) / "tests" / "data" / "meshes";

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

using Triangle = std::array<int32_t, 3>;

// Triangles rotated to start at their smallest id (keeps winding), then sorted: equal sets of
// equally wound triangles give equal vectors.
std::vector<Triangle> canonical_triangles(const std::vector<int32_t>& flat) {
  std::vector<Triangle> out;
  for (std::size_t i = 0; i < flat.size(); i += 3) {
    Triangle t = {flat[i], flat[i + 1], flat[i + 2]};
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    out.push_back(t);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// IPC's nonstandard "$Surface / n / i j k (1-based) / $EndSurface" block, which read_msh skips.
std::vector<int32_t> ipc_surface_block(const fs::path& path) {
  std::istringstream in(read_text(path));
  std::string word;
  while (in >> word && word != "$Surface") {
  }
  std::vector<int32_t> flat;
  int64_t count = 0;
  in >> count;
  for (int64_t i = 0; i < 3 * count; ++i) {
    int32_t tag = 0;
    in >> tag;
    flat.push_back(tag - 1);
  }
  return flat;
}

// Every IPC tet mesh in the repository: those of the shipped scenes and those kept for the tests.
std::vector<fs::path> ipc_msh_files() {
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(test::test_data("ipc-meshes/tetMeshes")))
    if (entry.is_regular_file() && entry.path().extension() == ".msh") files.push_back(entry.path());
  for (const auto& entry : fs::directory_iterator(fs::path(NEXDYN_SOURCE_DIR) / "scenes" / "meshes"))
    if (entry.is_regular_file() && entry.path().extension() == ".msh") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

TEST_SUITE_BEGIN("mesh");

TEST_CASE("read_msh: every IPC mesh in the repository matches mesh_info.jsonl") {
  std::map<std::string, nlohmann::json> info;
  {
    std::ifstream in(test::test_data("ipc-meshes/mesh_info.jsonl"));
    REQUIRE(in);
    std::string line;
    while (std::getline(in, line))
      if (!line.empty()) {
        const auto record = nlohmann::json::parse(line);
        info[record.at("file").get<std::string>()] = record;
      }
  }
  const std::vector<fs::path> files = ipc_msh_files();
  REQUIRE(!files.empty());
  CHECK(files.size() == info.size());

  for (const fs::path& file : files) {
    INFO("mesh: ", file.string());
    REQUIRE(info.count(file.filename().string()) == 1);
    const nlohmann::json& expected = info.at(file.filename().string());
    MshReadStats stats;
    const TetMesh mesh = read_msh(file, &stats);
    CHECK(stats.flipped_tets == expected.at("neg_vol_tets").get<int64_t>());
    CHECK(stats.unused_nodes == expected.at("unused_nodes").get<int64_t>());
    const SurfaceMesh surface = extract_surface(mesh);

    CHECK(mesh.num_vertices() == expected.at("nodes").get<int64_t>());
    CHECK(mesh.num_tets() == expected.at("tets").get<int64_t>());
    CHECK(surface.num_triangles() == expected.at("boundary_tris").get<int64_t>());
    const double total_volume = expected.at("total_vol").get<double>();
    CHECK(mesh_volume(mesh) == test::relative(total_volume, 1e-9));
    CHECK(count_non_positive_tets(mesh) == 0);
    CHECK(find_degenerate_tet(mesh) == -1);

    // Closed, consistently wound, wound outward (divergence theorem gives +volume, not -volume).
    CHECK(is_closed_and_consistently_wound(surface));
    CHECK(divergence_volume(mesh, surface) == test::relative(total_volume, 1e-9));
    CHECK(surface.edges == edges_of(surface));
    CHECK(std::is_sorted(surface.vertices.begin(), surface.vertices.end()));
    CHECK(std::adjacent_find(surface.vertices.begin(), surface.vertices.end()) ==
          surface.vertices.end());

    // Every shipped mesh is genus 0 per component (chi = 2 each) except the torus (chi = 0).
    const int components = count_components(surface, mesh.num_vertices());
    CHECK(components >= 1);
    if (file.filename() == "torus.msh") {
      CHECK(components == 1);
      CHECK(euler_characteristic(surface) == 0);
    } else {
      CHECK(euler_characteristic(surface) == 2 * components);
    }

    // IPC wrote its own outward boundary into $Surface: with tags 1..N and no unused nodes our
    // ids are tag - 1, so the two surfaces must agree triangle for triangle, winding included.
    if (expected.at("tags_1toN").get<bool>() && expected.at("unused_nodes").get<int64_t>() == 0)
      CHECK(canonical_triangles(surface.triangles) == canonical_triangles(ipc_surface_block(file)));
  }
}

TEST_CASE("read_msh: hand-written 2.2 file with mixed elements and unused nodes and sparse tags") {
  // mixed_v22.msh: $PhysicalNames and $NodeData sections, a point, a line and two triangles
  // among the elements, nodes 7 and 41 unused, tags 10 20 35 40 50 out of order with gaps, and
  // tet 5 negatively oriented.
  MshReadStats stats;
  const TetMesh mesh = read_msh(kTestMeshes / "mixed_v22.msh", &stats);
  CHECK(stats.flipped_tets == 1);
  CHECK(stats.skipped_elements == 4);
  CHECK(stats.unused_nodes == 2);
  // Used tags in order 10, 20, 35, 40, 50 become ids 0..4.
  const std::vector<double> expected_positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  CHECK(mesh.positions == expected_positions);
  REQUIRE(mesh.num_tets() == 2);
  CHECK(std::vector<int32_t>(mesh.tets.begin(), mesh.tets.begin() + 4) ==
        std::vector<int32_t>{0, 1, 2, 3});
  // Tet 5 was (20 40 35 50) = (1 3 2 4), negative; its last two vertices are swapped.
  CHECK(std::vector<int32_t>(mesh.tets.begin() + 4, mesh.tets.end()) ==
        std::vector<int32_t>{1, 3, 4, 2});
  CHECK(signed_tet_volume(mesh, 0) == test::relative(1.0 / 6.0, 1e-12));
  CHECK(signed_tet_volume(mesh, 1) == test::relative(1.0 / 3.0, 1e-12));
  const SurfaceMesh surface = extract_surface(mesh);
  CHECK(surface.num_triangles() == 6);
  CHECK(is_closed_and_consistently_wound(surface));
  CHECK(divergence_volume(mesh, surface) == test::relative(0.5, 1e-12));
}

namespace {

// The same two-tet mesh as mixed_v22.msh, in 4.1: an $Entities section, a parametric node
// block on a surface (u v after x y z), nodes split over three blocks with tags out of order,
// a triangle block between two tet blocks, CR LF line endings in the middle.
constexpr const char* kMixedV41 =
    "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
    "$Entities\n0 0 1 1\n1 0 0 0 1 1 1 0 0\n1 0 0 0 1 1 1 1 1 0\n$EndEntities\n"
    "$Nodes\n3 7 7 50\n"
    "2 1 1 2\n35\n10\n0 1 0 0.5 0.25\n0 0 0 0 0\n"
    "3 1 0 3\n40\n7\n41\n0 0 1\n9 9 9\n5 5 5\n"
    "0 1 0 2\r\n50\r\n20\r\n1 1 1\r\n1 0 0\r\n"
    "$EndNodes\n"
    "$Elements\n3 4 1 6\n"
    "3 1 4 1\n4 10 20 35 40\n"
    "2 1 2 2\n1 10 20 35\n2 20 35 40\n"
    "3 1 4 1\n5 20 40 35 50\n"
    "$EndElements\n"
    "$Surface\n1\n1 2 3\n$EndSurface\n";

}  // namespace

TEST_CASE("parse_msh: 4.1 with entities and parametric and split node blocks equals the 2.2 file") {
  const TetMesh from_v22 = read_msh(kTestMeshes / "mixed_v22.msh");
  const TetMesh from_v41 = parse_msh(kMixedV41, "mixed_v41");
  CHECK(from_v41.positions == from_v22.positions);
  CHECK(from_v41.tets == from_v22.tets);
}

TEST_CASE("parse_msh: huge sparse node tags and unordered tags") {
  // Tags near 1e15 cannot use a direct table; the binary-search path must give the same ids.
  const std::string text =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n"
      "1000000000000004 0 0 1\n"
      "1000000000000001 0 0 0\n"
      "3 7 7 7\n"
      "1000000000000003 0 1 0\n"
      "1000000000000002 1 0 0\n"
      "$EndNodes\n$Elements\n1\n"
      "9 4 0 1000000000000001 1000000000000002 1000000000000003 1000000000000004\n"
      "$EndElements\n";
  const TetMesh mesh = parse_msh(text, "sparse");
  CHECK(mesh.positions == std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1});
  CHECK(mesh.tets == std::vector<int32_t>{0, 1, 2, 3});
}

TEST_CASE("parse_msh: a tiny but well-shaped tet is not degenerate") {
  // Volume ~1.7e-34: a threshold relative to the tet's own size keeps it, an absolute one would
  // not.
  const std::string text =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n"
      "1 1000 1000 1000\n2 1000.00000000001 1000 1000\n3 1000 1000.00000000001 1000\n"
      "4 1000 1000 1000.00000000001\n$EndNodes\n$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";
  const TetMesh mesh = parse_msh(text, "tiny");
  REQUIRE(mesh.num_tets() == 1);
  CHECK(signed_tet_volume(mesh, 0) > 0.0);
}

TEST_CASE("read_msh: bad files throw MeshError naming the file and the culprit") {
  struct BadCase {
    const char* file;
    std::vector<std::string> expected;  // substrings of the message besides the file name
  };
  const std::vector<BadCase> cases = {
      {"bad_truncated.msh", {"line 22", "end of file", "$Elements", "element 5"}},
      {"bad_nan.msh", {"line 8", "node 17", "nan"}},
      {"bad_inf.msh", {"line 14", "node 4", "-inf"}},
      {"bad_unknown_node.msh", {"line 15", "element 7", "unknown node tag 99"}},
      {"bad_repeated_vertex.msh", {"line 20", "element 12", "node 2 twice"}},
      {"bad_zero_volume.msh", {"line 15", "element 3", "degenerate"}},
      {"bad_binary.msh", {"binary .msh not supported"}},
      {"bad_no_tets.msh", {"no linear tetrahedra", "skipped 1 element(s) of other types"}},
      {"bad_huge_count.msh", {"line 5", "1000000000000", "bytes remain"}},
  };
  for (const BadCase& bad : cases) {
    const fs::path path = kTestMeshes / bad.file;
    REQUIRE(fs::exists(path));
    const std::string message = mesh_error_of([&] { read_msh(path); });
    INFO("message: ", message);
    CHECK(contains(message, path.string()));
    for (const std::string& part : bad.expected) CHECK(contains(message, part));
  }
}

TEST_CASE("read_msh: a missing file is a MeshError naming it") {
  const fs::path path = kTestMeshes / "does_not_exist.msh";
  const std::string message = mesh_error_of([&] { read_msh(path); });
  CHECK(contains(message, path.string()));
  CHECK(contains(message, "no such file"));
  CHECK(contains(mesh_error_of([&] { read_msh(kTestMeshes); }), "not a regular file"));
}

TEST_CASE("parse_msh: malformed text is rejected with the line and the culprit") {
  const std::string header22 = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
  const std::string elements22 = "$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";
  const std::string nodes22 = "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";
  struct BadText {
    std::string text;
    std::vector<std::string> expected;
  };
  const std::vector<BadText> cases = {
      // Header and version problems.
      {"$MeshFormat\n4 0 8\n$EndMeshFormat\n" + nodes22 + elements22,
       {"line 2", "'4'", "not supported"}},
      {"$MeshFormat\n3.0 0 8\n$EndMeshFormat\n", {"'3.0'", "not supported"}},
      {nodes22 + elements22, {"line 1", "before $MeshFormat"}},
      {"hello\n", {"no $MeshFormat"}},
      // Counts that disagree with the content.
      {header22 + "$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n" + elements22,
       {"line 10", "$Nodes ends early", "after node 4"}},
      {header22 + "$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n" + elements22,
       {"line 9", "expected $EndNodes", "more entries"}},
      // Bad numbers.
      {header22 + "$Nodes\n4\n1 0 0 0\n2 1e999 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n" + elements22,
       {"line 7", "node 2", "inf"}},
      {header22 + "$Nodes\n4\n1 0 0 0\n2 1,5 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n" + elements22,
       {"line 7", "'1,5'", "node 2"}},
      {header22 + "$Nodes\n4\n1 0 0 0\n2 1 0 0 7\n3 0 1 0\n4 0 0 1\n$EndNodes\n" + elements22,
       {"line 7", "'7'", "node 2"}},
      {header22 + "$Nodes\n4\n1 0 0 0\n2 1 0 0\n2 0 1 0\n4 0 0 1\n$EndNodes\n" + elements22,
       {"node tag 2 is defined twice"}},
      // An unterminated unknown section is a truncated file, not a silent success.
      {header22 + nodes22 + elements22 + "$Surface\n1\n1 2 3\n",
       {"$Surface", "opened at line 15", "truncated"}},
      // Only quadratic tets: say why nothing was kept.
      {header22 + "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n"
                  "$Elements\n1\n1 11 0 1 2 3 4 1 2 3 4 1 2\n$EndElements\n",
       {"type 11"}},
  };
  for (const BadText& bad : cases) {
    const std::string message = mesh_error_of([&] { parse_msh(bad.text, "inline.msh"); });
    INFO("text:\n", bad.text, "\nmessage: ", message);
    CHECK(contains(message, "inline.msh: "));
    for (const std::string& part : bad.expected) CHECK(contains(message, part));
  }
}

TEST_SUITE_END();

// Wavefront .obj reader (what it accepts and rejects: obj_reader.hpp).
//
// The file is read into memory in one go and walked line by line, and each line word by word, with
// TextCursors (text_cursor.hpp): string_views, numbers parsed by std::from_chars (locale-free, no
// allocation). Text quoted in a message is cut to 40 characters with control bytes shown as '?',
// so that every message stays one short line whatever the file holds.
#include "engine/mesh/obj_reader.hpp"

#include "engine/mesh/mesh_file.hpp"
#include "engine/mesh/text_cursor.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

namespace nexdyn {
namespace {

// `text` in double quotes for a message: at most 40 characters, control bytes as '?'.
std::string quoted(std::string_view text) {
  std::string out = "\"";  // appended, not "\"" + excerpt(...): GCC 12 warns of a false -Wrestrict
  out += excerpt(text, HighBytes::kept);
  return out + "\"";
}

// Parses one OBJ face corner, "i", "i/t", "i//n" or "i/t/n", into a 0-based vertex id.
// Negative indices count back from the last vertex defined so far (-1 = the latest); positive
// ones must refer to a vertex already defined, as the OBJ format says. nullopt when malformed
// or out of range; the caller names the line.
std::optional<int32_t> obj_vertex_index(std::string_view corner, int64_t vertices_so_far) {
  auto parse = [](std::string_view text, int64_t& value) {
    return parse_integer(text, LeadingPlus::rejected, value) == NumberParse::ok;
  };
  // Split at '/': at most three parts; the texture and normal parts are checked, then ignored.
  std::string_view parts[3];
  int num_parts = 0;
  for (size_t start = 0;;) {
    if (num_parts == 3) return std::nullopt;
    const size_t slash = corner.find('/', start);
    parts[num_parts++] = corner.substr(start, slash == std::string_view::npos ? slash : slash - start);
    if (slash == std::string_view::npos) break;
    start = slash + 1;
  }
  int64_t ignored = 0;
  for (int p = 1; p < num_parts; ++p)
    if (!parts[p].empty() && !parse(parts[p], ignored)) return std::nullopt;
  int64_t index = 0;
  if (!parse(parts[0], index) || index == 0) return std::nullopt;
  // index > 0 here cannot overflow; index < 0 is at least INT64_MIN + 1, and vertices_so_far
  // is below 2^30, so the sum stays in range too.
  const int64_t id = index > 0 ? index - 1 : vertices_so_far + index;
  if (id < 0 || id >= vertices_so_far) return std::nullopt;
  return static_cast<int32_t>(id);
}

}  // namespace

bool is_degenerate_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double area = 0.5 * (b - a).cross(c - a).norm();
  const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  return area <= kDegenerateTriangleRelativeArea * longest * longest;
}

ObjMesh parse_obj(std::string_view text, std::string_view source_name) {
  ObjMesh mesh;
  TextCursor cursor(text, source_name);
  int64_t line_number = 0;
  auto fail = [&](const std::string& what) { cursor.fail_at(line_number, what); };
  std::vector<std::string_view> tokens;
  std::vector<int32_t> corners;
  while (!cursor.at_end()) {
    line_number = cursor.line();
    std::string_view line = cursor.read_line();
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);  // files written on Windows
    tokens.clear();
    TextCursor words(line, source_name);
    for (std::string_view word = words.next_word(); !word.empty(); word = words.next_word()) tokens.push_back(word);
    if (tokens.empty()) continue;
    if (tokens[0] == "v") {
      // x y z, optionally followed by w or by r g b vertex colours, which are ignored.
      if (tokens.size() < 4) fail("expected \"v x y z\", got " + quoted(line));
      for (size_t t = 1; t < tokens.size(); ++t) {
        double value = 0.0;
        if (parse_double(tokens[t], LeadingPlus::rejected, value) != NumberParse::ok || !std::isfinite(value))
          fail("expected a finite number, got " + quoted(tokens[t]));
        if (t <= 3) mesh.positions.push_back(value);
      }
      if (mesh.positions.size() / 3 > (size_t{1} << 30)) fail("more than 2^30 vertices");
    } else if (tokens[0] == "f") {
      if (tokens.size() < 4) fail("a face needs at least 3 vertices, got " + quoted(line));
      const int64_t defined = static_cast<int64_t>(mesh.positions.size() / 3);
      corners.clear();
      for (size_t t = 1; t < tokens.size(); ++t) {
        const auto id = obj_vertex_index(tokens[t], defined);
        if (!id) fail("bad vertex reference " + quoted(tokens[t]) + " (" + std::to_string(defined) +
                      " vertices defined so far)");
        corners.push_back(*id);
      }
      for (size_t k = 1; k + 1 < corners.size(); ++k) {
        const int32_t tri[3] = {corners[0], corners[k], corners[k + 1]};
        auto p = [&](int32_t id) { return Eigen::Vector3d::Map(&mesh.positions[3 * size_t(id)]); };
        if (is_degenerate_triangle(p(tri[0]), p(tri[1]), p(tri[2])))
          fail("degenerate (zero-area) triangle " + std::to_string(tri[0] + 1) + " " +
               std::to_string(tri[1] + 1) + " " + std::to_string(tri[2] + 1));
        mesh.triangles.insert(mesh.triangles.end(), tri, tri + 3);
      }
    }
  }
  if (mesh.triangles.empty()) cursor.fail_file("no faces (\"f\" lines)");
  return mesh;
}

ObjMesh read_obj(const std::filesystem::path& path) { return parse_obj(read_mesh_file(path), path.string()); }

}  // namespace nexdyn

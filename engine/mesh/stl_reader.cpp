// STL reader, ASCII and binary (what it accepts: surface_reader.hpp).
//
// Which of the two: a binary STL is an 80-byte header, a little-endian uint32 triangle count n and
// n records of 50 bytes, so its size is exactly 84 + 50 n. That equation is the test, because the
// obvious one, "an ASCII file starts with solid", is fooled by binary writers that put "solid ..."
// into the header. A text file passes it only by a coincidence of its bytes 80..83 with its length
// (for printable bytes n is above 5e8, a file of 25 GB). A file that fails it is ASCII if it starts
// with "solid" and holds no NUL byte (text never does; a truncated binary file nearly always does),
// and otherwise a binary file of the wrong size, which is what the message then says.
//
// Welding: STL repeats each corner's coordinates in every triangle that uses it, so the triangles
// only become a surface once equal corners are made one vertex. Corners are sorted by (x, y, z),
// equal ones grouped, and each group numbered by its first corner in file order: exact equality,
// no tolerance (a tolerance could merge distinct vertices of a fine mesh), and the numbering
// depends only on the file.
#include "engine/mesh/surface_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <string>

#include "engine/mesh/text_cursor.hpp"

namespace nexdyn {
namespace {

constexpr std::size_t kHeaderBytes = 80;
constexpr std::size_t kPrefixBytes = 84;  // header and triangle count
constexpr std::size_t kRecordBytes = 50;  // normal, 3 corners (12 floats), attribute (uint16)

uint32_t little_endian_u32(const char* bytes) {
  unsigned char b[4];
  std::memcpy(b, bytes, 4);
  return uint32_t{b[0]} | uint32_t{b[1]} << 8 | uint32_t{b[2]} << 16 | uint32_t{b[3]} << 24;
}

float little_endian_f32(const char* bytes) {
  const uint32_t bits = little_endian_u32(bytes);
  float value = 0.0f;
  std::memcpy(&value, &bits, 4);
  return value;
}

bool equals_ignoring_case(std::string_view word, std::string_view keyword) {
  if (word.size() != keyword.size()) return false;
  for (std::size_t i = 0; i < word.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(word[i])) != keyword[i]) return false;
  return true;
}

std::string quoted(std::string_view text) {
  std::string out = "\"";
  out += excerpt(text, HighBytes::replaced);
  return out + "\"";
}

// The corners (num_corners x 3) welded into vertices: `surface` gets one vertex per distinct
// position, numbered by first occurrence, and one id per corner (3 per triangle).
void weld_corners(const std::vector<double>& corners, TriangleSurface& surface,
                  std::string_view source_name) {
  const auto num_corners = static_cast<int32_t>(corners.size() / 3);
  std::vector<int32_t> order(static_cast<std::size_t>(num_corners));
  std::iota(order.begin(), order.end(), 0);
  auto position = [&](int32_t c) { return &corners[3 * static_cast<std::size_t>(c)]; };
  auto less = [&](int32_t a, int32_t b) {
    const double* p = position(a);
    const double* q = position(b);
    for (int k = 0; k < 3; ++k)
      if (p[k] != q[k]) return p[k] < q[k];
    return a < b;  // equal positions: file order, so a group starts with its first corner
  };
  std::sort(order.begin(), order.end(), less);
  // first[c]: the first corner (in file order) at corner c's position.
  std::vector<int32_t> first(static_cast<std::size_t>(num_corners));
  for (std::size_t k = 0; k < order.size();) {
    std::size_t end = k + 1;
    while (end < order.size() && std::equal(position(order[k]), position(order[k]) + 3, position(order[end])))
      ++end;
    for (std::size_t m = k; m < end; ++m) first[order[m]] = order[k];
    k = end;
  }
  std::vector<int32_t> vertex_of(static_cast<std::size_t>(num_corners), -1);
  surface.triangles.resize(static_cast<std::size_t>(num_corners));
  for (int32_t c = 0; c < num_corners; ++c) {
    if (first[c] == c) {
      vertex_of[c] = surface.num_vertices();
      surface.positions.insert(surface.positions.end(), position(c), position(c) + 3);
    }
    surface.triangles[c] = vertex_of[first[c]];
  }
  if (surface.num_vertices() > kMaxSurfaceVertices)
    throw MeshError(std::string(source_name) + ": more than " + std::to_string(kMaxSurfaceVertices) +
                    " vertices");
}

TriangleSurface parse_binary_stl(std::string_view bytes, std::string_view source_name) {
  const uint32_t count = little_endian_u32(bytes.data() + kHeaderBytes);
  const std::string name(source_name);
  if (count == 0) throw MeshError(name + ": no triangles (binary STL with a triangle count of 0)");
  if (count > kMaxSurfaceTriangles)
    throw MeshError(name + ": binary STL of " + std::to_string(count) + " triangles, more than " +
                    std::to_string(kMaxSurfaceTriangles));
  std::vector<double> corners;
  corners.reserve(9 * std::size_t{count});
  for (uint32_t t = 0; t < count; ++t) {
    const char* record = bytes.data() + kPrefixBytes + kRecordBytes * t;
    for (int k = 0; k < 9; ++k) {
      const float value = little_endian_f32(record + 12 + 4 * k);
      if (!std::isfinite(value))
        throw MeshError(name + ": triangle " + std::to_string(t + 1) + " of " + std::to_string(count) +
                        ": corner " + std::to_string(k / 3 + 1) + " has a non-finite coordinate");
      corners.push_back(value);
    }
  }
  TriangleSurface surface;
  weld_corners(corners, surface, source_name);
  return surface;
}

// The ASCII grammar, keywords in any case:
//   solid [name]  { facet normal nx ny nz  outer loop  vertex x y z (3 times)  endloop  endfacet }
//   endsolid [name]
// repeated for every solid of the file. Normals must be numbers but are otherwise ignored.
TriangleSurface parse_ascii_stl(std::string_view bytes, std::string_view source_name) {
  TextCursor cursor(bytes, source_name);
  int64_t line = 1;
  auto next = [&]() {
    cursor.skip_space();
    line = cursor.line();
    return cursor.read_word();
  };
  auto expect = [&](std::string_view keyword) {
    const std::string_view word = next();
    if (!equals_ignoring_case(word, keyword))
      cursor.fail_at(line, "expected \"" + std::string(keyword) + "\", got " +
                               (word.empty() ? std::string("the end of the file") : quoted(word)));
  };
  auto number = [&](bool must_be_finite) {
    const std::string_view word = next();
    double value = 0.0;
    if (word.empty()) cursor.fail_at(line, "expected a number, got the end of the file");
    // Normals are ignored, so any number will do for them, even one out of range.
    const NumberParse parsed = parse_double(word, LeadingPlus::accepted, value);
    if (parsed == NumberParse::malformed ||
        (must_be_finite && (parsed != NumberParse::ok || !std::isfinite(value))))
      cursor.fail_at(line, std::string("expected a ") + (must_be_finite ? "finite " : "") + "number, got " +
                               quoted(word));
    return value;
  };
  std::vector<double> corners;
  for (std::string_view word = next(); !word.empty(); word = next()) {
    if (!equals_ignoring_case(word, "solid")) cursor.fail_at(line, "expected \"solid\", got " + quoted(word));
    cursor.read_line();  // the solid's name
    for (word = next(); !equals_ignoring_case(word, "endsolid"); word = next()) {
      if (!equals_ignoring_case(word, "facet"))
        cursor.fail_at(line, "expected \"facet\" or \"endsolid\", got " +
                                 (word.empty() ? std::string("the end of the file") : quoted(word)));
      expect("normal");
      for (int k = 0; k < 3; ++k) number(false);
      expect("outer");
      expect("loop");
      for (int corner = 0; corner < 3; ++corner) {
        expect("vertex");
        for (int k = 0; k < 3; ++k) corners.push_back(number(true));
      }
      expect("endloop");
      expect("endfacet");
      if (corners.size() / 9 > static_cast<std::size_t>(kMaxSurfaceTriangles))
        cursor.fail_at(line, "more than " + std::to_string(kMaxSurfaceTriangles) + " triangles");
    }
    cursor.read_line();  // the name after endsolid
  }
  if (corners.empty()) cursor.fail_file("no triangles (\"facet\" blocks)");
  TriangleSurface surface;
  weld_corners(corners, surface, source_name);
  return surface;
}

bool starts_with_solid(std::string_view bytes) {
  std::size_t start = 0;
  while (start < bytes.size() && is_space(bytes[start])) ++start;
  return equals_ignoring_case(bytes.substr(start, 5), "solid");
}

}  // namespace

TriangleSurface parse_stl(std::string_view bytes, std::string_view source_name) {
  if (bytes.size() >= kPrefixBytes) {
    const uint64_t count = little_endian_u32(bytes.data() + kHeaderBytes);
    if (bytes.size() == kPrefixBytes + kRecordBytes * count) return parse_binary_stl(bytes, source_name);
  }
  if (starts_with_solid(bytes) && bytes.find('\0') == std::string_view::npos)
    return parse_ascii_stl(bytes, source_name);
  const std::string name(source_name);
  if (bytes.size() < kPrefixBytes)
    throw MeshError(name + ": not an STL file: " + std::to_string(bytes.size()) +
                    " bytes, too short for a binary STL (84 at least), and no ASCII \"solid\" at the start");
  const uint64_t count = little_endian_u32(bytes.data() + kHeaderBytes);
  throw MeshError(name + ": binary STL of " + std::to_string(count) + " triangles should have 84 + 50 * " +
                  std::to_string(count) + " = " + std::to_string(kPrefixBytes + kRecordBytes * count) +
                  " bytes, but has " + std::to_string(bytes.size()) + " (truncated, or not an STL file)");
}

}  // namespace nexdyn

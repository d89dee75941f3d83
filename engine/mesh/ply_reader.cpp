// PLY reader, ASCII and binary of either byte order (what it accepts: surface_reader.hpp).
//
// A PLY file is a text header that declares elements (a name and a count) and their properties
// (scalars or lists, each of one of eight numeric types), then the elements' values in the
// declared order: in ASCII one element per line, in binary packed with no padding. The reader
// walks the header into a list of Element records and then the body value by value through a
// BodyReader, which hides the encoding: every value of every element is read (and range-checked)
// even when it is thrown away, since in binary the only way past a value is to know its size, and
// in ASCII a wrong count of values on a line is the sign of a header that does not match.
//
// Memory: before the body is read, every element count is checked against the bytes left (a
// binary element needs its fixed bytes, an ASCII one at least a character and a separator per
// value), so a header that promises a billion vertices in a small file fails before allocating.
#include "engine/mesh/surface_reader.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>

#include "engine/mesh/text_cursor.hpp"

namespace nexdyn {
namespace {

enum class PlyType : uint8_t { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

struct TypeInfo {
  std::string_view name;   // the PLY 1.0 name
  std::string_view alias;  // the sized name many writers use instead
  PlyType type;
  int bytes;
  int64_t min, max;  // integer types: the range of values
};

constexpr TypeInfo kTypes[] = {
    {"char", "int8", PlyType::int8, 1, -128, 127},
    {"uchar", "uint8", PlyType::uint8, 1, 0, 255},
    {"short", "int16", PlyType::int16, 2, -32768, 32767},
    {"ushort", "uint16", PlyType::uint16, 2, 0, 65535},
    {"int", "int32", PlyType::int32, 4, INT32_MIN, INT32_MAX},
    {"uint", "uint32", PlyType::uint32, 4, 0, UINT32_MAX},
    {"float", "float32", PlyType::float32, 4, 0, 0},
    {"double", "float64", PlyType::float64, 8, 0, 0},
};

const TypeInfo& info(PlyType type) { return kTypes[static_cast<int>(type)]; }
bool is_integer(PlyType type) { return type != PlyType::float32 && type != PlyType::float64; }

std::optional<PlyType> type_named(std::string_view name) {
  for (const TypeInfo& t : kTypes)
    if (name == t.name || name == t.alias) return t.type;
  return std::nullopt;
}

std::string quoted(std::string_view text) {
  std::string out = "\"";
  out += excerpt(text, HighBytes::replaced);
  return out + "\"";
}

struct Property {
  std::string_view name;
  PlyType type = PlyType::float32;  // of the value, or of a list's items
  bool is_list = false;
  PlyType count_type = PlyType::uint8;  // lists only
};

struct Element {
  std::string_view name;
  int64_t count = 0;
  int64_t line = 0;  // of its header line, for messages
  std::vector<Property> properties;
};

enum class Format { ascii, little_endian, big_endian };

struct Header {
  Format format = Format::ascii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;  // first byte after the end_header line
  int64_t body_line = 0;        // and its line
};

// Whitespace-separated words of one header line.
std::vector<std::string_view> words_of(std::string_view line, std::string_view source_name) {
  std::vector<std::string_view> words;
  TextCursor cursor(line, source_name);
  for (std::string_view word = cursor.next_word(); !word.empty(); word = cursor.next_word())
    words.push_back(word);
  return words;
}

Header parse_header(std::string_view bytes, std::string_view source_name) {
  TextCursor cursor(bytes, source_name);
  auto next_line = [&]() {
    std::string_view line = cursor.read_line();
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    return line;
  };
  if (next_line() != "ply") cursor.fail_file("not a PLY file (its first line is not \"ply\")");
  Header header;
  bool has_format = false;
  for (;;) {
    if (cursor.at_end()) cursor.fail_file("the header has no \"end_header\" line");
    const int64_t line_number = cursor.line();
    const std::string_view line = next_line();
    auto fail = [&](const std::string& what) { cursor.fail_at(line_number, what); };
    const std::vector<std::string_view> words = words_of(line, source_name);
    if (words.empty() || words[0] == "comment" || words[0] == "obj_info") continue;
    const std::string_view key = words[0];
    if (key == "end_header") {
      if (words.size() != 1) fail("expected \"end_header\" alone, got " + quoted(line));
      break;
    }
    if (key == "format") {
      if (has_format) fail("a second \"format\" line");
      if (words.size() != 3)
        fail("expected \"format <ascii|binary_little_endian|binary_big_endian> 1.0\", got " + quoted(line));
      if (words[1] == "ascii")
        header.format = Format::ascii;
      else if (words[1] == "binary_little_endian")
        header.format = Format::little_endian;
      else if (words[1] == "binary_big_endian")
        header.format = Format::big_endian;
      else
        fail("unknown format " + quoted(words[1]) + " (ascii, binary_little_endian or binary_big_endian)");
      if (words[2] != "1.0") fail("unsupported PLY version " + quoted(words[2]) + " (1.0 only)");
      has_format = true;
    } else if (key == "element") {
      if (!has_format) fail("\"element\" before the \"format\" line");
      int64_t count = 0;
      if (words.size() != 3 || parse_integer(words[2], LeadingPlus::rejected, count) != NumberParse::ok ||
          count < 0)
        fail("expected \"element <name> <count>\" with a count of 0 or more, got " + quoted(line));
      header.elements.push_back({words[1], count, line_number, {}});
    } else if (key == "property") {
      if (header.elements.empty()) fail("\"property\" before any \"element\"");
      Property property;
      if (words.size() == 5 && words[1] == "list") {
        const auto count_type = type_named(words[2]), item_type = type_named(words[3]);
        if (!count_type) fail("unknown property type " + quoted(words[2]));
        if (!item_type) fail("unknown property type " + quoted(words[3]));
        if (!is_integer(*count_type))
          fail("a list's count type must be an integer type, got " + quoted(words[2]));
        property = {words[4], *item_type, true, *count_type};
      } else if (words.size() == 3 && words[1] != "list") {
        const auto type = type_named(words[1]);
        if (!type) fail("unknown property type " + quoted(words[1]));
        property = {words[2], *type, false, PlyType::uint8};
      } else {
        fail(
            "expected \"property <type> <name>\" or \"property list <count type> <item type> <name>\", got " +
            quoted(line));
      }
      header.elements.back().properties.push_back(property);
    } else {
      fail("unknown header line " + quoted(line));
    }
  }
  if (!has_format) cursor.fail_file("the header has no \"format\" line");
  header.body_offset = bytes.size() - cursor.remaining();
  header.body_line = cursor.line();
  return header;
}

// Reads the body's values one at a time, in either encoding, and words every failure with the
// element being read: "line 12: face 3 of 6: ..." (ASCII) or "face 3 of 6: ..." (binary).
class BodyReader {
 public:
  BodyReader(std::string_view bytes, const Header& header, std::string_view source_name)
      : bytes_(bytes),
        name_(source_name),
        format_(header.format),
        offset_(header.body_offset),
        text_(bytes.substr(header.body_offset), source_name),
        line_offset_(header.body_line - 1),
        words_(std::string_view(), source_name) {}

  // Starts element `index` (0-based) of `element`: in ASCII, its line (blank lines are skipped).
  void begin(const Element& element, int64_t index) {
    element_ = &element;
    index_ = index;
    if (format_ != Format::ascii) return;
    for (;;) {
      line_ = text_.line() + line_offset_;
      if (text_.at_end()) fail("the file ends before it");
      const std::string_view line = text_.read_line();
      if (!trim(line).empty()) {
        words_ = TextCursor(line, name_);
        return;
      }
    }
  }

  // Ends the element: in ASCII, its line must hold nothing more.
  void end() {
    if (format_ != Format::ascii) return;
    const std::string_view extra = words_.next_word();
    if (!extra.empty()) fail("more values on the line than its properties declare, from " + quoted(extra));
  }

  // A value of any type, as a double.
  double number(PlyType type) {
    if (is_integer(type)) return static_cast<double>(integer(type));
    if (format_ == Format::ascii) {
      const std::string_view word = next_word();
      double value = 0.0;
      const NumberParse parsed = parse_double(word, LeadingPlus::accepted, value);
      if (parsed == NumberParse::malformed) fail("expected a number, got " + quoted(word));
      return value;  // out of range: +-inf or 0, as strtod gives it; the caller checks what it keeps
    }
    const char* raw = take(info(type).bytes);
    if (type == PlyType::float32) return std::bit_cast<float>(decode<uint32_t>(raw));
    return std::bit_cast<double>(decode<uint64_t>(raw));
  }

  // A value of an integer type.
  int64_t integer(PlyType type) {
    if (format_ == Format::ascii) {
      const std::string_view word = next_word();
      int64_t value = 0;
      if (parse_integer(word, LeadingPlus::accepted, value) != NumberParse::ok || value < info(type).min ||
          value > info(type).max)
        fail("expected an integer of type " + std::string(info(type).name) + ", got " + quoted(word));
      return value;
    }
    const char* raw = take(info(type).bytes);
    switch (type) {
      case PlyType::int8:
        return static_cast<int8_t>(*raw);
      case PlyType::uint8:
        return static_cast<uint8_t>(*raw);
      case PlyType::int16:
        return static_cast<int16_t>(decode<uint16_t>(raw));
      case PlyType::uint16:
        return decode<uint16_t>(raw);
      case PlyType::int32:
        return static_cast<int32_t>(decode<uint32_t>(raw));
      default:
        return decode<uint32_t>(raw);
    }
  }

  // Skips `count` values of `type` (list items nobody needs).
  void skip(PlyType type, int64_t count) {
    if (format_ == Format::ascii) {
      for (int64_t k = 0; k < count; ++k) number(type);
      return;
    }
    if (count > static_cast<int64_t>(bytes_.size() - offset_) / info(type).bytes)
      fail("the file ends inside it");
    offset_ += static_cast<std::size_t>(count * info(type).bytes);
  }

  // After the last element: nothing may follow but whitespace (ASCII) or nothing at all (binary).
  void finish() {
    if (format_ == Format::ascii) {
      text_.skip_space();
      if (!text_.at_end())
        throw MeshError(std::string(name_) + ": line " + std::to_string(text_.line() + line_offset_) +
                        ": data after the last element the header declares");
    } else if (offset_ != bytes_.size()) {
      throw MeshError(std::string(name_) + ": " + std::to_string(bytes_.size() - offset_) +
                      " bytes after the last element the header declares");
    }
  }

  [[noreturn]] void fail(const std::string& what) const {
    std::string where = std::string(name_) + ": ";
    if (format_ == Format::ascii) where += "line " + std::to_string(line_) + ": ";
    throw MeshError(where + excerpt(element_->name, HighBytes::replaced) + " " + std::to_string(index_ + 1) +
                    " of " + std::to_string(element_->count) + ": " + what);
  }

 private:
  std::string_view next_word() {
    const std::string_view word = words_.next_word();
    if (word.empty()) fail("fewer values on the line than its properties declare");
    return word;
  }

  const char* take(int bytes) {
    if (bytes_.size() - offset_ < static_cast<std::size_t>(bytes)) fail("the file ends inside it");
    const char* raw = bytes_.data() + offset_;
    offset_ += static_cast<std::size_t>(bytes);
    return raw;
  }

  // An unsigned integer of the file's byte order.
  template <typename Unsigned>
  Unsigned decode(const char* raw) const {
    unsigned char b[sizeof(Unsigned)];
    std::memcpy(b, raw, sizeof(Unsigned));
    Unsigned value = 0;
    for (std::size_t k = 0; k < sizeof(Unsigned); ++k) {
      const std::size_t byte = format_ == Format::little_endian ? sizeof(Unsigned) - 1 - k : k;
      value = static_cast<Unsigned>((value << 8) | b[byte]);
    }
    return value;
  }

  std::string_view bytes_;
  std::string_view name_;
  Format format_;
  std::size_t offset_;   // binary: the next byte
  TextCursor text_;      // ASCII: the body's text
  int64_t line_offset_;  // header lines before the body
  TextCursor words_;     // ASCII: the current element's line
  int64_t line_ = 0;
  const Element* element_ = nullptr;
  int64_t index_ = 0;
};

// Throws when `element` cannot fit in the bytes after the header (see the file comment).
void check_count_fits(const Element& element, const Header& header, std::size_t body_bytes,
                      std::string_view source_name) {
  if (element.properties.empty()) return;  // reads nothing
  int64_t min_bytes = 0;
  for (const Property& p : element.properties)
    min_bytes += header.format == Format::ascii ? 2 : info(p.is_list ? p.count_type : p.type).bytes;
  if (element.count > (static_cast<int64_t>(body_bytes) + 1) / min_bytes)
    throw MeshError(std::string(source_name) + ": line " + std::to_string(element.line) + ": element " +
                    quoted(element.name) + " declares " + std::to_string(element.count) +
                    " elements, more than the " + std::to_string(body_bytes) +
                    " bytes after the header can hold");
}

int find_property(const Element& element, std::string_view name) {
  for (std::size_t k = 0; k < element.properties.size(); ++k)
    if (element.properties[k].name == name) return static_cast<int>(k);
  return -1;
}

}  // namespace

TriangleSurface parse_ply(std::string_view bytes, std::string_view source_name) {
  const Header header = parse_header(bytes, source_name);
  const std::string name(source_name);
  auto fail_at = [&](int64_t line, const std::string& what) {
    throw MeshError(name + ": line " + std::to_string(line) + ": " + what);
  };

  // The two elements a surface needs, and where their values sit among the properties.
  const Element* vertices = nullptr;
  const Element* faces = nullptr;
  int xyz[3] = {-1, -1, -1};
  int indices = -1;
  for (const Element& element : header.elements) {
    if (element.name == "vertex") {
      if (vertices) fail_at(element.line, "a second \"vertex\" element");
      vertices = &element;
      for (int k = 0; k < 3; ++k) {
        const std::string_view axis = k == 0 ? "x" : k == 1 ? "y" : "z";
        xyz[k] = find_property(element, axis);
        if (xyz[k] < 0 || element.properties[xyz[k]].is_list)
          fail_at(element.line, "element \"vertex\" has no scalar property \"" + std::string(axis) + "\"");
      }
      if (element.count > kMaxSurfaceVertices)
        fail_at(element.line, "more than " + std::to_string(kMaxSurfaceVertices) + " vertices");
    } else if (element.name == "face") {
      if (faces) fail_at(element.line, "a second \"face\" element");
      faces = &element;
      indices = find_property(element, "vertex_indices");
      if (indices < 0) indices = find_property(element, "vertex_index");
      if (indices < 0 || !element.properties[indices].is_list ||
          !is_integer(element.properties[indices].type))
        fail_at(element.line,
                "element \"face\" has no list of integers \"vertex_indices\" (or \"vertex_index\")");
    }
  }
  if (!vertices) throw MeshError(name + ": no \"vertex\" element in the header");
  if (!faces || faces->count == 0) throw MeshError(name + ": no triangles (no \"face\" element, or 0 faces)");
  for (const Element& element : header.elements)
    check_count_fits(element, header, bytes.size() - header.body_offset, source_name);

  TriangleSurface surface;
  surface.positions.resize(3 * static_cast<std::size_t>(vertices->count));
  surface.triangles.reserve(3 * static_cast<std::size_t>(faces->count));
  BodyReader body(bytes, header, source_name);
  std::vector<int32_t> polygon;
  for (const Element& element : header.elements) {
    if (element.properties.empty()) continue;
    for (int64_t e = 0; e < element.count; ++e) {
      body.begin(element, e);
      for (int k = 0; k < static_cast<int>(element.properties.size()); ++k) {
        const Property& property = element.properties[k];
        if (&element == vertices && !property.is_list) {
          const double value = body.number(property.type);
          const int axis = k == xyz[0] ? 0 : k == xyz[1] ? 1 : k == xyz[2] ? 2 : -1;
          if (axis < 0) continue;
          if (!std::isfinite(value))
            body.fail("coordinate " + std::string(property.name) + " is not a finite number");
          surface.positions[3 * static_cast<std::size_t>(e) + axis] = value;
        } else if (!property.is_list) {
          body.number(property.type);
        } else {
          const int64_t count = body.integer(property.count_type);
          if (count < 0) body.fail("a list of " + std::to_string(count) + " items");
          if (&element != faces || k != indices) {
            body.skip(property.type, count);
            continue;
          }
          if (count < 3) body.fail("a face needs at least 3 vertices, this one has " + std::to_string(count));
          polygon.clear();
          for (int64_t c = 0; c < count; ++c) {
            const int64_t index = body.integer(property.type);
            if (index < 0 || index >= vertices->count)
              body.fail("vertex index " + std::to_string(index) + " is out of range (" +
                        std::to_string(vertices->count) + " vertices, indices from 0)");
            polygon.push_back(static_cast<int32_t>(index));
          }
          if (static_cast<int64_t>(surface.triangles.size() / 3) + count - 2 > kMaxSurfaceTriangles)
            body.fail("more than " + std::to_string(kMaxSurfaceTriangles) + " triangles");
          for (std::size_t c = 1; c + 1 < polygon.size(); ++c)
            surface.triangles.insert(surface.triangles.end(), {polygon[0], polygon[c], polygon[c + 1]});
        }
      }
      body.end();
    }
  }
  body.finish();
  return surface;
}

}  // namespace nexdyn

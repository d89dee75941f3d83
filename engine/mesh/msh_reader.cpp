// Gmsh ASCII .msh 2.2 / 4.1 reader (what it accepts and rejects: msh_reader.hpp).
//
// The file is read into memory in one go and parsed with a TextCursor (text_cursor.hpp), which
// skips whitespace and counts lines, so every error can say where it happened. Parsing keeps raw tags (nodes and tets may
// come in any order, tags need not be contiguous), then one pass maps tags to compact ids.
// Numbers are parsed with std::from_chars: locale-free, exact (round-trips what Gmsh wrote) and
// allocation-free, so a 3 MB mesh loads in milliseconds.
//
// Formats (gmsh.info/doc/texinfo, "MSH file format"):
//   2.2  $Nodes: n, then n lines "tag x y z".
//        $Elements: n, then n lines "tag type ntags tag... node...".
//   4.1  $Nodes: "numBlocks numNodes minTag maxTag", then per block
//        "entityDim entityTag parametric numNodesInBlock", the block's tags, one per line, then
//        its coordinates "x y z [parametric coordinates]", one node per line.
//        $Elements: "numBlocks numElements minTag maxTag", then per block
//        "entityDim entityTag elementType numElementsInBlock" and one line "tag node..." each.
// Gmsh writes one node and one element per line; the reader relies on that only to skip the
// elements it does not keep (whose node count depends on the type) and parametric coordinates.
#include "engine/mesh/msh_reader.hpp"

#include "engine/mesh/mesh_file.hpp"
#include "engine/mesh/text_cursor.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

namespace nexdyn {
namespace {

constexpr int kLinearTetType = 4;

// Growth of the raw arrays is bounded by the file size anyway (see check_count); the cap only
// keeps an honest but huge count from reserving more than it needs before anything is read.
constexpr int64_t kMaxReserve = int64_t{1} << 22;

// Fewest bytes one entry can take in the file: a node is at least "t x y z\n" (8 bytes), a 2.2
// element at least "t y n v\n" (8), a 4.1 element at least "t v\n" (4), a 4.1 block header 8.
constexpr int64_t kMinNodeBytes = 8;
constexpr int64_t kMinElement22Bytes = 8;
constexpr int64_t kMinElement41Bytes = 4;
constexpr int64_t kMinBlockBytes = 8;

enum class MshVersion { kUnknown, k2, k41 };

// Everything read from the file before tags are resolved.
struct RawMesh {
  std::vector<int64_t> node_tags;      // (num_nodes) in file order
  std::vector<double> node_xyz;        // (num_nodes x 3)
  std::vector<int64_t> tet_nodes;      // (num_tets x 4) node tags
  std::vector<int64_t> tet_tags;       // (num_tets) element tags, for error messages
  std::vector<int64_t> tet_lines;      // (num_tets) line of each tet, for error messages
  int64_t skipped_elements = 0;        // elements of other types
  int64_t skipped_quadratic_tets = 0;  // type 11: worth naming when no linear tet is found
};

// Shortens a token for quoting in a message (binary junk or a whole line would be unreadable).
std::string quote(std::string_view token) {
  std::string out = "'";  // appended, not "'" + excerpt(...): GCC 12 warns of a false -Wrestrict
  out += excerpt(token, HighBytes::replaced);
  return out + "'";
}

// "$Name" of a section for a message: as it is when short and printable, else quoted, since
// the name of a section the reader skips is whatever follows a '$' in the file.
std::string section_text(std::string_view name) {
  bool plain = name.size() <= 40;
  for (char c : name) plain = plain && c > 32 && c < 127;
  return plain ? "$" + std::string(name) : quote("$" + std::string(name));
}

std::string format_double(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", x);
  return buffer;
}

// Node tag -> node index: a direct table when tags are dense (the usual 1..N), else binary search
// in the sorted tags, so a file with tags near 2^60 needs no giant table.
class NodeTagIndex {
 public:
  // `tags` in file order, `by_tag` their indices in increasing tag order (tags unique).
  NodeTagIndex(const std::vector<int64_t>& tags, const std::vector<int64_t>& by_tag)
      : by_tag_(by_tag) {
    const int64_t num_nodes = static_cast<int64_t>(tags.size());
    min_tag_ = num_nodes ? tags[by_tag.front()] : 0;
    max_tag_ = num_nodes ? tags[by_tag.back()] : -1;
    dense_ = num_nodes > 0 && max_tag_ - min_tag_ <= 4 * num_nodes + 1024;
    if (dense_) {
      table_.assign(static_cast<std::size_t>(max_tag_ - min_tag_ + 1), -1);
      for (int64_t i = 0; i < num_nodes; ++i) table_[tags[i] - min_tag_] = i;
    } else {
      sorted_tags_.resize(static_cast<std::size_t>(num_nodes));
      for (int64_t k = 0; k < num_nodes; ++k) sorted_tags_[k] = tags[by_tag[k]];
    }
  }
  // The index of the node tagged `tag`, -1 when there is none.
  int64_t operator()(int64_t tag) const {
    if (dense_) return (tag < min_tag_ || tag > max_tag_) ? -1 : table_[tag - min_tag_];
    const auto it = std::lower_bound(sorted_tags_.begin(), sorted_tags_.end(), tag);
    return (it == sorted_tags_.end() || *it != tag) ? -1 : by_tag_[it - sorted_tags_.begin()];
  }

 private:
  const std::vector<int64_t>& by_tag_;
  int64_t min_tag_ = 0, max_tag_ = -1;
  bool dense_ = false;
  std::vector<int64_t> table_;        // dense: index by tag - min_tag, -1 for no node
  std::vector<int64_t> sorted_tags_;  // sparse: the tags in increasing order
};

class MshParser {
 public:
  MshParser(std::string_view text, std::string_view source_name)
      : cursor_(text, source_name) {}

  TetMesh parse(MshReadStats* stats) {
    while (true) {
      cursor_.skip_space();
      if (cursor_.at_end()) break;
      const int64_t header_line = cursor_.line();
      const std::string_view header = read_line();
      if (header.empty() || header.front() != '$') continue;  // Gmsh ignores text between sections
      const std::string_view name = header.substr(1);
      if (name == "MeshFormat") {
        parse_mesh_format(header_line);
      } else if (name == "Nodes" || name == "Elements") {
        if (version_ == MshVersion::kUnknown)
          fail(header_line,
               "$" + std::string(name) + " before $MeshFormat (MSH 1 files are not supported)");
        section_ = name;
        section_line_ = header_line;
        item_kind_ = nullptr;
        last_item_tag_ = -1;
        if (name == "Nodes")
          version_ == MshVersion::k41 ? parse_nodes_41() : parse_nodes_2();
        else
          version_ == MshVersion::k41 ? parse_elements_41() : parse_elements_2();
        expect_section_end();
      } else if (name == "NOD" || name == "ELM") {
        fail(header_line, "MSH 1 format ($" + std::string(name) +
                              ") is not supported; re-save as MSH 2.2 or 4.1");
      } else if (name.substr(0, 3) == "End") {
        fail(header_line, quote(header) + " without a matching opening section");
      } else {
        skip_section(name, header_line);
      }
    }
    if (version_ == MshVersion::kUnknown) fail_file("not a Gmsh .msh file: no $MeshFormat section");
    return build_mesh(stats);
  }

 private:
  // ---- errors ---------------------------------------------------------------------------------
  [[noreturn]] void fail_file(const std::string& what) const { cursor_.fail_file(what); }
  [[noreturn]] void fail(int64_t line, const std::string& what) const { cursor_.fail_at(line, what); }
  [[noreturn]] void fail_here(const std::string& what) const { fail(cursor_.line(), what); }
  // Describes the node or element being read, so that truncation and syntax errors name it.
  std::string item_description() const {
    if (item_kind_ == nullptr || (item_tag_ < 0 && last_item_tag_ < 0)) return "";
    return std::string(", ") + (item_tag_ >= 0 ? "in " : "after ") + item_kind_ + " " +
           std::to_string(item_tag_ >= 0 ? item_tag_ : last_item_tag_);
  }
  [[noreturn]] void fail_eof() const {
    fail_here("unexpected end of file inside $" + std::string(section_) + " (opened at line " +
              std::to_string(section_line_) + ")" + item_description() + "; the file is truncated");
  }

  // ---- tokens ---------------------------------------------------------------------------------
  // Rest of the current line, trimmed; the cursor moves to the start of the next line.
  std::string_view read_line() { return trim(cursor_.read_line()); }
  void skip_line() { cursor_.read_line(); }
  std::string_view next_token(const char* what) {
    const std::string_view token = cursor_.next_word();
    if (token.empty()) fail_eof();
    if (token.front() == '$')
      fail_here("$" + std::string(section_) + " ends early: expected " + what + ", found " +
                quote(token) + item_description() +
                " (the section holds fewer entries than it declares)");
    return token;
  }
  int64_t read_int(const char* what) {
    const std::string_view token = next_token(what);
    int64_t value = 0;
    const NumberParse parsed = parse_integer(token, LeadingPlus::accepted, value);
    if (parsed == NumberParse::out_of_range)
      fail_here(std::string(what) + " " + quote(token) + " is out of range" + item_description());
    if (parsed != NumberParse::ok)
      fail_here("expected " + std::string(what) + ", found " + quote(token) + item_description());
    return value;
  }
  int64_t read_non_negative(const char* what) {
    const int64_t value = read_int(what);
    if (value < 0)
      fail_here(std::string(what) + " must not be negative, found " + std::to_string(value) +
                item_description());
    return value;
  }
  // Out of range: overflow gives +-HUGE_VAL, caught as non-finite by the caller; underflow a
  // harmless 0 or subnormal.
  double read_double(const char* what) {
    const std::string_view token = next_token(what);
    double value = 0.0;
    if (parse_double(token, LeadingPlus::accepted, value) == NumberParse::malformed)
      fail_here("expected " + std::string(what) + ", found " + quote(token) + item_description());
    return value;
  }
  // Entries must end their line: trailing numbers mean the file does not say what we think it
  // says (a wrong element type, a 4.0 file read as 4.1), and going on would misread the rest.
  void expect_line_end(const char* what) {
    cursor_.skip_inline_space();
    if (!cursor_.at_line_end())
      fail_here("unexpected " + quote(cursor_.read_word()) + " after " + what + item_description());
  }
  // A count read from the file must fit in what is left of the file: this is what stops a
  // corrupt header from requesting a giant allocation.
  void check_count(int64_t count, int64_t min_bytes_each, const char* what) {
    const int64_t remaining = static_cast<int64_t>(cursor_.remaining());
    if (count > remaining / min_bytes_each)
      fail_here("$" + std::string(section_) + " declares " + std::to_string(count) + " " + what +
                " but only " + std::to_string(remaining) +
                " bytes remain in the file (corrupt or truncated count)");
  }
  void begin_item(const char* kind) {
    item_kind_ = kind;
    item_tag_ = -1;
  }
  void set_item_tag(int64_t tag) {
    item_tag_ = tag;
    last_item_tag_ = tag;
  }
  void end_item() { item_tag_ = -1; }

  // ---- sections -------------------------------------------------------------------------------
  void parse_mesh_format(int64_t header_line) {
    section_ = "MeshFormat";
    section_line_ = header_line;
    item_kind_ = nullptr;
    const std::string_view version = next_token("format version");
    const int64_t file_type = read_int("file type (0 = ASCII, 1 = binary)");
    read_int("data size");
    if (file_type == 1)
      fail(header_line + 1,
           "binary .msh not supported; re-save the mesh as ASCII (e.g. gmsh -save -format msh41, "
           "Mesh.Binary = 0)");
    if (file_type != 0)
      fail(header_line + 1, "file type must be 0 (ASCII), found " + std::to_string(file_type));
    if (version == "4.1") {
      version_ = MshVersion::k41;
    } else if (version == "2" || version == "2.0" || version == "2.1" || version == "2.2") {
      version_ = MshVersion::k2;
    } else {
      fail(header_line + 1, "MSH version " + quote(version) +
                                " is not supported; re-save the mesh as MSH 2.2 or 4.1");
    }
    expect_line_end("the format line");
    expect_section_end();
  }

  void expect_section_end() {
    item_kind_ = nullptr;
    cursor_.skip_space();
    if (cursor_.at_end()) fail_eof();
    const int64_t line = cursor_.line();
    const std::string_view found = read_line();
    if (found.size() != section_.size() + 4 || found.substr(0, 4) != "$End" ||
        found.substr(4) != section_)
      fail(line, "expected $End" + std::string(section_) + " to close $" + std::string(section_) +
                     " (opened at line " + std::to_string(section_line_) + "), found " +
                     quote(found) + " (the section holds more entries than it declares)");
  }

  void skip_section(std::string_view name, int64_t header_line) {
    while (!cursor_.at_end()) {
      const std::string_view line = read_line();
      if (line.size() == name.size() + 4 && line.substr(0, 4) == "$End" && line.substr(4) == name)
        return;
    }
    fail_here("unexpected end of file inside " + section_text(name) + " (opened at line " +
              std::to_string(header_line) + "); the file is truncated");
  }

  void reserve_nodes(int64_t count) {
    const std::size_t n = static_cast<std::size_t>(std::min(count, kMaxReserve));
    raw_.node_tags.reserve(raw_.node_tags.size() + n);
    raw_.node_xyz.reserve(raw_.node_xyz.size() + 3 * n);
  }

  void read_coordinates(int64_t tag) {
    for (int d = 0; d < 3; ++d) {
      const double x = read_double("a node coordinate");
      if (!std::isfinite(x))
        fail_here("node " + std::to_string(tag) + " has a non-finite coordinate (" +
                  (std::isnan(x) ? std::string("nan") : std::string(x > 0 ? "inf" : "-inf")) + ")");
      raw_.node_xyz.push_back(x);
    }
  }

  void parse_nodes_2() {
    const int64_t count = read_non_negative("node count");
    expect_line_end("the node count");
    check_count(count, kMinNodeBytes, "nodes");
    reserve_nodes(count);
    for (int64_t i = 0; i < count; ++i) {
      begin_item("node");
      const int64_t tag = read_non_negative("node tag");
      set_item_tag(tag);
      raw_.node_tags.push_back(tag);
      read_coordinates(tag);
      expect_line_end("the node's coordinates");
      end_item();
    }
  }

  void parse_nodes_41() {
    const int64_t num_blocks = read_non_negative("node block count");
    const int64_t count = read_non_negative("node count");
    read_non_negative("min node tag");
    read_non_negative("max node tag");
    expect_line_end("the $Nodes header");
    check_count(num_blocks, kMinBlockBytes, "node blocks");
    check_count(count, kMinNodeBytes, "nodes");
    reserve_nodes(count);
    int64_t total = 0;
    for (int64_t b = 0; b < num_blocks; ++b) {
      item_kind_ = nullptr;
      const int64_t header_line = cursor_.line();
      const int64_t entity_dim = read_int("entity dimension");
      read_int("entity tag");
      const int64_t parametric = read_int("parametric flag");
      const int64_t in_block = read_non_negative("block node count");
      expect_line_end("the node block header");
      if (entity_dim < 0 || entity_dim > 3)
        fail(header_line, "node block " + std::to_string(b + 1) + " has entity dimension " +
                              std::to_string(entity_dim) + " (must be 0..3)");
      if (parametric != 0 && parametric != 1)
        fail(header_line, "node block " + std::to_string(b + 1) + " has parametric flag " +
                              std::to_string(parametric) + " (must be 0 or 1)");
      check_count(in_block, kMinNodeBytes, "nodes in a block");
      total += in_block;
      if (total > count)
        fail(header_line, "node blocks hold more nodes than the " + std::to_string(count) +
                              " declared in the $Nodes header");
      // Tags first, then coordinates in the same order.
      const std::size_t first = raw_.node_tags.size();
      for (int64_t i = 0; i < in_block; ++i) {
        begin_item("node");
        const int64_t tag = read_non_negative("node tag");
        set_item_tag(tag);
        raw_.node_tags.push_back(tag);
      }
      for (int64_t i = 0; i < in_block; ++i) {
        begin_item("node");
        const int64_t tag = raw_.node_tags[first + i];
        set_item_tag(tag);
        read_coordinates(tag);
        // Parametric coordinates (u, v, w up to the entity dimension) follow x y z on the same
        // line; the engine has no use for them.
        if (parametric == 1)
          skip_line();
        else
          expect_line_end("the node's coordinates");
        end_item();
      }
    }
    if (total != count)
      fail_here("node blocks hold " + std::to_string(total) +
                " nodes but the $Nodes header declares " + std::to_string(count));
  }

  void add_tet(int64_t tag, int64_t line, const int64_t nodes[4]) {
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        if (nodes[i] == nodes[j])
          fail(line, "element " + std::to_string(tag) + " (tet) uses node " +
                         std::to_string(nodes[i]) + " twice");
    raw_.tet_nodes.insert(raw_.tet_nodes.end(), nodes, nodes + 4);
    raw_.tet_tags.push_back(tag);
    raw_.tet_lines.push_back(line);
  }

  void skip_element(int64_t type) {
    ++raw_.skipped_elements;
    if (type == 11) ++raw_.skipped_quadratic_tets;
    skip_line();
  }

  void parse_elements_2() {
    const int64_t count = read_non_negative("element count");
    expect_line_end("the element count");
    check_count(count, kMinElement22Bytes, "elements");
    for (int64_t i = 0; i < count; ++i) {
      begin_item("element");
      const int64_t tag = read_non_negative("element tag");
      set_item_tag(tag);
      const int64_t line = cursor_.line();
      const int64_t type = read_int("element type");
      if (type != kLinearTetType) {
        skip_element(type);
        end_item();
        continue;
      }
      const int64_t num_tags = read_non_negative("number of element tags");
      if (num_tags > 64)
        fail(line,
             "element " + std::to_string(tag) + " declares " + std::to_string(num_tags) + " tags");
      for (int64_t k = 0; k < num_tags; ++k) read_int("element tag value");
      int64_t nodes[4];
      for (int64_t& node : nodes) node = read_non_negative("node tag");
      expect_line_end("the tet's 4 node tags");
      add_tet(tag, line, nodes);
      end_item();
    }
  }

  void parse_elements_41() {
    const int64_t num_blocks = read_non_negative("element block count");
    const int64_t count = read_non_negative("element count");
    read_non_negative("min element tag");
    read_non_negative("max element tag");
    expect_line_end("the $Elements header");
    check_count(num_blocks, kMinBlockBytes, "element blocks");
    check_count(count, kMinElement41Bytes, "elements");
    int64_t total = 0;
    for (int64_t b = 0; b < num_blocks; ++b) {
      item_kind_ = nullptr;
      const int64_t header_line = cursor_.line();
      read_int("entity dimension");
      read_int("entity tag");
      const int64_t type = read_int("element type");
      const int64_t in_block = read_non_negative("block element count");
      expect_line_end("the element block header");
      check_count(in_block, kMinElement41Bytes, "elements in a block");
      total += in_block;
      if (total > count)
        fail(header_line, "element blocks hold more elements than the " + std::to_string(count) +
                              " declared in the $Elements header");
      if (type == kLinearTetType) {
        const std::size_t n = static_cast<std::size_t>(std::min(in_block, kMaxReserve));
        raw_.tet_nodes.reserve(raw_.tet_nodes.size() + 4 * n);
        raw_.tet_tags.reserve(raw_.tet_tags.size() + n);
        raw_.tet_lines.reserve(raw_.tet_lines.size() + n);
      }
      for (int64_t i = 0; i < in_block; ++i) {
        begin_item("element");
        const int64_t tag = read_non_negative("element tag");
        set_item_tag(tag);
        const int64_t line = cursor_.line();
        if (type != kLinearTetType) {
          skip_element(type);
          end_item();
          continue;
        }
        int64_t nodes[4];
        for (int64_t& node : nodes) node = read_non_negative("node tag");
        expect_line_end("the tet's 4 node tags");
        add_tet(tag, line, nodes);
        end_item();
      }
    }
    if (total != count)
      fail_here("element blocks hold " + std::to_string(total) +
                " elements but the $Elements header declares " + std::to_string(count));
  }

  // ---- tags to ids ----------------------------------------------------------------------------
  // Node indices in increasing tag order; fails on a tag given twice. Files almost always list
  // tags in increasing order; only sort otherwise.
  std::vector<int64_t> nodes_by_tag() const {
    const std::vector<int64_t>& tags = raw_.node_tags;
    const int64_t num_nodes = static_cast<int64_t>(tags.size());
    std::vector<int64_t> by_tag(static_cast<std::size_t>(num_nodes));
    std::iota(by_tag.begin(), by_tag.end(), int64_t{0});
    if (!std::is_sorted(tags.begin(), tags.end()))
      std::sort(by_tag.begin(), by_tag.end(),
                [&](int64_t a, int64_t b) { return tags[a] < tags[b]; });
    for (int64_t k = 1; k < num_nodes; ++k)
      if (tags[by_tag[k]] == tags[by_tag[k - 1]])
        fail_file("node tag " + std::to_string(tags[by_tag[k]]) + " is defined twice in $Nodes");
    return by_tag;
  }

  TetMesh build_mesh(MshReadStats* stats) {
    const int64_t num_tets = static_cast<int64_t>(raw_.tet_tags.size());
    if (num_tets == 0) {
      std::string what = "no linear tetrahedra (element type 4) in the file";
      if (raw_.skipped_quadratic_tets > 0)
        what += "; it has " + std::to_string(raw_.skipped_quadratic_tets) +
                " 10-node tets (type 11), which are not supported";
      else if (raw_.skipped_elements > 0)
        what += "; skipped " + std::to_string(raw_.skipped_elements) + " element(s) of other types";
      fail_file(what);
    }
    if (num_tets > std::numeric_limits<int32_t>::max() / 4)
      fail_file(std::to_string(num_tets) + " tets do not fit in 32-bit ids");

    const std::vector<int64_t> by_tag = nodes_by_tag();
    const int64_t num_nodes = static_cast<int64_t>(by_tag.size());
    const NodeTagIndex node_index(raw_.node_tags, by_tag);

    // Resolve tet node tags, mark used nodes.
    std::vector<int64_t> tet_node_index(raw_.tet_nodes.size());
    std::vector<int32_t> new_id(static_cast<std::size_t>(num_nodes), -1);
    for (std::size_t k = 0; k < raw_.tet_nodes.size(); ++k) {
      const int64_t index = node_index(raw_.tet_nodes[k]);
      if (index < 0)
        fail(raw_.tet_lines[k / 4], "element " + std::to_string(raw_.tet_tags[k / 4]) +
                                        " references unknown node tag " +
                                        std::to_string(raw_.tet_nodes[k]));
      tet_node_index[k] = index;
      new_id[index] = 0;  // used
    }

    // Compact renumbering in tag order, dropping unused nodes.
    TetMesh mesh;
    int64_t next = 0;
    for (const int64_t index : by_tag)
      if (new_id[index] == 0) {
        if (next == std::numeric_limits<int32_t>::max()) fail_file("too many nodes for 32-bit ids");
        new_id[index] = static_cast<int32_t>(next++);
      }
    mesh.positions.resize(3 * static_cast<std::size_t>(next));
    for (int64_t i = 0; i < num_nodes; ++i)
      if (new_id[i] >= 0)
        std::copy_n(&raw_.node_xyz[3 * i], 3,
                    &mesh.positions[3 * static_cast<std::size_t>(new_id[i])]);
    mesh.tets.resize(tet_node_index.size());
    for (std::size_t k = 0; k < tet_node_index.size(); ++k)
      mesh.tets[k] = new_id[tet_node_index[k]];

    const int32_t bad = find_degenerate_tet(mesh);
    if (bad >= 0) {
      const std::string detail =
          "volume " + format_double(signed_tet_volume(mesh, bad)) +
          ", |volume| / longest edge^3 = " + format_double(tet_relative_volume(mesh, bad)) +
          " <= " + format_double(kDegenerateTetRelativeVolume);
      fail(raw_.tet_lines[bad], "element " + std::to_string(raw_.tet_tags[bad]) +
                                    " is a degenerate tet (" + detail + ")");
    }
    const int32_t flipped = orient_tets_positively(mesh);
    if (stats != nullptr) {
      stats->flipped_tets = flipped;
      stats->skipped_elements = raw_.skipped_elements;
      stats->unused_nodes = num_nodes - next;
    }
    return mesh;
  }

  TextCursor cursor_;
  MshVersion version_ = MshVersion::kUnknown;
  std::string_view section_ = "";  // name of the section being parsed, for messages
  int64_t section_line_ = 0;
  const char* item_kind_ = nullptr;  // "node" / "element" while reading one, for messages
  int64_t item_tag_ = -1;
  int64_t last_item_tag_ = -1;
  RawMesh raw_;
};

}  // namespace

TetMesh parse_msh(std::string_view text, std::string_view source_name, MshReadStats* stats) {
  return MshParser(text, source_name).parse(stats);
}

TetMesh read_msh(const std::filesystem::path& path, MshReadStats* stats) {
  return parse_msh(read_mesh_file(path), path.string(), stats);
}

}  // namespace nexdyn

// TextCursor: the reading position in a mesh file held in memory, shared by the .msh and .obj
// readers, with the line it is on, so that every error can say where it happened.
//
// The readers parse whole files as one string_view (mesh_file.hpp), never copying a line or a
// token: the cursor hands out views into the text. Whitespace is the C locale's (space, \t,
// \n, \v, \f, \r); lines end at '\n' and a '\r' before it is whitespace, so files written on
// Windows read the same. Numbers are parsed with std::from_chars: locale-free, exact and
// allocation-free. Errors are MeshError, "<file>: line <n>: <what>", built by fail_at.
#pragma once

#include "engine/mesh/mesh_error.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace nexdyn {

bool is_space(char c);          // ' ', \t, \n, \v, \f, \r
bool is_inline_space(char c);   // the same but '\n'

class TextCursor {
 public:
  // `text` and `source_name` (a file name, for messages) must outlive the cursor.
  TextCursor(std::string_view text, std::string_view source_name) : text_(text), name_(source_name) {}

  bool at_end() const { return pos_ == text_.size(); }
  // At the end of the text or of a line.
  bool at_line_end() const { return at_end() || text_[pos_] == '\n'; }
  // 1-based line of the character at the cursor.
  int64_t line() const { return line_; }
  // Bytes from the cursor to the end of the text.
  std::size_t remaining() const { return text_.size() - pos_; }

  // Moves past whitespace, line ends included.
  void skip_space();
  // Moves past whitespace on the current line, stopping at its end.
  void skip_inline_space();
  // The run of non-whitespace characters at the cursor, moving past it; empty at whitespace or
  // at the end.
  std::string_view read_word();
  // skip_space, then read_word: the next token, empty only at the end of the text.
  std::string_view next_word();
  // The rest of the current line, without its '\n' (untrimmed); the cursor moves to the start
  // of the next line.
  std::string_view read_line();

  // Throws MeshError "<source>: line <line>: <what>".
  [[noreturn]] void fail_at(int64_t line, const std::string& what) const;
  // Throws MeshError "<source>: <what>", for problems of the whole file.
  [[noreturn]] void fail_file(const std::string& what) const;

 private:
  std::string_view text_;
  std::string_view name_;
  std::size_t pos_ = 0;
  int64_t line_ = 1;
};

// `text` without leading and trailing whitespace.
std::string_view trim(std::string_view text);

// How a whole token parses as a number. `plus` says whether one leading '+' is accepted (Gmsh
// writes none, but other writers do).
enum class NumberParse { ok, malformed, out_of_range };
enum class LeadingPlus { rejected, accepted };

// A decimal integer; `value` is set only when ok.
NumberParse parse_integer(std::string_view token, LeadingPlus plus, int64_t& value);
// A decimal floating-point number (also "inf", "nan"). out_of_range sets `value` as strtod does:
// +-HUGE_VAL on overflow, the rounded tiny value (0 or subnormal) on underflow.
NumberParse parse_double(std::string_view token, LeadingPlus plus, double& value);

// `text` for quoting in a message: at most 40 characters ("..." marks a cut), with control
// bytes as '?' so that a message stays one printable line. Bytes from 128 up (UTF-8) are kept
// with HighBytes::kept, else '?' too.
enum class HighBytes { kept, replaced };
std::string excerpt(std::string_view text, HighBytes high_bytes);

}  // namespace nexdyn

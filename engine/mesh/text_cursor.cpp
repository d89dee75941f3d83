// The text cursor and token helpers of the mesh readers (see text_cursor.hpp).
#include "engine/mesh/text_cursor.hpp"

#include <charconv>
#include <cstdlib>
#include <system_error>

namespace nexdyn {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }

bool is_inline_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// ---- TextCursor ----------------------------------------------------------------------------------

void TextCursor::skip_space() {
  while (pos_ < text_.size() && is_space(text_[pos_])) {
    if (text_[pos_] == '\n') ++line_;
    ++pos_;
  }
}

void TextCursor::skip_inline_space() {
  while (pos_ < text_.size() && is_inline_space(text_[pos_])) ++pos_;
}

std::string_view TextCursor::read_word() {
  const std::size_t begin = pos_;
  while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
  return text_.substr(begin, pos_ - begin);
}

std::string_view TextCursor::next_word() {
  skip_space();
  return read_word();
}

std::string_view TextCursor::read_line() {
  const std::size_t begin = pos_;
  while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  const std::string_view line = text_.substr(begin, pos_ - begin);
  if (pos_ < text_.size()) {
    ++pos_;
    ++line_;
  }
  return line;
}

void TextCursor::fail_at(int64_t line, const std::string& what) const {
  throw MeshError(std::string(name_) + ": line " + std::to_string(line) + ": " + what);
}

void TextCursor::fail_file(const std::string& what) const { throw MeshError(std::string(name_) + ": " + what); }

// ---- tokens --------------------------------------------------------------------------------------

std::string_view trim(std::string_view text) {
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  return text;
}

namespace {

const char* after_plus(std::string_view token, LeadingPlus plus) {
  const char* first = token.data();
  if (plus == LeadingPlus::accepted && !token.empty() && *first == '+') ++first;
  return first;
}

}  // namespace

NumberParse parse_integer(std::string_view token, LeadingPlus plus, int64_t& value) {
  const char* last = token.data() + token.size();
  int64_t parsed = 0;
  const auto [end, error] = std::from_chars(after_plus(token, plus), last, parsed);
  // Out of range wins over trailing characters: "99999999999999999999x" is a number too large.
  if (error == std::errc::result_out_of_range) return NumberParse::out_of_range;
  if (error != std::errc() || end != last) return NumberParse::malformed;
  value = parsed;
  return NumberParse::ok;
}

NumberParse parse_double(std::string_view token, LeadingPlus plus, double& value) {
  const char* last = token.data() + token.size();
  const auto [end, error] = std::from_chars(after_plus(token, plus), last, value);
  if (end != last || (error != std::errc() && error != std::errc::result_out_of_range)) return NumberParse::malformed;
  if (error == std::errc::result_out_of_range) {
    // from_chars leaves the value unspecified; strtod tells overflow from underflow.
    value = std::strtod(std::string(token).c_str(), nullptr);
    return NumberParse::out_of_range;
  }
  return NumberParse::ok;
}

std::string excerpt(std::string_view text, HighBytes high_bytes) {
  std::string out;
  for (char c : text.substr(0, 40)) {
    const auto byte = static_cast<unsigned char>(c);
    const bool printable = byte >= 32 && byte != 127 && (byte < 128 || high_bytes == HighBytes::kept);
    out += printable ? c : '?';
  }
  if (text.size() > 40) out += "...";
  return out;
}

}  // namespace nexdyn

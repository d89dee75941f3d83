// Tests of TextCursor and the token helpers shared by the .msh and .obj readers: line counting,
// words and lines as views into the text, the number parsers' three outcomes, message excerpts
// and the exact form of the errors.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>

#include "engine/mesh/text_cursor.hpp"

using namespace nexdyn;

namespace {

std::string error_of(const TextCursor& cursor, int64_t line, const std::string& what) {
  try {
    line < 0 ? cursor.fail_file(what) : cursor.fail_at(line, what);
  } catch (const MeshError& error) {
    return error.what();
  }
  return "";
}

}  // namespace

TEST_SUITE_BEGIN("mesh");

TEST_CASE("TextCursor: words, lines and the line count") {
  const std::string_view text = "  alpha\tbeta\r\n\n gamma  \nlast";
  TextCursor cursor(text, "t.txt");
  CHECK(cursor.line() == 1);
  CHECK(cursor.remaining() == text.size());
  CHECK(cursor.next_word() == "alpha");
  CHECK(cursor.next_word() == "beta");
  CHECK(cursor.line() == 1);
  cursor.skip_inline_space();  // the '\r' is space; the '\n' ends the line
  CHECK(cursor.at_line_end());
  CHECK_FALSE(cursor.at_end());
  CHECK(cursor.read_word().empty());  // at a space: no word, no move
  CHECK(cursor.next_word() == "gamma");
  CHECK(cursor.line() == 3);
  // The rest of line 3, untrimmed and without its '\n'; the cursor moves to line 4.
  CHECK(cursor.read_line() == "  ");
  CHECK(cursor.line() == 4);
  CHECK(cursor.remaining() == 4);
  // The last line has no '\n': read whole, the line count stays.
  CHECK(cursor.read_line() == "last");
  CHECK(cursor.at_end());
  CHECK(cursor.at_line_end());
  CHECK(cursor.line() == 4);
  CHECK(cursor.next_word().empty());
  CHECK(cursor.read_line().empty());
}

TEST_CASE("TextCursor: words are views into the text, not copies") {
  const std::string text = "v 1 2 3\n";
  TextCursor cursor(text, "t.obj");
  const std::string_view word = cursor.next_word();
  CHECK(word.data() == text.data());
  CHECK(cursor.next_word().data() == text.data() + 2);
}

TEST_CASE("TextCursor: empty lines and skip_space count every line end") {
  TextCursor cursor("\n\n\r\n\tx", "t.txt");
  cursor.skip_space();
  CHECK(cursor.line() == 4);
  CHECK(cursor.next_word() == "x");
  TextCursor lines("\n\n", "t.txt");
  CHECK(lines.read_line().empty());
  CHECK(lines.read_line().empty());
  CHECK(lines.at_end());
  CHECK(lines.line() == 3);
}

TEST_CASE("TextCursor: errors name the source and the line") {
  const TextCursor cursor("", "meshes/bowl.obj");
  CHECK(error_of(cursor, 12, "bad vertex reference") == "meshes/bowl.obj: line 12: bad vertex reference");
  CHECK(error_of(cursor, -1, "no faces") == "meshes/bowl.obj: no faces");
}

TEST_CASE("trim: removes whitespace at both ends only") {
  CHECK(trim(" \t$Nodes \r") == "$Nodes");
  CHECK(trim("a b") == "a b");
  CHECK(trim(" \n ").empty());
}

TEST_CASE("parse_integer: whole tokens, an optional '+', out of range told apart") {
  int64_t value = 7;
  CHECK(parse_integer("-42", LeadingPlus::rejected, value) == NumberParse::ok);
  CHECK(value == -42);
  CHECK(parse_integer("+42", LeadingPlus::accepted, value) == NumberParse::ok);
  CHECK(value == 42);
  CHECK(parse_integer("+42", LeadingPlus::rejected, value) == NumberParse::malformed);
  CHECK(parse_integer("9223372036854775807", LeadingPlus::rejected, value) == NumberParse::ok);
  CHECK(value == std::numeric_limits<int64_t>::max());
  value = 7;
  CHECK(parse_integer("9223372036854775808", LeadingPlus::rejected, value) == NumberParse::out_of_range);
  // Too large wins over trailing junk; the value is left alone when not ok.
  CHECK(parse_integer("99999999999999999999x", LeadingPlus::accepted, value) == NumberParse::out_of_range);
  CHECK(parse_integer("12x", LeadingPlus::accepted, value) == NumberParse::malformed);
  CHECK(parse_integer("1.0", LeadingPlus::accepted, value) == NumberParse::malformed);
  CHECK(parse_integer("", LeadingPlus::accepted, value) == NumberParse::malformed);
  CHECK(parse_integer("+", LeadingPlus::accepted, value) == NumberParse::malformed);
  CHECK(value == 7);
}

TEST_CASE("parse_double: exact values, overflow to infinity, underflow to zero") {
  double value = 0.0;
  CHECK(parse_double("0.1", LeadingPlus::rejected, value) == NumberParse::ok);
  CHECK(value == 0.1);  // correctly rounded, as Gmsh wrote it
  CHECK(parse_double("+2.5e-3", LeadingPlus::accepted, value) == NumberParse::ok);
  CHECK(value == 2.5e-3);
  CHECK(parse_double("+2.5e-3", LeadingPlus::rejected, value) == NumberParse::malformed);
  CHECK(parse_double("1e999", LeadingPlus::rejected, value) == NumberParse::out_of_range);
  CHECK(value == std::numeric_limits<double>::infinity());
  CHECK(parse_double("-1e999", LeadingPlus::accepted, value) == NumberParse::out_of_range);
  CHECK(value == -std::numeric_limits<double>::infinity());
  CHECK(parse_double("1e-999", LeadingPlus::accepted, value) == NumberParse::out_of_range);
  CHECK(value == 0.0);
  CHECK(parse_double("nan", LeadingPlus::accepted, value) == NumberParse::ok);
  CHECK(std::isnan(value));
  CHECK(parse_double("1,5", LeadingPlus::accepted, value) == NumberParse::malformed);
  CHECK(parse_double("1.5e", LeadingPlus::accepted, value) == NumberParse::malformed);
  CHECK(parse_double("", LeadingPlus::accepted, value) == NumberParse::malformed);
}

TEST_CASE("excerpt: 40 characters at most, control bytes as '?', high bytes by choice") {
  CHECK(excerpt("abc", HighBytes::kept) == "abc");
  CHECK(excerpt(std::string(40, 'x'), HighBytes::kept) == std::string(40, 'x'));
  CHECK(excerpt(std::string(41, 'x'), HighBytes::kept) == std::string(40, 'x') + "...");
  CHECK(excerpt(std::string_view("a\0b\tc\x7f", 6), HighBytes::kept) == "a?b?c?");
  CHECK(excerpt("\xc3\xa9", HighBytes::kept) == "\xc3\xa9");
  CHECK(excerpt("\xc3\xa9", HighBytes::replaced) == "??");
  CHECK(excerpt(" ~", HighBytes::replaced) == " ~");
}

TEST_SUITE_END();

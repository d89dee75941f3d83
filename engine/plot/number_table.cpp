// The strict CSV reader of nexdyn plot (see number_table.hpp).
#include "engine/plot/number_table.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace nexdyn {

namespace fs = std::filesystem;

const std::vector<double>* NumberTable::find(std::string_view name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? nullptr : &columns[static_cast<size_t>(it - names.begin())];
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

[[noreturn]] void fail(const fs::path& file, const std::string& what) {
  throw std::runtime_error(file.string() + ": " + what);
}

}  // namespace

std::string quoted_field(std::string_view field) {
  constexpr size_t kLongest = 40;
  std::string s = "\"";
  for (char c : field.substr(0, kLongest)) s += static_cast<unsigned char>(c) < 0x20 || c == 0x7f ? '?' : c;
  return s + (field.size() > kLongest ? "...\"" : "\"");
}

namespace {

std::vector<std::string_view> split(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  for (size_t begin = 0;;) {
    const size_t end = text.find(separator, begin);
    parts.push_back(text.substr(begin, end == std::string_view::npos ? end : end - begin));
    if (end == std::string_view::npos) return parts;
    begin = end + 1;
  }
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open for reading");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) fail(file, "read error");
  return std::move(text).str();
}

enum class Field { number, not_a_number, not_finite };

// The whole field as a double. from_chars takes neither blanks nor a leading '+' (the engine
// writes neither); it reads "inf" and "nan", which the callers refuse where they must.
Field parse_field(std::string_view field, double& value) {
  const char* end = field.data() + field.size();
  const auto [stop, error] = std::from_chars(field.data(), end, value);
  if (stop != end || field.empty()) return Field::not_a_number;
  if (error == std::errc::result_out_of_range) return Field::not_finite;  // 1e999
  if (error != std::errc()) return Field::not_a_number;
  return std::isfinite(value) ? Field::number : Field::not_finite;
}

}  // namespace

NumberTable read_number_table(const fs::path& file, const std::vector<std::string>& required,
                              const std::vector<std::string>& may_be_missing, bool partial) {
  const std::string text = read_text(file);
  std::vector<std::string_view> lines = split(text, '\n');
  // The newline ending the last line leaves an empty piece after it. Without that newline, the
  // last line of a partial file may be a row the run is writing at this moment.
  if (lines.back().empty())
    lines.pop_back();
  else if (partial && lines.size() > 1)
    lines.pop_back();
  if (lines.empty() || lines.front().empty()) fail(file, "empty (no header)");

  NumberTable table;
  table.file = file;
  for (std::string_view name : split(lines.front(), ',')) {
    if (table.find(name)) fail(file, "line 1: column " + quoted_field(name) + " appears twice in the header");
    table.names.emplace_back(name);
    table.columns.emplace_back();
  }
  for (const std::string& name : required)
    if (!table.find(name)) fail(file, "line 1: no column " + quoted_field(name) + " in the header");
  if (lines.size() == 1) fail(file, "no rows (only the header)");

  const size_t num_columns = table.names.size();
  std::vector<bool> missing_allowed(num_columns);
  for (size_t c = 0; c < num_columns; ++c)
    missing_allowed[c] = std::count(may_be_missing.begin(), may_be_missing.end(), table.names[c]) > 0;
  for (std::vector<double>& column : table.columns) column.reserve(lines.size() - 1);

  for (size_t l = 1; l < lines.size(); ++l) {
    const std::string line = "line " + std::to_string(l + 1);
    if (lines[l].empty()) fail(file, line + ": empty line");
    const std::vector<std::string_view> fields = split(lines[l], ',');
    if (fields.size() != num_columns) {
      const std::string which = fields.size() < num_columns
                                    ? "none for column " + quoted_field(table.names[fields.size()])
                                    : "one after the last column " + quoted_field(table.names.back());
      fail(file, line + ": " + std::to_string(fields.size()) + " fields where the header has " +
                     std::to_string(num_columns) + " (" + which + ")");
    }
    for (size_t c = 0; c < num_columns; ++c) {
      double value = 0.0;
      const Field kind = parse_field(fields[c], value);
      const bool infinite = kind == Field::not_finite && std::isinf(value) && value > 0.0;
      if (missing_allowed[c] && (fields[c].empty() || infinite)) {
        value = kNaN;
      } else if (kind != Field::number) {
        fail(file, line + ", column " + quoted_field(table.names[c]) + ": " + quoted_field(fields[c]) +
                       (kind == Field::not_a_number ? " is not a number" : " is not a finite number"));
      }
      table.columns[c].push_back(value);
    }
  }
  return table;
}

}  // namespace nexdyn

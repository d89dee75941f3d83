// A strict reader of CSV files of numbers (stats.csv, timings.csv) for nexdyn plot: every
// field a finite number, or one line naming the file, the line and the column (stats_plot.hpp).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace nexdyn {

// A CSV file of numbers: the header's column names and every column's values.
struct NumberTable {
  std::filesystem::path file;
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;  // columns[c][row], as many rows in each

  size_t rows() const { return columns.empty() ? 0 : columns.front().size(); }
  // The column's values, or nullptr when the header has no such column.
  const std::vector<double>* find(std::string_view name) const;
};

// Reads `file` strictly: a header that holds every name in `required`, then at least one row,
// each with as many fields as the header, each field a finite number. A column named in
// `may_be_missing` also takes "inf" or an empty field, read as NaN. With `partial` (a
// *.partial.csv a run is still appending to), a last line without its newline is a row being
// written and is left out. Throws std::runtime_error with one line naming the file, the line
// and the column.
NumberTable read_number_table(const std::filesystem::path& file, const std::vector<std::string>& required,
                              const std::vector<std::string>& may_be_missing = {}, bool partial = false);

// A field quoted for an error message that must stay one line: control characters (a stray
// '\r' would move the cursor) become '?', and long fields are cut.
std::string quoted_field(std::string_view field);

}  // namespace nexdyn

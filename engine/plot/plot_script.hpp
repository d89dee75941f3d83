// The gnuplot script of nexdyn plot: the charts of stats.csv and timings.csv as gnuplot commands
// over inline data blocks, written by C++ so that gnuplot never reads a CSV file itself.
#pragma once

#include "engine/plot/number_table.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace nexdyn {

// A gnuplot string expression. In single quotes only the quote itself is special (doubled); a
// newline is joined in from a double-quoted "\n", and any other control character, which would
// end the command, becomes '?'.
std::string gp_string(std::string_view text);

// An inline data block of equal-length columns ($name << EOD ... EOD), whose columns the plot
// commands refer to by number: the data never goes through a file of its own.
class DataBlock {
 public:
  explicit DataBlock(std::string name) : name_(std::move(name)) {}
  const std::string& name() const { return name_; }
  // Adds a column; returns its gnuplot column number (from 1).
  int add(std::vector<double> values) {
    columns_.push_back(std::move(values));
    return static_cast<int>(columns_.size());
  }
  // The block's definition, to put before the commands that read it.
  std::string text() const;

 private:
  std::string name_;
  std::vector<std::vector<double>> columns_;
};

// A chart: its PNG's name and the commands that draw it once the output is set.
struct Chart {
  std::string file;
  std::string commands;
};

// The charts of stats.csv (energies, the energy balance when its columns are there, momentum,
// contacts, Newton iterations), their data added to `data`; `lines` is the curve style, `run`
// the run's name for the titles.
std::vector<Chart> stats_charts(const NumberTable& stats, DataBlock& data, const std::string& lines,
                                const std::string& run);
// timings.csv as stacked boxes, one per step.
Chart timings_chart(const NumberTable& timings, DataBlock& data, const std::string& run);

}  // namespace nexdyn

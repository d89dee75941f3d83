// nexdyn plot: PNG charts of a finished (or unfinished) run, drawn from its stats.csv and
// timings.csv by gnuplot (issue 21).
//
// The CSV files are read strictly first, in C++ (number_table.hpp): a header holding the columns the charts need,
// then rows of as many fields, each a finite number. Bad input is refused with one line naming
// the file, the line and the column, before anything is written, so gnuplot never sees a value
// it would silently skip or misread. The one exception is min_distance, which a step without
// any contact pair writes as "inf": that is read as a missing value.
//
// The charts are then drawn by one gnuplot run (pngcairo terminal) whose script, with the data
// inline, C++ writes (plot_script.hpp; the run: gnuplot_runner.hpp). gnuplot draws into a temporary folder inside the output folder, and each
// PNG is renamed into place only after gnuplot succeeded: a failure leaves no half-drawn file.
#pragma once

#include "engine/plot/number_table.hpp"

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace nexdyn {

struct PlotOptions {
  std::filesystem::path run_dir;  // the output folder of nexdyn run
  std::filesystem::path out_dir;  // where the PNGs go; empty: run_dir / "plots"
  int width = 1200, height = 800;  // pixels of every PNG
};

struct PlotResult {
  std::filesystem::path stats_file;  // the stats file read (stats.csv or stats.partial.csv)
  bool partial = false;              // stats.csv was missing: the run is under way, stopped or failed
  size_t rows = 0;                   // steps in it
  std::vector<std::filesystem::path> pngs;  // the files written, in order
};

// "WxH" of --size, each between 64 and 10000 pixels. Throws std::runtime_error naming the
// option and the value.
void parse_plot_size(const std::string& text, int& width, int& height);

// Reads the run's tables and writes energies.png, energy_balance.png (when stats.csv has the
// balance columns), momentum.png, contacts.png, newton.png and timings.png (when there is a
// timings file) into the output folder. Throws std::runtime_error with one line on bad input,
// a missing gnuplot or a gnuplot failure; then no PNG of this call is left behind.
PlotResult plot_run(const PlotOptions& options);

}  // namespace nexdyn

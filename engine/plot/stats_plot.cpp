// nexdyn plot (see stats_plot.hpp): the run's tables read, the charts' script written, gnuplot
// run, the PNGs renamed into place.
#include "engine/plot/stats_plot.hpp"

#include "engine/output/frame_writer.hpp"
#include "engine/plot/gnuplot_runner.hpp"
#include "engine/plot/plot_script.hpp"

#include <algorithm>
#include <charconv>
#include <optional>
#include <stdexcept>
#include <system_error>

namespace nexdyn {

namespace fs = std::filesystem;

void parse_plot_size(const std::string& text, int& width, int& height) {
  constexpr int kSmallest = 64, kLargest = 10000;
  const size_t x = text.find('x');
  int w = 0, h = 0;
  const auto whole_int = [](std::string_view s, int& v) {
    const auto [stop, error] = std::from_chars(s.data(), s.data() + s.size(), v);
    return error == std::errc() && stop == s.data() + s.size() && !s.empty();
  };
  if (x == std::string::npos || !whole_int(std::string_view(text).substr(0, x), w) ||
      !whole_int(std::string_view(text).substr(x + 1), h) || w < kSmallest || w > kLargest || h < kSmallest ||
      h > kLargest)
    throw std::runtime_error("--size: expected WIDTHxHEIGHT in pixels, each from 64 to 10000 (such as "
                             "1200x800), got " + quoted_field(text));
  width = w;
  height = h;
}

namespace {

// What the charts of stats.csv need; the balance columns and retries are drawn when present.
const std::vector<std::string> kStatsColumnsNeeded = {
    "step", "time", "kinetic_energy", "elastic_energy", "gravity_energy", "barrier_energy", "total_energy",
    "momentum_x", "momentum_y", "momentum_z", "newton_iterations", "contacts", "min_distance"};

}  // namespace

PlotResult plot_run(const PlotOptions& options) {
  const fs::path& dir = options.run_dir;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw std::runtime_error(dir.string() + ": no such folder");
  PlotResult result;
  result.stats_file = dir / "stats.csv";
  fs::path timings_file = dir / "timings.csv";
  if (!fs::exists(result.stats_file, ec) && fs::exists(dir / "stats.partial.csv", ec)) {
    result.partial = true;
    result.stats_file = dir / "stats.partial.csv";
    timings_file = dir / "timings.partial.csv";
  }
  if (!fs::exists(result.stats_file, ec))
    throw std::runtime_error(dir.string() + ": no stats.csv or stats.partial.csv (not an output folder of "
                             "nexdyn run?)");

  // Everything is read and checked before anything is written.
  const NumberTable stats =
      read_number_table(result.stats_file, kStatsColumnsNeeded, {"min_distance"}, result.partial);
  std::optional<NumberTable> timings;
  if (fs::exists(timings_file, ec))
    timings = read_number_table(timings_file, {"step", "total_ms"}, {}, result.partial);
  result.rows = stats.rows();

  std::string run = dir.lexically_normal().string();
  if (run.size() > 1 && run.back() == '/') run.pop_back();
  if (result.partial) run += " (" + std::to_string(stats.rows()) + " steps of an unfinished run)";
  // Few points are drawn with markers too: a one-step run is a single point, which a line hides.
  const std::string lines = stats.rows() <= 100 ? "linespoints pt 7 ps 0.8" : "lines";
  DataBlock stats_data("$stats"), timings_data("$timings");
  std::vector<Chart> charts = stats_charts(stats, stats_data, lines, run);
  if (timings) charts.push_back(timings_chart(*timings, timings_data, run));

  const fs::path out = options.out_dir.empty() ? dir / "plots" : options.out_dir;
  const bool out_existed = fs::exists(out, ec);
  fs::create_directories(out, ec);
  if (ec) throw std::runtime_error(out.string() + ": cannot create the folder: " + ec.message());
  try {
    ScratchFolder scratch(out);
    // pngcairo draws exactly width x height pixels. noenhanced: the column names' underscores
    // are text, not subscripts. The font grows with the picture.
    const int font = std::clamp(options.height / 66, 8, 18);
    const std::string common = "set grid\nset key below\nset datafile missing 'NaN'\n";
    std::string script = "set terminal pngcairo size " + std::to_string(options.width) + "," +
                         std::to_string(options.height) + " noenhanced font 'sans," + std::to_string(font) +
                         "'\n" + stats_data.text() + (timings ? timings_data.text() : "");
    for (const Chart& chart : charts)
      script += "reset\n" + common + "set output " + gp_string((scratch.path() / chart.file).string()) +
                "\n" + chart.commands + "unset output\n";
    write_file_atomically(scratch.path() / "charts.gp", script);
    run_gnuplot(scratch.path() / "charts.gp", scratch.path() / "gnuplot.log");
    for (const Chart& chart : charts)
      if (fs::file_size(scratch.path() / chart.file, ec) == 0 || ec)
        throw std::runtime_error("gnuplot exited without drawing " + chart.file);
    for (const Chart& chart : charts) {
      fs::rename(scratch.path() / chart.file, out / chart.file, ec);
      if (ec)
        throw std::runtime_error((out / chart.file).string() + ": cannot rename into place: " + ec.message());
      result.pngs.push_back(out / chart.file);
    }
  } catch (...) {
    if (!out_existed) fs::remove(out, ec);  // only if still empty
    throw;
  }
  return result;
}

}  // namespace nexdyn

// Reading a run's CSV files strictly and drawing them with gnuplot (see stats_plot.hpp).
#include "engine/plot/stats_plot.hpp"

#include "engine/output/frame_writer.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

extern char** environ;

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

// A field quoted for an error message that must stay one line: control characters (a stray
// '\r' would move the cursor) become '?', and long fields are cut.
std::string shown(std::string_view field) {
  constexpr size_t kLongest = 40;
  std::string s = "\"";
  for (char c : field.substr(0, kLongest)) s += static_cast<unsigned char>(c) < 0x20 || c == 0x7f ? '?' : c;
  return s + (field.size() > kLongest ? "...\"" : "\"");
}

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
    if (table.find(name)) fail(file, "line 1: column " + shown(name) + " appears twice in the header");
    table.names.emplace_back(name);
    table.columns.emplace_back();
  }
  for (const std::string& name : required)
    if (!table.find(name)) fail(file, "line 1: no column " + shown(name) + " in the header");
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
                                    ? "none for column " + shown(table.names[fields.size()])
                                    : "one after the last column " + shown(table.names.back());
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
        fail(file, line + ", column " + shown(table.names[c]) + ": " + shown(fields[c]) +
                       (kind == Field::not_a_number ? " is not a number" : " is not a finite number"));
      }
      table.columns[c].push_back(value);
    }
  }
  return table;
}

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
                             "1200x800), got " + shown(text));
  width = w;
  height = h;
}

namespace {

// ---- The gnuplot script ----------------------------------------------------------------------

// A gnuplot string expression. In single quotes only the quote itself is special (doubled); a
// newline is joined in from a double-quoted "\n", and any other control character, which would
// end the command, becomes '?'.
std::string gp_string(std::string_view text) {
  std::string s = "'";
  for (char c : text) {
    if (c == '\'') s += "''";
    else if (c == '\n') s += "' . \"\\n\" . '";
    else s += static_cast<unsigned char>(c) < 0x20 ? '?' : c;
  }
  return s + "'";
}

std::string number(double value) {
  if (std::isnan(value)) return "NaN";  // a missing point to gnuplot
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  return buf;
}

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
  std::string text() const {
    std::string s = name_ + " << EOD\n";
    const size_t rows = columns_.empty() ? 0 : columns_.front().size();
    for (size_t r = 0; r < rows; ++r) {
      for (size_t c = 0; c < columns_.size(); ++c) {
        if (c > 0) s += ' ';
        s += number(columns_[c][r]);
      }
      s += '\n';
    }
    return s + "EOD\n";
  }

 private:
  std::string name_;
  std::vector<std::vector<double>> columns_;
};

// One curve of a plot command.
std::string curve(const DataBlock& data, int x, int y, const std::string& style, const std::string& title) {
  return data.name() + " using " + std::to_string(x) + ":" + std::to_string(y) + " with " + style +
         " title " + gp_string(title);
}

std::string plot_command(const std::vector<std::string>& curves) {
  std::string s = "plot ";
  for (size_t i = 0; i < curves.size(); ++i) s += (i ? ", \\\n     " : "") + curves[i];
  return s + "\n";
}

// A chart: its PNG's name and the commands that draw it once the output is set.
struct Chart {
  std::string file;
  std::string commands;
};

// The top of an axis that starts at 0 for counts (contacts, iterations): a little above the
// largest value, and 1 when they are all 0, where gnuplot would complain of an empty range.
std::string count_range(const std::vector<double>& values) {
  double top = 0.0;
  for (double v : values)
    if (std::isfinite(v)) top = std::max(top, v);
  return "set yrange [0:" + number(top > 0.0 ? 1.08 * top : 1.0) + "]\n";
}

double mean(const std::vector<double>& values) {
  double sum = 0.0;
  for (double v : values) sum += v;
  return values.empty() ? 0.0 : sum / double(values.size());
}

// The axis titles, with their units, and the chart's title.
std::string labels(const std::string& x, const std::string& y, const std::string& title) {
  return "set xlabel " + gp_string(x) + "\nset ylabel " + gp_string(y) + "\nset title " + gp_string(title) +
         "\n";
}

// What the charts of stats.csv share: the table, the data block their curves read, its columns
// of step and time, the curve style for the number of rows, and the run's name for the titles.
struct StatsCharts {
  const NumberTable& stats;
  DataBlock& data;
  std::string lines;
  std::string run;
  int step = 0, time = 0;

  const std::vector<double>& column(const char* name) const { return *stats.find(name); }
  std::string drawn(int width, const std::string& color) const {
    return lines + " lw " + std::to_string(width) + " lc rgb '" + color + "'";
  }
};

// Energies, the total in black.
Chart energies_chart(StatsCharts& s) {
  const char* terms[][3] = {{"kinetic_energy", "kinetic", "#1f77b4"},
                            {"elastic_energy", "elastic", "#2ca02c"},
                            {"gravity_energy", "gravity", "#9467bd"},
                            {"barrier_energy", "barrier (kappa B)", "#d62728"}};
  std::vector<std::string> curves;
  for (const auto& [name, title, color] : terms)
    curves.push_back(curve(s.data, s.time, s.data.add(s.column(name)), s.drawn(2, color), title));
  curves.push_back(curve(s.data, s.time, s.data.add(s.column("total_energy")), s.drawn(3, "black"), "total"));
  return {"energies.png", labels("time [s]", "energy [J]", "Energies: " + s.run) + plot_command(curves)};
}

// The change of total_energy since the first row against the balance terms of the later rows
// summed (each row holds its own step's terms), and what is left over, on its own axis since it
// should be orders of magnitude smaller. Each term's sum is drawn thin, to show where the change
// came from.
Chart energy_balance_chart(StatsCharts& s, const char* const (&names)[4]) {
  const double signs[] = {1.0, -1.0, 1.0, 1.0};  // boundary_work - friction_dissipated + ...
  const char* colors[] = {"#1f77b4", "#2ca02c", "#9467bd", "#8c564b"};
  const std::vector<double>& total = s.column("total_energy");
  std::vector<double> change(total.size()), balance(total.size(), 0.0), residual(total.size());
  std::vector<std::vector<double>> sums(4, std::vector<double>(total.size(), 0.0));
  for (size_t r = 0; r < total.size(); ++r) {
    change[r] = total[r] - total.front();
    for (size_t t = 0; r > 0 && t < 4; ++t) {
      sums[t][r] = sums[t][r - 1] + signs[t] * s.column(names[t])[r];
      balance[r] += sums[t][r];
    }
    residual[r] = change[r] - balance[r];
  }
  std::vector<std::string> curves = {
      curve(s.data, s.time, s.data.add(change), s.drawn(3, "black"), "change of total_energy"),
      curve(s.data, s.time, s.data.add(balance), s.drawn(2, "#ff7f0e") + " dt 2", "balance terms")};
  for (size_t t = 0; t < 4; ++t)
    curves.push_back(curve(s.data, s.time, s.data.add(sums[t]), s.drawn(2, colors[t]) + " dt 3",
                           std::string(signs[t] < 0 ? "-" : "") + names[t]));
  curves.push_back(curve(s.data, s.time, s.data.add(residual), s.drawn(2, "#d62728") + " axes x1y2",
                         "residual (right axis)"));
  const std::string title = "Energy balance: " + s.run + "\nchange of total_energy since the first row = "
                            "boundary_work - friction_dissipated + kappa_energy + integrator_energy "
                            "(summed) + residual";
  return {"energy_balance.png", labels("time [s]", "since the first row [J]", title) +
                                    "set y2label 'residual [J]'\nset ytics nomirror\nset y2tics\n" +
                                    plot_command(curves)};
}

Chart momentum_chart(StatsCharts& s) {
  const char* parts[][2] = {{"momentum_x", "#d62728"}, {"momentum_y", "#2ca02c"}, {"momentum_z", "#1f77b4"}};
  std::vector<std::string> curves;
  for (const auto& [name, color] : parts)
    curves.push_back(curve(s.data, s.time, s.data.add(s.column(name)), s.drawn(2, color), name));
  return {"momentum.png",
          labels("time [s]", "momentum [kg m/s]", "Momentum: " + s.run) + plot_command(curves)};
}

// Contacts, and the smallest distance on a log axis. The engine writes min_distance = inf when
// no surface pair or plane is within reach (and in every row of a scene without contact), read
// as missing; a zero cannot be drawn on a log axis either.
Chart contacts_chart(StatsCharts& s) {
  std::vector<double> distance = s.column("min_distance");
  bool any_distance = false;
  for (double& d : distance) {
    if (!(d > 0.0)) d = kNaN;
    any_distance = any_distance || !std::isnan(d);
  }
  std::string commands =
      labels("time [s]", "contacts (surface pairs closer than dhat)", "Contacts: " + s.run) +
      count_range(s.column("contacts"));
  std::vector<std::string> curves = {
      curve(s.data, s.time, s.data.add(s.column("contacts")), s.drawn(2, "#1f77b4"), "contacts (left axis)")};
  if (any_distance) {
    commands += "set ytics nomirror\nset y2tics\nset logscale y2\nset format y2 '%.0e'\n"
                "set y2label 'min_distance [m] (log scale)'\n";
    curves.push_back(curve(s.data, s.time, s.data.add(distance), s.drawn(2, "#d62728") + " axes x1y2",
                           "min_distance (right axis)"));
  } else {
    commands += "set label 1 'min_distance: no surfaces within reach in any step (inf)' at graph 0.02, "
                "graph 0.95\n";
  }
  return {"contacts.png", commands + plot_command(curves)};
}

// Newton iterations per step, and the step's failed attempts when stats.csv has them.
Chart newton_chart(StatsCharts& s) {
  const std::vector<double>& iterations = s.column("newton_iterations");
  char title[64];
  std::snprintf(title, sizeof title, "Newton iterations (mean %.3g)", mean(iterations));
  std::vector<std::string> curves = {
      curve(s.data, s.step, s.data.add(iterations), s.drawn(2, "#1f77b4"), title)};
  std::vector<double> counts = iterations;
  std::string chart_title = "Newton iterations per step: " + s.run;
  // Retries are rare: drawn only where a step had some, not as a row of zeros along the axis.
  if (const std::vector<double>* retries = s.stats.find("retries")) {
    std::vector<double> nonzero = *retries;
    size_t steps_retried = 0;
    for (double& r : nonzero) {
      steps_retried += r > 0.0;
      if (r == 0.0) r = kNaN;
    }
    if (steps_retried > 0) {
      curves.push_back(curve(s.data, s.step, s.data.add(nonzero), "points pt 7 ps 1.2 lc rgb '#d62728'",
                             "retries (" + std::to_string(steps_retried) + " steps)"));
      counts.insert(counts.end(), retries->begin(), retries->end());
      chart_title += "\nretries: failed attempts of a step, each retried as two halves";
    } else {
      chart_title += "\nno step was retried";
    }
  }
  return {"newton.png", labels("step", "per step", chart_title) + count_range(counts) + plot_command(curves)};
}

// The charts of stats.csv, their data added to `data`.
std::vector<Chart> stats_charts(const NumberTable& stats, DataBlock& data, const std::string& lines,
                                const std::string& run) {
  StatsCharts s{stats, data, lines, run};
  s.step = data.add(s.column("step"));
  s.time = data.add(s.column("time"));
  std::vector<Chart> charts = {energies_chart(s)};
  static const char* const balance[4] = {"boundary_work", "friction_dissipated", "kappa_energy",
                                         "integrator_energy"};
  if (std::all_of(std::begin(balance), std::end(balance), [&](const char* name) { return stats.find(name); }))
    charts.push_back(energy_balance_chart(s, balance));
  charts.push_back(momentum_chart(s));
  charts.push_back(contacts_chart(s));
  charts.push_back(newton_chart(s));
  return charts;
}

// timings.csv as stacked boxes, one per step: each phase's box sits on the ones before it, so
// the top of the stack is the step's total_ms. Phases that took no time in any step are left out
// of the stack and the legend.
Chart timings_chart(const NumberTable& timings, DataBlock& data, const std::string& run) {
  const char* colors[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                          "#7f7f7f", "#bcbd22", "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#c5b0d5"};
  const int step = data.add(*timings.find("step"));
  std::vector<double> stacked(timings.rows(), 0.0);
  std::vector<std::string> curves;  // bottom of the stack first
  for (size_t c = 0; c < timings.names.size(); ++c) {
    const std::string& name = timings.names[c];
    if (name == "step" || name == "total_ms") continue;
    const std::vector<double>& ms = timings.columns[c];
    if (std::all_of(ms.begin(), ms.end(), [](double v) { return v == 0.0; })) continue;
    for (size_t r = 0; r < stacked.size(); ++r) stacked[r] += ms[r];
    std::string label = name.size() > 3 && name.ends_with("_ms") ? name.substr(0, name.size() - 3) : name;
    std::replace(label.begin(), label.end(), '_', ' ');
    const std::string style = "boxes lc rgb '" + std::string(colors[c % std::size(colors)]) + "'";
    curves.push_back(curve(data, step, data.add(stacked), style, label));
  }
  // Drawn from the top of the stack down, each box over the taller ones drawn before it.
  std::reverse(curves.begin(), curves.end());
  char title[256];
  std::snprintf(title, sizeof title, "Where each step's time went (mean %.4g ms per step): ",
                mean(*timings.find("total_ms")));
  // The legend on the right, top to bottom as the stack; the x axis ends at the first and last box.
  std::string commands = labels("step", "wall time per step [ms]", title + run) +
                         "set yrange [0:*]\nset style fill solid 1.0 noborder\nset boxwidth 1.0 absolute\n"
                         "set key outside right top vertical\n"
                         "set autoscale xfix\nset offsets 0.5, 0.5, 0, 0\n";
  if (curves.empty()) {  // no phase took any time: nothing to stack
    commands += "set label 1 'every phase took 0 ms' at graph 0.02, graph 0.95\n";
    curves.push_back(curve(data, step, data.add(*timings.find("total_ms")), "boxes", "total"));
  }
  return {"timings.png", commands + plot_command(curves)};
}

// ---- Running gnuplot -------------------------------------------------------------------------

// A fresh folder inside `parent` (on its file system, so renames out of it are atomic),
// removed with its contents when this goes out of scope.
class ScratchFolder {
 public:
  explicit ScratchFolder(const fs::path& parent) {
    std::string pattern = (parent / ".plot-XXXXXX").string();
    if (!mkdtemp(pattern.data()))
      throw std::runtime_error(parent.string() + ": cannot create a temporary folder: " +
                               std::strerror(errno));
    path_ = pattern;
  }
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;
  ~ScratchFolder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// The last line of gnuplot's messages that says something: its error, after the echoed command
// and the caret.
std::string last_message(const fs::path& log) {
  std::ifstream in(log);
  std::string last;
  for (std::string line; std::getline(in, line);) {
    const size_t begin = line.find_first_not_of(" \t\r^");
    if (begin != std::string::npos) last = line.substr(begin);
  }
  return last.empty() ? "no message" : last;
}

// Runs gnuplot with `script` on its standard input and its messages into `log`. -d: no
// ~/.gnuplot or system gnuplotrc, so a user's settings cannot change the charts.
void run_gnuplot(const fs::path& script, const fs::path& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, script.c_str(), O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  char program[] = "gnuplot", defaults[] = "-d";
  char* argv[] = {program, defaults, nullptr};
  pid_t pid = 0;
  const int error = posix_spawnp(&pid, program, &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  if (error == ENOENT)
    throw std::runtime_error("gnuplot not found: install the Debian package gnuplot-nox (./build.sh does)");
  if (error != 0) throw std::runtime_error(std::string("cannot start gnuplot: ") + std::strerror(error));
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) throw std::runtime_error(std::string("waiting for gnuplot: ") + std::strerror(errno));
  if (WIFSIGNALED(status))
    throw std::runtime_error("gnuplot was killed by signal " + std::to_string(WTERMSIG(status)));
  if (WEXITSTATUS(status) != 0)
    throw std::runtime_error("gnuplot failed (exit code " + std::to_string(WEXITSTATUS(status)) +
                             "): " + last_message(log));
}

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

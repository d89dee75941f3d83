// The gnuplot script of nexdyn plot (see plot_script.hpp).
#include "engine/plot/plot_script.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>

namespace nexdyn {

std::string gp_string(std::string_view text) {
  std::string s = "'";
  for (char c : text) {
    if (c == '\'') s += "''";
    else if (c == '\n') s += "' . \"\\n\" . '";
    else s += static_cast<unsigned char>(c) < 0x20 ? '?' : c;
  }
  return s + "'";
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string number(double value) {
  if (std::isnan(value)) return "NaN";  // a missing point to gnuplot
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  return buf;
}

}  // namespace

std::string DataBlock::text() const {
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

namespace {

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

}  // namespace

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

}  // namespace nexdyn

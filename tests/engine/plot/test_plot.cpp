// nexdyn plot end to end: every shipped scene's one-step run drawn into PNGs of the asked size,
// and bad input (a non-number, a wrong field count, an empty file, a missing folder, no gnuplot)
// refused with one line on stderr and no PNG written. Also the strict CSV reader by itself.
#include "engine/plot/stats_plot.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kPngs = {"energies.png", "energy_balance.png", "momentum.png",
                                        "contacts.png", "newton.png",         "timings.png"};

struct Output {
  int exit_code = -1;
  std::string out, err;  // stdout and stderr, apart: errors must be exactly one line on stderr
};

// nexdyn with these arguments (after an optional environment assignment such as "PATH=...").
Output run_nexdyn(const std::string& args, const std::string& environment = "") {
  const fs::path err_file = test::temp_dir("plot_stderr") / "stderr.txt";
  const std::string command =
      environment + " " + test::cli_path() + " " + args + " 2>" + err_file.string();
  Output result;
  FILE* pipe = popen(command.c_str(), "r");
  REQUIRE(pipe);
  char buf[4096];
  for (size_t n; (n = fread(buf, 1, sizeof buf, pipe)) > 0;) result.out.append(buf, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(err_file);
  result.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  fs::remove_all(err_file.parent_path());
  return result;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

size_t count_lines(const std::string& text) { return size_t(std::count(text.begin(), text.end(), '\n')); }

// A PNG of width x height: the 8-byte signature, then the IHDR chunk (length, "IHDR", width and
// height as big-endian 32-bit numbers); more than 1 KB, so more than an empty frame.
void check_png(const fs::path& file, uint32_t width, uint32_t height) {
  INFO(file.string());
  REQUIRE(fs::is_regular_file(file));
  CHECK(fs::file_size(file) > 1024);
  unsigned char head[24] = {};
  std::ifstream in(file, std::ios::binary);
  in.read(reinterpret_cast<char*>(head), sizeof head);
  REQUIRE(in.gcount() == sizeof head);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  CHECK(std::memcmp(head, signature, 8) == 0);
  CHECK(std::memcmp(head + 12, "IHDR", 4) == 0);
  const auto big_endian = [&](int at) {
    uint32_t value = 0;
    for (int i = 0; i < 4; ++i) value = value << 8 | head[at + i];
    return value;
  };
  CHECK(big_endian(16) == width);
  CHECK(big_endian(20) == height);
}

// Every PNG anywhere under `dir`.
std::vector<fs::path> pngs_under(const fs::path& dir) {
  std::vector<fs::path> found;
  if (!fs::exists(dir)) return found;
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.path().extension() == ".png") found.push_back(entry.path());
  return found;
}

// Every scene in scenes/ and scenes/stress/, sorted: a new scene is covered with no edit here.
std::vector<fs::path> shipped_scenes() {
  std::vector<fs::path> scenes;
  for (const char* folder : {"scenes", "scenes/stress"})
    for (const auto& entry : fs::directory_iterator(fs::path(NEXDYN_SOURCE_DIR) / folder))
      if (entry.is_regular_file() && entry.path().extension() == ".json") scenes.push_back(entry.path());
  std::sort(scenes.begin(), scenes.end());
  return scenes;
}

// A stats.csv with the engine's header and `rows` rows of plausible numbers; min_distance is
// inf in the first row, as the engine writes it before any contact.
std::string stats_csv(int rows) {
  std::string text = std::string(kStatsHeader) + ",retries" + kBalanceColumns + "\n";
  for (int i = 1; i <= rows; ++i) {
    const double t = 0.01 * i;
    std::ostringstream row;
    row << i << ',' << t << ',' << 1.0 + t << ',' << 0.5 * t << ',' << -9.81 * t << ",0," << 1.0 - 8.31 * t
        << ",0.1,0,-0.2," << 3 + i % 4 << ',' << (i > 2 ? 4 : 0) << ',' << (i == 1 ? "inf" : "0.0012")
        << ",0.01," << (i == 3 ? 1 : 0) << ",0,0.001,0,-0.002,0,0,0\n";
    text += row.str();
  }
  return text;
}

std::string timings_csv(int rows) {
  std::string text = timings_header() + "\n";
  for (int i = 1; i <= rows; ++i)
    text += std::to_string(i) + ",1,0.5,2,0,1.5,0.25,4,0.5,0.75,0.25,0.25,0.1,11.1\n";  // phases add up
  return text;
}

// A run folder holding these files.
fs::path run_folder(const std::string& tag, const std::vector<std::pair<std::string, std::string>>& files) {
  const fs::path dir = test::temp_dir(tag);
  for (const auto& [name, text] : files) test::write_text(dir / name, text);
  return dir;
}

// Row `line` (1 = the header) of `text` with field `field` (0-based) replaced by `value`, or
// removed when `value` is null.
std::string with_field(const std::string& text, int line, int field, const char* value) {
  std::vector<std::string> lines;
  std::stringstream in(text);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  std::vector<std::string> fields;
  std::stringstream row(lines[size_t(line - 1)]);
  for (std::string f; std::getline(row, f, ',');) fields.push_back(f);
  if (value) fields[size_t(field)] = value;
  else fields.erase(fields.begin() + field);
  std::string joined;
  for (const std::string& f : fields) joined += (joined.empty() ? "" : ",") + f;
  lines[size_t(line - 1)] = joined;
  std::string out;
  for (const std::string& l : lines) out += l + "\n";
  return out;
}

}  // namespace

TEST_CASE("nexdyn plot draws every PNG at the asked size for one step of every shipped scene") {
  const std::vector<fs::path> scenes = shipped_scenes();
  const auto shipped = [&](const char* name) {
    return std::count(scenes.begin(), scenes.end(), fs::path(NEXDYN_SOURCE_DIR) / "scenes" / name) == 1;
  };
  REQUIRE(shipped("cantilever.json"));
  REQUIRE(shipped("stress/pile_1000.json"));
  const fs::path root = test::temp_dir("plot_scenes");
  const auto start = std::chrono::steady_clock::now();
  std::string times;
  for (const fs::path& scene : scenes) {
    const auto scene_start = std::chrono::steady_clock::now();
    const std::string name = scene.parent_path().filename().string() + "_" + scene.stem().string();
    INFO(scene.string());
    const fs::path out = root / name;
    const Output run = run_nexdyn("run " + scene.string() + " --steps 1 --out " + out.string() + " --quiet");
    REQUIRE(run.exit_code == 0);
    // 800x500, not the default, so that --size is what sets the pictures' size.
    const Output plot = run_nexdyn("plot " + out.string() + " --size 800x500");
    INFO(plot.err);
    REQUIRE(plot.exit_code == 0);
    CHECK(plot.err.empty());
    // One line per PNG, its path, in order; the plots folder holds the PNGs and nothing else.
    std::string expected;
    for (const std::string& png : kPngs) expected += (out / "plots" / png).string() + "\n";
    CHECK(plot.out == expected);
    for (const std::string& png : kPngs) check_png(out / "plots" / png, 800, 500);
    const auto entries = std::distance(fs::directory_iterator(out / "plots"), fs::directory_iterator());
    CHECK(entries == long(kPngs.size()));
    const double seconds = seconds_since(scene_start);
    char time[64];
    std::snprintf(time, sizeof time, " %s %.1f s;", name.c_str(), seconds);
    times += time;
    fs::remove_all(out);  // the frames of the largest scenes are tens of MB
  }
  const double total = seconds_since(start);
  MESSAGE("run --steps 1 and plot of " << scenes.size() << " scenes: " << total << " s;" << times);
  fs::remove_all(root);
}

TEST_CASE("nexdyn plot: the default size is 1200x800, and a scene without contact has min_distance inf") {
  const fs::path out = test::temp_dir("plot_default");
  REQUIRE(run_nexdyn("run " + test::scene_path("cantilever.json").string() + " --steps 3 --quiet --out " +
                     out.string()).exit_code == 0);
  // What contacts.png reads as "no surfaces within reach": the engine's inf, not a number.
  const auto rows = test::read_lines(out / "stats.csv");
  REQUIRE(rows.size() == 4);
  CHECK(test::csv_field(rows[1], 12) == "inf");
  const fs::path pngs = out / "elsewhere" / "pngs";
  const Output plot = run_nexdyn("plot " + out.string() + " --out " + pngs.string());
  REQUIRE(plot.exit_code == 0);
  for (const std::string& png : kPngs) check_png(pngs / png, 1200, 800);
  CHECK_FALSE(fs::exists(out / "plots"));
  fs::remove_all(out);
}

TEST_CASE("nexdyn plot: a changed column changes exactly the charts that draw it") {
  // One value of one column changed at a time: the charts that draw that column must come out
  // different, every other chart the same bytes (gnuplot's PNGs hold no date). So each chart
  // reads the columns it names, and only those.
  // One folder throughout: the charts' titles name it.
  const std::string stats = stats_csv(12), timings = timings_csv(12);
  const fs::path dir = test::temp_dir("plot_columns");
  const auto pictures = [&](const std::string& stats_text, const std::string& timings_text) {
    test::write_text(dir / "stats.csv", stats_text);
    test::write_text(dir / "timings.csv", timings_text);
    REQUIRE(run_nexdyn("plot " + dir.string() + " --size 400x300").exit_code == 0);
    std::vector<std::string> bytes;
    for (const std::string& png : kPngs) {
      std::ifstream in(dir / "plots" / png, std::ios::binary);
      bytes.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    return bytes;
  };
  const std::vector<std::string> base = pictures(stats, timings);
  CHECK(base == pictures(stats, timings));
  struct Change {
    const char* file;
    int field;  // 0-based, in the engine's header order
    const char* value;
    std::vector<std::string> charts;
  };
  const std::vector<Change> changes = {
      {"stats.csv", 2, "1.3", {"energies.png"}},               // kinetic_energy
      {"stats.csv", 8, "0.4", {"momentum.png"}},               // momentum_y
      {"stats.csv", 10, "9", {"newton.png"}},                  // newton_iterations
      {"stats.csv", 11, "7", {"contacts.png"}},                // contacts
      {"stats.csv", 12, "0.0005", {"contacts.png"}},           // min_distance
      {"stats.csv", 16, "0.02", {"energy_balance.png"}},       // friction_dissipated
      {"stats.csv", 6, "0.5", {"energies.png", "energy_balance.png"}},  // total_energy
      {"stats.csv", 13, "0.5", {}},                            // wall_seconds: drawn from timings.csv
      {"timings.csv", 8, "9", {"timings.png"}},                // solve_ms
  };
  for (const Change& c : changes) {
    const std::string file = c.file;
    CAPTURE(file);
    CAPTURE(c.field);
    const bool in_stats = std::string(c.file) == "stats.csv";
    const std::vector<std::string> changed = pictures(in_stats ? with_field(stats, 6, c.field, c.value) : stats,
                                                      in_stats ? timings : with_field(timings, 6, c.field, c.value));
    for (size_t k = 0; k < kPngs.size(); ++k) {
      CAPTURE(kPngs[k]);
      const bool draws = std::find(c.charts.begin(), c.charts.end(), kPngs[k]) != c.charts.end();
      CHECK((changed[k] != base[k]) == draws);
    }
  }
  fs::remove_all(dir);
}

TEST_CASE("nexdyn plot: a bad stats.csv or timings.csv is one line on stderr and no PNG") {
  const std::string good = stats_csv(6);
  struct Case {
    const char* what;
    std::string stats, timings;
    const char* file;
    std::string message;  // after "<dir>/<file>: "
  };
  const Case cases[] = {
      {"a field that is not a number", with_field(good, 4, 2, "abc"), timings_csv(6), "stats.csv",
       "line 4, column \"kinetic_energy\": \"abc\" is not a number"},
      {"a NaN", with_field(good, 5, 7, "nan"), timings_csv(6), "stats.csv",
       "line 5, column \"momentum_x\": \"nan\" is not a finite number"},
      {"inf where it is not min_distance", with_field(good, 2, 6, "inf"), timings_csv(6), "stats.csv",
       "line 2, column \"total_energy\": \"inf\" is not a finite number"},
      {"a row with a field too few", with_field(good, 3, 21, nullptr), timings_csv(6), "stats.csv",
       "line 3: 21 fields where the header has 22 (none for column \"damping_dissipated\")"},
      {"a row with a field too many", with_field(good, 6, 21, "0,0"), timings_csv(6), "stats.csv",
       "line 6: 23 fields where the header has 22 (one after the last column \"damping_dissipated\")"},
      {"an empty stats.csv", "", timings_csv(6), "stats.csv", "empty (no header)"},
      {"a header and no rows", good.substr(0, good.find('\n') + 1), timings_csv(6), "stats.csv",
       "no rows (only the header)"},
      {"a column a chart needs is missing", with_field(good, 1, 8, "momentum_q"), timings_csv(6), "stats.csv",
       "line 1: no column \"momentum_y\" in the header"},
      {"a bad timings.csv", good, with_field(timings_csv(6), 7, 7, "4ms"), "timings.csv",
       "line 7, column \"factorisation_ms\": \"4ms\" is not a number"},
      {"an empty timings.csv", good, "", "timings.csv", "empty (no header)"},
  };
  for (const Case& c : cases) {
    INFO(c.what);
    const fs::path dir = run_folder("plot_bad", {{"stats.csv", c.stats}, {"timings.csv", c.timings}});
    const fs::path elsewhere = dir / "elsewhere";
    for (const std::string& out_option : {std::string(), " --out " + elsewhere.string()}) {
      const Output r = run_nexdyn("plot " + dir.string() + out_option);
      INFO(r.err);
      CHECK(r.exit_code == 1);
      CHECK(count_lines(r.err) == 1);
      CHECK(r.err == "nexdyn: error: " + (dir / c.file).string() + ": " + c.message + "\n");
      CHECK(r.out.empty());
      CHECK(pngs_under(dir).empty());
      CHECK_FALSE(fs::exists(dir / "plots"));
      CHECK_FALSE(fs::exists(elsewhere));
    }
    fs::remove_all(dir);
  }
}

TEST_CASE("nexdyn plot: a missing folder, a folder without stats.csv or a bad --size is one line") {
  const fs::path dir = test::temp_dir("plot_missing");
  const Output missing = run_nexdyn("plot " + (dir / "nope").string());
  CHECK(missing.exit_code == 1);
  CHECK(missing.err == "nexdyn: error: " + (dir / "nope").string() + ": no such folder\n");
  CHECK(missing.out.empty());
  CHECK_FALSE(fs::exists(dir / "nope"));

  const Output empty = run_nexdyn("plot " + dir.string());
  CHECK(empty.exit_code == 1);
  CHECK(count_lines(empty.err) == 1);
  CHECK(empty.err.find(dir.string() + ": no stats.csv or stats.partial.csv") != std::string::npos);
  CHECK(fs::is_empty(dir));

  test::write_text(dir / "stats.csv", stats_csv(3));
  for (const char* size : {"1200", "20x20", "800x500x2", "axb", "800x0"}) {
    INFO(size);
    const Output bad = run_nexdyn("plot " + dir.string() + " --size " + size);
    CHECK(bad.exit_code == 1);
    CHECK(count_lines(bad.err) == 1);
    CHECK(bad.err.find("--size") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "plots"));
  }
  fs::remove_all(dir);
}

TEST_CASE("nexdyn plot without gnuplot on the PATH is one line saying which package to install") {
  const fs::path dir =
      run_folder("plot_no_gnuplot", {{"stats.csv", stats_csv(4)}, {"timings.csv", timings_csv(4)}});
  const Output r = run_nexdyn("plot " + dir.string(), "PATH=" + (dir / "no-such-bin").string());
  CHECK(r.exit_code == 1);
  CHECK(r.err ==
        "nexdyn: error: gnuplot not found: install the Debian package gnuplot-nox (./build.sh does)\n");
  CHECK(r.out.empty());
  // The plots folder it made for the PNGs is gone again, with its scratch folder.
  CHECK_FALSE(fs::exists(dir / "plots"));
  fs::remove_all(dir);
}

TEST_CASE("nexdyn plot of an unfinished run reads stats.partial.csv and says so") {
  // The last row has no newline yet: the run may be writing it, so it is left out.
  const std::string partial = stats_csv(5) + "6,0.06,1.";
  const fs::path dir = run_folder("plot_partial", {{"stats.partial.csv", partial},
                                                   {"timings.partial.csv", timings_csv(4)}});
  const Output r = run_nexdyn("plot " + dir.string() + " --size 640x480");
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const std::vector<std::string> lines = test::read_lines(test::write_text(dir / "stdout.txt", r.out));
  REQUIRE(lines.size() == 1 + kPngs.size());
  CHECK(lines[0] == "no stats.csv: plotted the 5 rows of " + (dir / "stats.partial.csv").string() +
                        " (the run is under way, was stopped or failed)");
  for (size_t i = 0; i < kPngs.size(); ++i) {
    CHECK(lines[i + 1] == (dir / "plots" / kPngs[i]).string());
    check_png(dir / "plots" / kPngs[i], 640, 480);
  }
  fs::remove_all(dir);
}

TEST_CASE("plot's CSV reader: min_distance's inf and empty fields are missing values, nothing else is") {
  const fs::path dir = test::temp_dir("plot_reader");
  const fs::path file = test::write_text(dir / "t.csv", "a,min_distance\n1,inf\n2,\n3,0.5\n");
  const NumberTable t = read_number_table(file, {"a"}, {"min_distance"});
  REQUIRE(t.rows() == 3);
  CHECK(*t.find("a") == std::vector<double>{1, 2, 3});
  const std::vector<double>& d = *t.find("min_distance");
  CHECK(std::isnan(d[0]));
  CHECK(std::isnan(d[1]));
  CHECK(d[2] == 0.5);
  CHECK(t.find("b") == nullptr);

  const auto message = [&](const std::string& text, bool partial = false) {
    test::write_text(file, text);
    try {
      read_number_table(file, {"a"}, {"min_distance"}, partial);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string f = file.string() + ": ";
  CHECK(message("a,min_distance\n1,-inf\n") ==
        f + "line 2, column \"min_distance\": \"-inf\" is not a finite number");
  CHECK(message("a,min_distance\n,1\n") == f + "line 2, column \"a\": \"\" is not a number");
  CHECK(message("a,min_distance\n1, 2\n") == f + "line 2, column \"min_distance\": \" 2\" is not a number");
  CHECK(message("a,min_distance\n1e999,2\n") == f + "line 2, column \"a\": \"1e999\" is not a finite number");
  CHECK(message("a,min_distance\n1,2\r\n") == f + "line 2, column \"min_distance\": \"2?\" is not a number");
  CHECK(message("a,min_distance\n1,2\n\n3,4\n") == f + "line 3: empty line");
  CHECK(message("a,a\n1,2\n") == f + "line 1: column \"a\" appears twice in the header");
  CHECK(message("b\n1\n") == f + "line 1: no column \"a\" in the header");
  CHECK(message("\n1,2\n") == f + "empty (no header)");
  // Without its newline, the last line of a complete file is a row; of a partial file, it may be
  // half written and is left out.
  CHECK(message("a,min_distance\n1,2") == "no error");
  CHECK(message("a,min_distance\n1,2", true) == f + "no rows (only the header)");
  fs::remove_all(dir);
}

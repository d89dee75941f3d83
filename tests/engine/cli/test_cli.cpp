// The nexdyn program end to end: the contracts of DESIGN.md section 6 (exit codes, one-line
// errors, the exact stats.csv header, frames and scene.pvd, nothing half-written) and
// thread-count independence of stats.csv.
#include "engine/output/frame_writer.hpp"
#include "engine/run.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

// stats.csv without its wall_seconds column.
std::vector<std::string> stats_without_wall_time(const fs::path& file) {
  std::vector<std::string> rows = test::read_lines(file);
  for (std::string& row : rows) row = test::without_wall_seconds(row);
  return rows;
}

}  // namespace

TEST_CASE("nexdyn check validates a scene and prints its size") {
  const auto r = test::run_cli("check " + test::scene_path("cantilever.json").string());
  CHECK(r.exit_code == 0);
  CHECK(r.output.find("tets 3840") != std::string::npos);
  CHECK(r.output.find("ok") != std::string::npos);
}

TEST_CASE("nexdyn run writes stats.csv with the exact header and frames and scene.pvd and threads do not change it") {
  const fs::path out1 = test::temp_dir("cli_threads1"), out2 = test::temp_dir("cli_threads2");
  const std::string scene = test::scene_path("cantilever.json").string();
  const auto r1 = test::run_cli_on_threads("run " + scene + " --steps 30 --quiet --out " + out1.string(), 1);
  const auto r2 = test::run_cli_on_threads("run " + scene + " --steps 30 --quiet --out " + out2.string(), 2);
  REQUIRE(r1.exit_code == 0);
  REQUIRE(r2.exit_code == 0);
  const auto rows1 = test::read_lines(out1 / "stats.csv");
  REQUIRE(rows1.size() == 31);
  CHECK(rows1[0] == std::string(kStatsHeader) + ",retries" + kBalanceColumns + kAngularMomentumColumns);
  CHECK(rows1[1].rfind("1,0.01,", 0) == 0);  // the first row is the state after step 1
  CHECK(stats_without_wall_time(out1 / "stats.csv") == stats_without_wall_time(out2 / "stats.csv"));
  CHECK_FALSE(fs::exists(out1 / "stats.partial.csv"));
  // output.every = 5: frames 0, 5, ..., 30.
  for (int f = 0; f <= 30; f += 5) CHECK(fs::exists(out1 / "frames" / frame_file_name(f, "vtu")));
  CHECK_FALSE(fs::exists(out1 / "frames" / "frame_000001.vtu"));
  const auto pvd = test::read_lines(out1 / "scene.pvd");
  int datasets = 0;
  for (const auto& line : pvd) datasets += line.find("<DataSet") != std::string::npos;
  CHECK(datasets == 7);
}

TEST_CASE("output.formats \"bodies\" writes a row per body per frame: a falling box's centre follows the parabola") {
  // No contact, no boundary: the box's centre of mass falls freely, and every scheme of the family
  // integrates a constant acceleration exactly, so its height and velocity at t are y0 - g t^2 / 2
  // and -g t to rounding.
  const fs::path dir = test::temp_dir("cli_bodies");
  const fs::path scene = test::write_text(dir / "fall.json", R"({
    "time": { "dt": 0.01, "steps": 4 }, "output": { "every": 2, "formats": ["bodies"] },
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.1, 0.3], "cells": [2, 1, 3] }, "material": "m", "translate": [1, 2, 3] } ] })");
  const auto r = test::run_cli("run " + scene.string() + " --quiet --out " + (dir / "out").string());
  REQUIRE(r.exit_code == 0);
  CHECK_FALSE(fs::exists(dir / "out" / "frames" / frame_file_name(0, "vtu")));
  for (int frame : {0, 2, 4}) {
    CAPTURE(frame);
    const auto rows = test::read_lines(dir / "out" / "frames" / bodies_file_name(frame));
    REQUIRE(rows.size() == 2);
    CHECK(rows[0] == kBodiesHeader);
    std::vector<double> cells;
    std::stringstream row(rows[1].substr(std::string("0,tets,").size()));
    for (std::string cell; std::getline(row, cell, ',') && !cell.empty();) cells.push_back(std::stod(cell));
    REQUIRE(cells.size() == 7);
    const double t = 0.01 * frame;
    CHECK(cells[0] == doctest::Approx(1000 * 0.2 * 0.1 * 0.3).epsilon(1e-12));
    CHECK(std::abs(cells[1] - 1.0) <= 1e-12);
    CHECK(std::abs(cells[2] - (2.0 - 0.5 * 9.81 * t * t)) <= 1e-12);
    CHECK(std::abs(cells[3] - 3.0) <= 1e-12);
    CHECK(std::abs(cells[5] + 9.81 * t) <= 1e-12);
  }
  CHECK_FALSE(fs::exists(dir / "out" / "frames" / bodies_file_name(1)));
}

TEST_CASE("resume refuses a run whose stats header another version wrote, and leaves its rows alone") {
  // A run stopped after step 5, its header then made another version's (one column renamed, the
  // same length, as when a later version appends or renames a column): resuming would append
  // rows that do not match it.
  const fs::path out = test::temp_dir("cli_resume_header") / "run";
  const std::string scene = test::scene_path("cube_drop.json").string();
  REQUIRE(test::run_cli_with_env("NEXDYN_TEST_SIGNAL=TERM@5:row", "run " + scene + " --steps 10 --quiet --out " +
                                                                      out.string())
              .exit_code == 143);
  std::vector<std::string> rows = test::read_lines(out / "stats.partial.csv");
  REQUIRE(rows.size() == 6);
  const size_t at = rows[0].find("angular_momentum_x");
  REQUIRE(at != std::string::npos);
  rows[0][at + std::string("angular_momentum_").size()] = 'q';
  std::string text;
  for (const std::string& row : rows) text += row + "\n";
  test::write_text(out / "stats.partial.csv", text);
  const auto r = test::run_cli("resume " + out.string() + " --quiet");
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("stats.partial.csv: its header is not the one this version of nexdyn writes") != std::string::npos);
  CHECK(test::read_lines(out / "stats.partial.csv") == rows);
}

TEST_CASE("bad input: one line on stderr and a non-zero exit and nothing written") {
  const fs::path dir = test::temp_dir("cli_bad");
  const fs::path out = dir / "out";
  const fs::path bad = test::write_text(dir / "bad.json", R"({
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.5, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" } ] })");
  const auto r = test::run_cli("run " + bad.string() + " --out " + out.string());
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("bad.json: materials.m.poisson") != std::string::npos);
  CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
  CHECK_FALSE(fs::exists(out));

  const auto missing = test::run_cli("run " + (dir / "nope.json").string());
  CHECK(missing.exit_code != 0);
  CHECK(missing.output.find("nope.json") != std::string::npos);

  const auto unknown = test::run_cli("run " + test::scene_path("cantilever.json").string() +
                                     " --integrator leapfrog --out " + out.string());
  CHECK(unknown.exit_code != 0);
  CHECK(unknown.output.find("leapfrog") != std::string::npos);
  CHECK_FALSE(fs::exists(out / "stats.csv"));
}

TEST_CASE("a Newton failure is reported with its step and reason and stats.csv is not presented as complete") {
  const fs::path dir = test::temp_dir("cli_fail");
  const fs::path scene = test::write_text(dir / "stiff.json", R"({
    "time": { "dt": 0.01, "steps": 10 }, "solver": { "tolerance": 1e-12, "max_iterations": 1 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 0.1, 0.1], "cells": [10, 1, 1] }, "material": "m" } ],
    "boundary": [ { "box_min": [-0.51, -1, -1], "box_max": [-0.49, 1, 1], "fix": true } ] })");
  const auto r = test::run_cli("run " + scene.string() + " --quiet --out " + (dir / "out").string());
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("step 1 ") != std::string::npos);
  CHECK(r.output.find("max_iterations") != std::string::npos);
  CHECK_FALSE(fs::exists(dir / "out" / "stats.csv"));
  CHECK(fs::exists(dir / "out" / "stats.partial.csv"));
  CHECK_FALSE(fs::exists(dir / "out" / "timings.csv"));
  CHECK(fs::exists(dir / "out" / "timings.partial.csv"));
}

TEST_CASE("a run says how many steps it retried in halves and why the first one failed") {
  // scenes/twist_big_dt.json: each 0.1 s step inverts the tets next to the turned end face and is
  // taken as two halves; the summary names the first and the failure that split it.
  const fs::path dir = test::temp_dir("cli_retry");
  const auto r = test::run_cli("run " + test::scene_path("twist_big_dt.json").string() + " --steps 2 --out " +
                               (dir / "out").string());
  INFO(r.output);
  CHECK(r.exit_code == 0);
  CHECK(r.output.find("steps retried in halves: 2 ") != std::string::npos);
  CHECK(r.output.find("the first, step 1: [non_finite] ") != std::string::npos);
  CHECK(r.output.find("is inverted") != std::string::npos);
  CHECK(r.output.find("(a step of 0.1 s from t = 0 s)") != std::string::npos);
  const auto quiet = test::run_cli("run " + test::scene_path("twist_big_dt.json").string() + " --steps 2 --quiet --out " +
                                   (dir / "quiet").string());
  CHECK(quiet.exit_code == 0);
  CHECK(quiet.output.find("retried") == std::string::npos);
}

// timings.csv: a row per step whose phases, rest and output add up to its total, which is the
// step's wall time in stats.csv plus the output; friction shows in a friction scene.
TEST_CASE("nexdyn run writes timings.csv, a row per step split by phase") {
  const fs::path out = test::temp_dir("cli_timings");
  const auto r = test::run_cli("run " + test::scene_path("block_slide.json").string() + " --steps 20 --out " + out.string());
  REQUIRE(r.exit_code == 0);
  CHECK(r.output.find("friction ") != std::string::npos);
  CHECK(r.output.find("ms per step; Newton iterations per step") != std::string::npos);
  const auto timings = test::read_lines(out / "timings.csv");
  const auto stats = test::read_lines(out / "stats.csv");
  REQUIRE(timings.size() == 21);
  CHECK(timings[0] == timings_header());
  CHECK(timings[0].rfind("step,broad_phase_ms,ccd_ms,barrier_ms,friction_ms,", 0) == 0);
  CHECK_FALSE(fs::exists(out / "timings.partial.csv"));
  double friction = 0.0;
  for (size_t i = 1; i < timings.size(); ++i) {
    std::vector<double> v;
    std::stringstream ss(timings[i]);
    for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
    REQUIRE(v.size() == 14);
    CHECK(v[0] == double(i));
    double parts = 0.0;
    for (size_t c = 1; c + 1 < v.size(); ++c) {
      CHECK(v[c] >= 0.0);
      parts += v[c];
    }
    CHECK(parts == test::relative(v.back(), 1e-4));
    friction += v[4];
    // total = wall_seconds (stats column 14) + output, in ms
    const double wall = std::stod(test::csv_field(stats[i], 13));
    CHECK(v.back() == test::relative(1e3 * wall + v[12], 1e-4));
  }
  CHECK(friction > 0.0);
}

namespace {

// Runs nexdyn with `args`, stdout and stderr into files of their own; the exit code.
struct SplitResult {
  int exit_code = -1;
  std::string out, err;
};
SplitResult run_split(const std::string& args) {
  const fs::path dir = test::temp_dir("cli_split");
  const int status = std::system((test::cli_path() + " " + args + " > " + (dir / "out").string() + " 2> " +
                                  (dir / "err").string()).c_str());
  auto read = [](const fs::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read(dir / "out"), read(dir / "err")};
}

}  // namespace

TEST_CASE("the CLI speaks like a tool: the commands without arguments, one-line option errors, --version, exit codes") {
  // No arguments: the list of commands on stdout, and the usage exit code.
  const SplitResult none = run_split("");
  CHECK(none.exit_code == 2);
  CHECK(none.err.empty());
  for (const char* command : {"run", "resume", "check", "render", "plot", "mesh", "sweep"})
    CHECK_MESSAGE(none.out.find(std::string("\n  ") + command + " ") != std::string::npos, command);

  // Every option's range error is one line in the engine's words, and a usage error (2).
  const std::string scene = test::scene_path("cube_drop.json").string();
  const fs::path out = test::temp_dir("cli_usage") / "out";
  const std::string run = "run " + scene + " --out " + out.string();
  const std::vector<std::pair<std::string, std::string>> refused = {
      {run + " --threads 0", "--threads must be at least 1 (got 0)"},
      {"resume " + out.string() + " --threads -3", "--threads must be at least 1 (got -3)"},
      {run + " --steps 0", "--steps must be at least 1 (got 0)"},
      {run + " --steps ten", "--steps must be a whole number (got \"ten\")"},
      {run + " --checkpoint-every -1", "--checkpoint-every must be at least 0 (got -1)"},
      {run + " --energy-guard maybe", "--energy-guard must be on or off (got \"maybe\")"},
      {"render " + out.string() + " --color red", "--color must be body or speed (got \"red\")"},
  };
  for (const auto& [args, message] : refused) {
    const SplitResult r = run_split(args);
    CHECK_MESSAGE(r.exit_code == 2, args);
    CHECK_MESSAGE(r.err == "nexdyn: error: " + message + " (nexdyn --help lists the commands and options)\n", r.err);
    CHECK(r.out.empty());
  }
  CHECK_FALSE(fs::exists(out));
  const SplitResult unknown = run_split("frobnicate");
  CHECK(unknown.exit_code == 2);
  CHECK(unknown.err.find("frobnicate") != std::string::npos);
  CHECK(std::count(unknown.err.begin(), unknown.err.end(), '\n') == 1);

  // Bad input is 1: a scene that cannot be read.
  const SplitResult missing = run_split("run " + (out.parent_path() / "nope.json").string());
  CHECK(missing.exit_code == 1);

  // --version: the version and the commit of the clone the program was built from.
  const SplitResult version = run_split("--version");
  CHECK(version.exit_code == 0);
  CHECK_MESSAGE(std::regex_match(version.out, std::regex(R"(nexdyn \d+\.\d+\.\d+ \(commit ([0-9a-f]{7,}(-dirty)?|unknown)\)\n)")),
                version.out);
}

// The CCD query runner (engine/ccd_queries) and `nexdyn ccd`: zero false negatives on both shipped
// query files with exact ground truth (Wang et al. 2021 sample queries), the false positives pinned,
// thread-count independence, the exact output line, and strict parsing with file:line errors.
#include "engine/ccd_queries.hpp"
#include "engine/parallel.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/test_data.hpp"

#include <doctest/doctest.h>
#include <tbb/task_arena.h>

#include <regex>
#include <stdexcept>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

fs::path shipped(const std::string& name) { return test::test_data("ccd/" + name); }

std::string error_of(const fs::path& file) {
  try {
    read_ccd_queries(file);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

const char* kGoodLine =
    "scene f 0 0 0 0 1  0 0 0  1 0 0  0 1 0  0 0 -1  0 0 0  1 0 0  0 1 0\n";

}  // namespace

TEST_CASE("ccd: zero false negatives, and false positives pinned at the engine's own counts, on the sample query files") {
  // The engine reports 19 false positives on vertex-face.txt and 23 on edge-edge.txt (issue 20;
  // Tight-Inclusion, tolerance 1e-6, reports 23 and 46). The counts are pinned: a change that
  // makes either larger fails here, and one that makes it smaller should lower the pin.
  struct Expected {
    const char* file;
    int64_t queries, positives, false_positives;
  };
  for (const Expected& e : {Expected{"vertex-face.txt", 1109, 83, 19}, Expected{"edge-edge.txt", 1486, 62, 23}}) {
    const std::string file = e.file;
    CAPTURE(file);
    const CcdQuerySet set = read_ccd_queries(shipped(e.file));
    const CcdQueryStats stats = run_ccd_queries(set);
    CHECK(stats.queries == set.size());
    CHECK(stats.queries == e.queries);
    CHECK(stats.positives == e.positives);
    CHECK(stats.false_negatives == 0);
    const double fp_rate = double(stats.false_positives) / double(stats.queries);
    MESSAGE(e.file << ": false positives " << stats.false_positives << " of " << stats.queries << " ("
                   << 100.0 * fp_rate << "%), " << stats.queries / stats.seconds << " queries/s");
    CHECK(stats.false_positives <= e.false_positives);
  }
}

TEST_CASE("ccd: query results do not depend on the thread count") {
  // Query by query: the verdicts of a plain loop, of one thread and of two are the same.
  for (const char* name : {"vertex-face.txt", "edge-edge.txt"}) {
    CAPTURE(name);
    const CcdQuerySet set = read_ccd_queries(shipped(name));
    std::vector<uint8_t> serial(set.size());
    for (int64_t i = 0; i < set.size(); ++i) serial[i] = ccd_query_collides(set.kind, set.points.data() + 24 * i);
    CcdQueryStats s1, s2;
    tbb::task_arena(1).execute([&] { s1 = run_ccd_queries(set); });
    const int64_t split_before = split_loop_count().load();
    tbb::task_arena(2).execute([&] { s2 = run_ccd_queries(set); });
    CHECK(split_loop_count().load() > split_before);  // the queries were shared out in chunks
    CHECK(s1.reported == serial);
    CHECK(s2.reported == serial);
    int64_t fp = 0, fn = 0;
    for (int64_t i = 0; i < set.size(); ++i) {
      fp += serial[i] && !set.truth[i];
      fn += !serial[i] && set.truth[i];
    }
    CHECK(fp == s2.false_positives);
    CHECK(fn == s2.false_negatives);
  }
}

TEST_CASE("ccd: malformed query files name the file and the line") {
  const fs::path dir = test::temp_dir("ccd_bad");
  struct Case {
    std::string name, text, expect;
  };
  const Case cases[] = {
      {"no_kind.txt", std::string("# hello\n") + kGoodLine, "bad_no_kind.txt:1:"},
      {"unknown_kind.txt", std::string("# kind: face-face\n") + kGoodLine, ":1:"},
      {"short_line.txt", std::string("# kind: vertex-face\n# comment\n") + kGoodLine + "scene f 1 0 0 0 1\n", ":4:"},
      {"bad_number.txt", std::string("# kind: edge-edge\n") + kGoodLine +
                              "scene f 0 0 0 0 1  0 0 0  1 0 0  0 1 0  0 0 -1  0 0 0  1 0 0  0 1 0x\n", ":3:"},
      {"nan.txt", std::string("# kind: edge-edge\n") +
                       "scene f 0 0 nan 0 1  0 0 0  1 0 0  0 1 0  0 0 -1  0 0 0  1 0 0  0 1 0\n", ":2:"},
      {"truth.txt", std::string("# kind: edge-edge\n") +
                         "scene f 0 2 0 0 1  0 0 0  1 0 0  0 1 0  0 0 -1  0 0 0  1 0 0  0 1 0\n", ":2:"},
      {"empty.txt", "", ":1:"},
      {"no_queries.txt", "# kind: edge-edge\n# nothing\n", "no queries"},
  };
  for (const Case& c : cases) {
    const fs::path file = test::write_text(dir / ("bad_" + c.name), c.text);
    const std::string message = error_of(file);
    INFO(c.name << ": " << message);
    CHECK(message.find(file.string()) != std::string::npos);
    CHECK(message.find(c.expect) != std::string::npos);
  }
  CHECK(error_of(dir / "missing.txt").find("missing.txt") != std::string::npos);
  // A well-formed one-query file parses: the point falls through the triangle.
  const CcdQuerySet ok = read_ccd_queries(test::write_text(dir / "ok.txt", std::string("# kind: vertex-face\n") + kGoodLine));
  REQUIRE(ok.size() == 1);
  CHECK(ccd_query_collides(ok.kind, ok.points.data()));
}

TEST_CASE("ccd: nexdyn ccd prints the one line with the exact keys") {
  const auto r = test::run_cli("ccd " + shipped("vertex-face.txt").string());
  REQUIRE(r.exit_code == 0);
  const std::regex line(
      "queries=1109 positives=83 false_negatives=0 false_positives=[0-9]+ seconds=[0-9.]+ "
      "queries_per_second=[0-9.]+\n");
  CHECK(std::regex_match(r.output, line));
  const auto e = test::run_cli("ccd " + shipped("edge-edge.txt").string());
  REQUIRE(e.exit_code == 0);
  CHECK(e.output.rfind("queries=1486 positives=62 false_negatives=0 false_positives=", 0) == 0);
}

TEST_CASE("ccd: nexdyn ccd on a malformed file exits 1 with one error line naming file and line") {
  const fs::path dir = test::temp_dir("ccd_cli_bad");
  const fs::path bad = test::write_text(dir / "bad.txt", std::string("# kind: vertex-face\n") + kGoodLine + "x y\n");
  const auto r = test::run_cli("ccd " + bad.string());
  CHECK(r.exit_code == 1);
  CHECK(r.output.rfind("nexdyn: error: " + bad.string() + ":3:", 0) == 0);
  CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
  const auto missing = test::run_cli("ccd " + (dir / "none.txt").string());
  CHECK(missing.exit_code == 1);
  CHECK(missing.output.find("none.txt") != std::string::npos);
}

// Kill and resume, end to end (tet scenes, and one with affine bodies beside tet ones): `nexdyn run` killed with SIGKILL at chosen steps (the run sends
// itself the signal through the NEXDYN_TEST_SIGNAL hook, engine/run.hpp, so every kill lands
// where the test says on any machine) and continued with `nexdyn resume` writes the same
// stats.csv (all but wall_seconds), frames and scene.pvd as a run never stopped; SIGTERM stops a run with a checkpoint; a damaged newest checkpoint is
// skipped for the one before; resume refuses what it cannot continue.
#include "engine/stop_request.hpp"
#include "tests/engine/cli/child_process.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <regex>
#include <string>
#include <vector>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

using test::ChildEnd;
using test::read_bytes;
using test::run_outputs;
using test::spawn_cli;
using test::wait_child;

void check_same_outputs(const fs::path& expected, const fs::path& resumed) {
  REQUIRE(fs::exists(resumed / "stats.csv"));
  CHECK_FALSE(fs::exists(resumed / "stats.partial.csv"));
  CHECK(fs::is_empty(resumed / "checkpoints"));  // a finished run removes its checkpoints
  const auto a = run_outputs(expected), b = run_outputs(resumed);
  CHECK(a.size() == b.size());
  for (const auto& [name, bytes] : a) {
    CAPTURE(name);
    const auto it = b.find(name);
    REQUIRE(it != b.end());
    CHECK(it->second == bytes);
  }
}

// The checkpoints in `out`, by step, oldest first.
std::vector<int64_t> checkpoint_steps(const fs::path& out) {
  std::vector<int64_t> steps;
  std::error_code ec;
  if (!fs::is_directory(out / "checkpoints", ec)) return steps;
  for (const auto& entry : fs::directory_iterator(out / "checkpoints", ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".ckpt" && name.rfind("checkpoint_", 0) == 0)
      steps.push_back(std::stoll(name.substr(11, 9)));
  }
  std::sort(steps.begin(), steps.end());
  return steps;
}

// Data rows (all but the header) of a stats or timings file.
int64_t data_rows(const fs::path& file) { return static_cast<int64_t>(test::read_lines(file).size()) - 1; }

// Where a run is stopped: at `step`, as it begins, after its stats row, after its checkpoint, or
// inside it, as its first Newton iteration begins.
struct Stop {
  int64_t step = 0;
  std::string place;
  std::string hook() const { return "KILL@" + std::to_string(step) + ":" + place; }
};

// `count` stops at increasing steps in [1, total - 1] drawn with `seed`, at the `places` in turn (a
// "checkpoint" stop moved to the next step that writes one). Spread so that the later ones come
// after the first checkpoint: some runs restart from nothing, the others resume.
std::vector<Stop> stop_plan(int64_t total, int64_t every, int count, unsigned seed,
                            const std::vector<std::string>& places) {
  std::mt19937 rng(seed);
  std::vector<Stop> plan;
  int64_t previous = 0;
  for (int k = 0; k < count; ++k) {
    const int64_t last = std::max(previous + 1, previous + (total - 1 - previous) / (count - k));
    Stop stop{std::uniform_int_distribution<int64_t>(previous + 1, last)(rng), places[(seed + k) % places.size()]};
    if (stop.place == "checkpoint") {
      const int64_t at = (stop.step + every - 1) / every * every;
      if (at <= total - 1) stop.step = at;
      else stop.place = "row";
    }
    plan.push_back(stop);
    previous = stop.step;
  }
  return plan;
}

// Runs `args` (whose run has `total` steps and a checkpoint every `every`) into `full` once
// without a stop, then again into `killed`, stopped with SIGKILL at the steps and places of a
// plan and resumed after each (run afresh when no checkpoint was written yet). After each kill the
// folder must hold exactly what the run had written by then: the stats and timings rows of the
// steps before (and of the stopped one, past its row), and the newest checkpoints up to there. The
// finished run must write what the unstopped one did. "newton" stops need every step to solve
// (no scene whose bodies all sleep).
void check_kill_and_resume(const std::vector<std::string>& args, int64_t total, int64_t every, int kills,
                           unsigned seed,
                           const std::vector<std::string>& places = {"begin", "row", "checkpoint"}) {
  const fs::path dir = test::temp_dir("kill_resume");
  const fs::path full = dir / "full", killed = dir / "killed";
  auto with_out = [&](const fs::path& out) {
    std::vector<std::string> a = args;
    a.insert(a.end(), {"--quiet", "--out", out.string()});
    return a;
  };
  const std::vector<std::string> resume = {"resume", killed.string(), "--quiet"};
  REQUIRE(wait_child(spawn_cli(with_out(full))).exited(0));
  REQUIRE(data_rows(full / "stats.csv") == total);

  int resumed = 0;
  std::vector<int64_t> expected;  // the checkpoints the folder holds, by step
  for (const Stop& stop : stop_plan(total, every, kills, seed, places)) {
    CAPTURE(stop.hook());
    const bool can_resume = !checkpoint_steps(killed).empty();
    resumed += can_resume;
    CHECK(wait_child(spawn_cli(can_resume ? resume : with_out(killed), stop.hook())).killed_by(SIGKILL));
    const int64_t rows = stop.place == "begin" || stop.place == "newton" ? stop.step - 1 : stop.step;
    CHECK(data_rows(killed / "stats.partial.csv") == rows);
    CHECK(data_rows(killed / "timings.partial.csv") == rows - (stop.place == "row"));
    // Written since the start or the resume: a checkpoint every `every` steps up to the stop, each
    // followed by the removal of all but the newest two; a stop just after a checkpoint's file
    // comes before that removal. (A fresh run starts with none.)
    const int64_t from = expected.empty() ? 0 : expected.back();
    if (!can_resume) expected.clear();
    const int64_t last = stop.place == "checkpoint" ? stop.step : stop.step - 1;
    for (int64_t c = from + every; c <= last; c += every) {
      expected.push_back(c);
      if (!(stop.place == "checkpoint" && c == stop.step))
        while (expected.size() > 2) expected.erase(expected.begin());
    }
    CHECK(checkpoint_steps(killed) == expected);
  }
  const bool can_resume = !checkpoint_steps(killed).empty();
  resumed += can_resume;
  REQUIRE(wait_child(spawn_cli(can_resume ? resume : with_out(killed))).exited(0));
  MESSAGE("resumed ", resumed, " times");
  CHECK(resumed >= kills - 1);
  check_same_outputs(full, killed);
}

}  // namespace

TEST_CASE("kill and resume: the cube stack killed at chosen steps writes what an unstopped run does") {
  // The rows a killed run wrote past its last checkpoint must be cut off on resume.
  check_kill_and_resume({"run", test::scene_path("cube_stack.json").string(), "--checkpoint-every", "40"}, 200, 40,
                        4, 11);
}

// The soak of issue 42, short enough for the suite (scripts/soak_resume.sh is the long version):
// kills at seeded steps at every place, inside Newton included, on the stress scenes.
TEST_CASE("kill and resume: the 100-body pile killed at chosen steps and places writes what an unstopped run does") {
  check_kill_and_resume({"run", test::scene_path("stress/pile_100.json").string(), "--steps", "30",
                         "--checkpoint-every", "4", "--threads", "2"}, 30, 4, 5, 14,
                        {"begin", "row", "checkpoint", "newton"});
}

TEST_CASE("kill and resume: the 40x40 mat killed at chosen steps and places writes what an unstopped run does") {
  check_kill_and_resume({"run", test::scene_path("stress/mat_40.json").string(), "--steps", "24",
                         "--checkpoint-every", "3", "--threads", "2"}, 24, 3, 4, 6,
                        {"newton", "begin", "row", "checkpoint"});
}

TEST_CASE("kill and resume: soft bodies landing on affine ones, killed at chosen steps, write what an unstopped run does") {
  // mixed_drop: affine nodes and followers, tet bodies and their contacts through the map, with
  // the bodies frames of output.formats; its soft bodies land on the affine ones by step 30.
  check_kill_and_resume({"run", test::scene_path("mixed_drop.json").string(), "--steps", "60",
                         "--checkpoint-every", "8", "--threads", "2"}, 60, 8, 3, 5);
}

TEST_CASE("SIGTERM stops a run with a checkpoint, and a damaged newest checkpoint is skipped on resume") {
  const fs::path dir = test::temp_dir("sigterm");
  const std::string scene = test::scene_path("stress/pile_10.json").string();
  const std::vector<std::string> args = {"run", scene, "--steps", "60", "--checkpoint-every", "10", "--quiet", "--out"};
  auto run_into = [&](const fs::path& out) {
    std::vector<std::string> a = args;
    a.push_back(out.string());
    return a;
  };
  REQUIRE(wait_child(spawn_cli(run_into(dir / "full"))).exited(0));

  // SIGTERM as step 25 begins: the run abandons that step at its first safe point, writes a
  // checkpoint of step 24 and exits with code 128 + 15 (it is not killed by the signal).
  const fs::path out = dir / "stopped";
  CHECK(wait_child(spawn_cli(run_into(out), "TERM@25")).exited(128 + SIGTERM));
  CHECK(data_rows(out / "stats.partial.csv") == 24);
  CHECK(data_rows(out / "timings.partial.csv") == 24);
  CHECK(checkpoint_steps(out) == std::vector<int64_t>{20, 24});

  // Damage the newest checkpoint: resume names it, falls back to the one before, and still ends
  // where the unstopped run did.
  const fs::path newest = out / "checkpoints" / "checkpoint_000000024.ckpt";
  {
    std::fstream f(newest, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(40);
    f.put('\x5a');
  }
  const auto r = test::run_cli("resume " + out.string() + " --quiet");
  CHECK(r.exit_code == 0);
  CHECK(r.output.find("skipping checkpoint " + newest.string()) != std::string::npos);
  CHECK(r.output.find("checksum mismatch") != std::string::npos);
  check_same_outputs(dir / "full", out);
}

TEST_CASE("SIGTERM inside a step's Newton iterations abandons the step: the last finished step, the summary, exit 143") {
  // The stop comes as step 25's third Newton iteration begins, by step count and not by wall time.
  const fs::path dir = test::temp_dir("sigterm_newton");
  const std::string scene = test::scene_path("stress/pile_10.json").string();
  const std::string args = "run " + scene + " --steps 40 --checkpoint-every 10 --out ";
  REQUIRE(test::run_cli(args + (dir / "full").string() + " --quiet").exit_code == 0);
  const fs::path out = dir / "stopped";
  const auto stopped = test::run_cli_with_env("NEXDYN_TEST_SIGNAL=TERM@25:newton3", args + out.string());
  CHECK(stopped.exit_code == 128 + SIGTERM);
  CHECK(data_rows(out / "stats.partial.csv") == 24);
  CHECK(data_rows(out / "timings.partial.csv") == 24);
  CHECK(checkpoint_steps(out) == std::vector<int64_t>{20, 24});
  // The summary of the steps it took, as a finished run prints it, then how to go on.
  CHECK(stopped.output.find("stopped: 24 steps in ") != std::string::npos);
  CHECK(stopped.output.find("Newton iterations per step: ") != std::string::npos);
  CHECK(stopped.output.find("peak memory ") != std::string::npos);
  CHECK(stopped.output.find("interrupted by SIGTERM after step 24; checkpoint " +
                            (out / "checkpoints" / "checkpoint_000000024.ckpt").string()) != std::string::npos);
  REQUIRE(wait_child(spawn_cli({"resume", out.string(), "--quiet"})).exited(0));
  check_same_outputs(dir / "full", out);
}

TEST_CASE("a first SIGTERM or SIGINT asks for a stop, and a second one ends the process at once") {
  auto caught = [](int signal) {  // whether a handler takes the signal, not the system's default
    struct sigaction now {};
    sigaction(signal, nullptr, &now);
    return now.sa_handler != SIG_DFL;
  };
  for (const int signal : {SIGTERM, SIGINT}) {
    CAPTURE(signal);
    StopSignals signals;
    CHECK(signals.received() == 0);
    CHECK(caught(signal));
    std::raise(signal);
    CHECK(signals.received() == signal);
    CHECK(stop_requested() == signal);
    CHECK_THROWS_AS(stop_point(), StepStopped);
    // The handler gave the signal back to the system: a second one is not caught.
    CHECK_FALSE(caught(signal));
  }
  CHECK(StopSignals().received() == 0);  // a new run starts without the old request
}

TEST_CASE("SIGINT after a step's stats row stops the run at that step, also without periodic checkpoints") {
  const fs::path dir = test::temp_dir("sigint");
  const std::string scene = test::scene_path("cube_stack.json").string();
  auto run_into = [&](const fs::path& out) {
    return std::vector<std::string>{"run", scene, "--steps", "12", "--checkpoint-every", "0", "--quiet", "--out",
                                    out.string()};
  };
  REQUIRE(wait_child(spawn_cli(run_into(dir / "full"))).exited(0));
  const fs::path out = dir / "stopped";
  CHECK(wait_child(spawn_cli(run_into(out), "INT@5:row")).exited(128 + SIGINT));
  CHECK(data_rows(out / "stats.partial.csv") == 5);
  CHECK(checkpoint_steps(out) == std::vector<int64_t>{5});
  REQUIRE(wait_child(spawn_cli({"resume", out.string(), "--quiet"})).exited(0));
  check_same_outputs(dir / "full", out);

  // A malformed hook is refused with the variable named, before any step.
  const fs::path bad = dir / "bad";
  CHECK(wait_child(spawn_cli(run_into(bad), "KILL@5:middle")).exited(1));
  CHECK_FALSE(fs::exists(bad / "stats.partial.csv"));
}

namespace {

// Every file under `out` with its bytes (the lock file, and the folder's whole state).
std::map<std::string, std::string> folder_bytes(const fs::path& out) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(out))
    files[fs::relative(entry.path(), out).string()] = entry.is_regular_file() ? read_bytes(entry.path()) : "(folder)";
  return files;
}

}  // namespace

TEST_CASE("one writer per output folder: a second run or resume is refused, names the holder, writes nothing") {
  const fs::path dir = test::temp_dir("folder_lock");
  const std::string scene = test::scene_path("stress/pile_10.json").string();
  const fs::path out = dir / "run";
  const std::vector<std::string> run = {"run", scene, "--steps", "20", "--checkpoint-every", "5", "--quiet", "--out",
                                        out.string()};
  // The first run suspends itself after step 7's row (SIGSTOP through the test hook), holding the
  // folder: by step count, not by wall time.
  const pid_t holder = spawn_cli(run, "STOP@7:row");
  int status = 0;
  REQUIRE(waitpid(holder, &status, WUNTRACED) == holder);
  REQUIRE(WIFSTOPPED(status));
  const auto before = folder_bytes(out);
  CHECK(before.count(".nexdyn.lock") == 1);
  const std::string pid = "process " + std::to_string(holder);
  for (const std::string& args : {"run " + scene + " --steps 20 --out " + out.string(), "resume " + out.string()}) {
    CAPTURE(args);
    const auto refused = test::run_cli(args);
    CHECK(refused.exit_code == 1);
    CHECK(refused.output.find(out.string() + ": another run is writing this output folder (" + pid) !=
          std::string::npos);
    CHECK(folder_bytes(out) == before);
  }
  // The lock dies with its process, even by SIGKILL: the folder resumes.
  kill(holder, SIGKILL);
  CHECK(wait_child(holder).killed_by(SIGKILL));
  REQUIRE(wait_child(spawn_cli({"resume", out.string(), "--quiet"})).exited(0));
  std::vector<std::string> full = run;
  full.back() = (dir / "full").string();
  REQUIRE(wait_child(spawn_cli(full)).exited(0));
  check_same_outputs(dir / "full", out);
}

TEST_CASE("one writer per output folder within a process too, and the lock goes with its holder") {
  const fs::path dir = test::temp_dir("folder_lock_process");
  {
    const auto first = OutputLock::acquire(dir);
    try {
      OutputLock::acquire(dir);
      FAIL("a second lock of the folder in the same process was granted");
    } catch (const std::runtime_error& e) {
      CHECK(std::string(e.what()).find("process " + std::to_string(getpid()) + " (this one)") != std::string::npos);
    }
    // Another process is refused while this one holds it, and told which process does.
    test::write_text(dir / "stats.partial.csv", "step\n");
    const auto other = test::run_cli("resume " + dir.string());
    CHECK(other.exit_code == 1);
    CHECK(other.output.find("another run is writing this output folder (process " + std::to_string(getpid())) !=
          std::string::npos);
  }
  CHECK_NOTHROW(OutputLock::acquire(dir));  // released with its last holder
}

TEST_CASE("resume refuses a finished run, a folder without a run and a changed scene file, and repeats a failed step") {
  const fs::path dir = test::temp_dir("resume_refuse");
  const auto finished = test::run_cli("run " + test::scene_path("cube_stack.json").string() +
                                      " --steps 5 --quiet --out " + (dir / "done").string());
  REQUIRE(finished.exit_code == 0);
  const auto again = test::run_cli("resume " + (dir / "done").string());
  CHECK(again.exit_code != 0);
  CHECK(again.output.find("the run finished") != std::string::npos);

  const auto empty = test::run_cli("resume " + (dir / "nothing").string());
  CHECK(empty.exit_code != 0);
  CHECK(empty.output.find("no run to resume") != std::string::npos);

  // A run that stops at a failed step leaves its last good state as a checkpoint, without any
  // kill: twist_big_dt with no halvings fails at step 1. Resumed as it is, it fails the same way;
  // with the scene file edited, resume refuses.
  const fs::path scene = dir / "twist.json";
  std::string text = read_bytes(test::scene_path("twist_big_dt.json"));
  text = std::regex_replace(text, std::regex("\"substep_halvings\": 4"), "\"substep_halvings\": 0");
  REQUIRE(text.find("\"substep_halvings\": 0") != std::string::npos);
  test::write_text(scene, text);
  const fs::path out = dir / "failed";
  const auto failed = test::run_cli("run " + scene.string() + " --quiet --out " + out.string());
  CHECK(failed.exit_code == 1);
  CHECK(fs::exists(out / "checkpoints" / "checkpoint_000000000.ckpt"));
  const auto again_failed = test::run_cli("resume " + out.string() + " --quiet");
  CHECK(again_failed.exit_code == 1);
  CHECK(again_failed.output.find("step 1 (t = 0.1 s) failed [non_finite]") != std::string::npos);
  test::write_text(scene, text + "\n");
  const auto changed = test::run_cli("resume " + out.string());
  CHECK(changed.exit_code != 0);
  CHECK(changed.output.find("changed since the run started") != std::string::npos);
}

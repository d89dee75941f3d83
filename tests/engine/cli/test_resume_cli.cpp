// Kill and resume, end to end: `nexdyn run` killed with SIGKILL at random moments and continued
// with `nexdyn resume` writes the same stats.csv (all but wall_seconds), frames and scene.pvd as
// a run never stopped; SIGTERM stops a run with a checkpoint; a damaged newest checkpoint is
// skipped for the one before; resume refuses what it cannot continue.
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <regex>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

// nexdyn with these arguments as a child process, its output thrown away.
pid_t spawn_cli(const std::vector<std::string>& args) {
  std::vector<std::string> all = {NEXDYN_CLI_PATH};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  const int error = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  REQUIRE(error == 0);
  return pid;
}

// Waits for the child; its exit code, or 128 + the signal that ended it.
int wait_child(pid_t pid) {
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Everything a run leaves that must not depend on being stopped and resumed: stats.csv without
// wall_seconds, scene.pvd, and every frame file, by name.
std::map<std::string, std::string> run_outputs(const fs::path& out) {
  std::map<std::string, std::string> files;
  std::string stats;
  for (const std::string& row : test::read_lines(out / "stats.csv")) stats += test::without_wall_seconds(row) + "\n";
  files["stats.csv"] = stats;
  files["scene.pvd"] = read_bytes(out / "scene.pvd");
  for (const auto& entry : fs::directory_iterator(out / "frames"))
    files["frames/" + entry.path().filename().string()] = read_bytes(entry.path());
  return files;
}

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

// True when `out` has no checkpoint to resume from.
bool no_checkpoint(const fs::path& out) {
  std::error_code ec;
  if (!fs::is_directory(out / "checkpoints", ec)) return true;
  for (const auto& entry : fs::directory_iterator(out / "checkpoints", ec))
    if (entry.path().extension() == ".ckpt") return false;
  return true;
}

// Runs `args` into `out` once without a stop, timing it, then again into `killed_out`, killed with
// SIGKILL at `kills` random moments and resumed each time (started afresh when the kill came
// before the first checkpoint), and compares the two.
void check_kill_and_resume(const std::vector<std::string>& args, int kills, unsigned seed) {
  const fs::path dir = test::temp_dir("kill_resume");
  const fs::path full = dir / "full", killed = dir / "killed";
  auto with_out = [&](const fs::path& out) {
    std::vector<std::string> a = args;
    a.insert(a.end(), {"--quiet", "--out", out.string()});
    return a;
  };
  const auto start = std::chrono::steady_clock::now();
  REQUIRE(wait_child(spawn_cli(with_out(full))) == 0);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> moment(0.05 * seconds, 0.9 * seconds);
  bool started = false;
  int resumed = 0;
  for (int k = 0; k < kills; ++k) {
    const bool can_resume = started && !no_checkpoint(killed);
    const pid_t pid = spawn_cli(can_resume ? std::vector<std::string>{"resume", killed.string(), "--quiet"}
                                           : with_out(killed));
    resumed += can_resume;
    started = true;
    std::this_thread::sleep_for(std::chrono::duration<double>(moment(rng)));
    kill(pid, SIGKILL);
    if (wait_child(pid) == 0) break;  // it finished before the kill
  }
  if (!fs::exists(killed / "stats.csv")) {
    const bool can_resume = !no_checkpoint(killed);
    resumed += can_resume;
    REQUIRE(wait_child(spawn_cli(can_resume ? std::vector<std::string>{"resume", killed.string(), "--quiet"}
                                            : with_out(killed))) == 0);
  }
  MESSAGE("resumed ", resumed, " times");
  CHECK(resumed > 0);
  check_same_outputs(full, killed);
}

}  // namespace

TEST_CASE("kill and resume: the cube stack killed at random moments writes what an unstopped run does") {
  // The rows a killed run wrote past its last checkpoint must be cut off on resume.
  check_kill_and_resume({"run", test::scene_path("cube_stack.json").string(), "--checkpoint-every", "40"}, 4, 11);
}

TEST_CASE("kill and resume: the 100-body pile killed at random moments writes what an unstopped run does") {
  check_kill_and_resume({"run", test::scene_path("stress/pile_100.json").string(), "--steps", "30",
                         "--checkpoint-every", "4", "--threads", "2"}, 3, 7);
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
  REQUIRE(wait_child(spawn_cli(run_into(dir / "full"))) == 0);

  // SIGTERM once the run has passed its first periodic checkpoint: it ends the step under way,
  // writes a checkpoint of it and exits with 128 + 15.
  const fs::path out = dir / "stopped";
  const pid_t pid = spawn_cli(run_into(out));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out / "checkpoints" / "checkpoint_000000010.ckpt") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  kill(pid, SIGTERM);
  const int code = wait_child(pid);
  if (code == 0) {
    MESSAGE("the run finished before SIGTERM arrived; nothing to check");
    return;
  }
  CHECK(code == 128 + SIGTERM);
  const auto rows = test::read_lines(out / "stats.partial.csv");
  REQUIRE(rows.size() >= 11);
  const int64_t stopped_after = static_cast<int64_t>(rows.size()) - 1;
  char name[64];
  std::snprintf(name, sizeof name, "checkpoint_%09lld.ckpt", static_cast<long long>(stopped_after));
  CHECK(fs::exists(out / "checkpoints" / name));

  // Damage the newest checkpoint: resume names it, falls back to the one before, and still ends
  // where the unstopped run did.
  std::vector<fs::path> found;
  for (const auto& entry : fs::directory_iterator(out / "checkpoints")) found.push_back(entry.path());
  std::sort(found.begin(), found.end());
  REQUIRE(found.size() == 2);
  {
    std::fstream f(found.back(), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(40);
    f.put('\x5a');
  }
  const auto r = test::run_cli("resume " + out.string() + " --quiet");
  CHECK(r.exit_code == 0);
  CHECK(r.output.find("skipping checkpoint " + found.back().string()) != std::string::npos);
  CHECK(r.output.find("checksum mismatch") != std::string::npos);
  check_same_outputs(dir / "full", out);
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
  CHECK(failed.exit_code == 2);
  CHECK(fs::exists(out / "checkpoints" / "checkpoint_000000000.ckpt"));
  const auto again_failed = test::run_cli("resume " + out.string() + " --quiet");
  CHECK(again_failed.exit_code == 2);
  CHECK(again_failed.output.find("step 1 (t = 0.1 s) failed [non_finite]") != std::string::npos);
  test::write_text(scene, text + "\n");
  const auto changed = test::run_cli("resume " + out.string());
  CHECK(changed.exit_code != 0);
  CHECK(changed.output.find("changed since the run started") != std::string::npos);
}

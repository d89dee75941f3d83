// `nexdyn` as a child process, for the tests that stop a run with a signal and resume it
// (tests/engine/cli/test_resume_cli.cpp for tet scenes, tests/engine/mpm/test_mpm_run.cpp for
// particle scenes): spawn it, wait for it, and read back what the run left.
#pragma once

#include "engine/run.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

extern char** environ;

namespace nexdyn::test {

// nexdyn with these arguments as a child process, its output thrown away; with a `signal_at`
// (SIGNAL@STEP[:PLACE], engine/run.hpp) the run sends itself that signal there.
inline pid_t spawn_cli(const std::vector<std::string>& args, const std::string& signal_at = "") {
  std::vector<std::string> all = {cli_path()};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  // The environment of this process without any hook of its own, plus the one asked for.
  const std::string hook_prefix = std::string(nexdyn::kTestSignalVariable) + "=";
  std::string hook = hook_prefix + signal_at;
  std::vector<char*> env;
  for (char** e = environ; *e; ++e)
    if (std::string(*e).rfind(hook_prefix, 0) != 0) env.push_back(*e);
  if (!signal_at.empty()) env.push_back(hook.data());
  env.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  const int error = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), env.data());
  posix_spawn_file_actions_destroy(&actions);
  REQUIRE(error == 0);
  return pid;
}

// How a child process ended: by exit (with its code) or killed by a signal; an exit with code
// 143 is not a death by SIGTERM.
struct ChildEnd {
  bool killed = false;  // ended by a signal
  int value = 0;        // the exit code, or the signal
  bool exited(int code) const { return !killed && value == code; }
  bool killed_by(int signal) const { return killed && value == signal; }
};
inline doctest::String toString(const ChildEnd& e) {
  return (std::string(e.killed ? "killed by signal " : "exit code ") + std::to_string(e.value)).c_str();
}

inline ChildEnd wait_child(pid_t pid) {
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  REQUIRE((WIFEXITED(status) || WIFSIGNALED(status)));
  return WIFEXITED(status) ? ChildEnd{false, WEXITSTATUS(status)} : ChildEnd{true, WTERMSIG(status)};
}

inline std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Everything a run leaves that must not depend on being stopped and resumed: stats.csv without
// wall_seconds, scene.pvd, and every frame file, by name.
inline std::map<std::string, std::string> run_outputs(const std::filesystem::path& out) {
  std::map<std::string, std::string> files;
  std::string stats;
  for (const std::string& row : read_lines(out / "stats.csv")) stats += without_wall_seconds(row) + "\n";
  files["stats.csv"] = stats;
  files["scene.pvd"] = read_bytes(out / "scene.pvd");
  for (const auto& entry : std::filesystem::directory_iterator(out / "frames"))
    files["frames/" + entry.path().filename().string()] = read_bytes(entry.path());
  return files;
}

}  // namespace nexdyn::test

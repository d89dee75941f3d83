// Running gnuplot for nexdyn plot (see gnuplot_runner.hpp).
#include "engine/plot/gnuplot_runner.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace nexdyn {

namespace fs = std::filesystem;

ScratchFolder::ScratchFolder(const fs::path& parent) {
  std::string pattern = (parent / ".plot-XXXXXX").string();
  if (!mkdtemp(pattern.data()))
    throw std::runtime_error(parent.string() + ": cannot create a temporary folder: " + std::strerror(errno));
  path_ = pattern;
}

ScratchFolder::~ScratchFolder() {
  std::error_code ignored;
  fs::remove_all(path_, ignored);
}

namespace {

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

}  // namespace

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

}  // namespace nexdyn

// Running gnuplot for nexdyn plot: a scratch folder for its output, and the run itself with its
// error turned into one line.
#pragma once

#include <filesystem>

namespace nexdyn {

// A fresh folder inside `parent` (on its file system, so renames out of it are atomic),
// removed with its contents when this goes out of scope.
class ScratchFolder {
 public:
  explicit ScratchFolder(const std::filesystem::path& parent);
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;
  ~ScratchFolder();
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Runs gnuplot with `script` on its standard input and its messages into `log`. -d: no
// ~/.gnuplot or system gnuplotrc, so a user's settings cannot change the charts. Throws
// std::runtime_error with one line when gnuplot is missing, fails or is killed.
void run_gnuplot(const std::filesystem::path& script, const std::filesystem::path& log);

}  // namespace nexdyn

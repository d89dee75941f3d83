// One writer per output folder (issue 42): `nexdyn run`, `nexdyn resume` and a Python Simulation
// with an output folder hold an exclusive lock on the folder while they write it, so that two
// processes never interleave their rows, frames and checkpoints.
//
// The lock is a POSIX record lock (fcntl F_SETLK) on the file .nexdyn.lock in the folder: the
// kernel drops it when its process ends, however it ends (a SIGKILL leaves no stale lock), and it
// names the process that holds it (F_GETLK). The file itself stays; it means nothing unlocked.
// A POSIX lock belongs to the process and goes when any descriptor of the file in the process is
// closed, so the file is opened once per process: a second lock of the same folder within the
// process is refused like one from another process.
#pragma once

#include <filesystem>
#include <memory>
#include <stdexcept>

namespace nexdyn {

inline constexpr const char* kLockFileName = ".nexdyn.lock";

// The refusal: another process, or another run of this one, holds the folder.
class OutputFolderBusy : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class OutputLock {
 public:
  // Locks `folder`, which must exist. Throws OutputFolderBusy naming the folder and the process id
  // of the holder when another process (or another run of this one) holds it; std::runtime_error
  // when the lock file cannot be opened.
  static std::shared_ptr<OutputLock> acquire(const std::filesystem::path& folder);
  ~OutputLock();  // releases the lock
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  OutputLock(int fd, std::filesystem::path key) : fd_(fd), key_(std::move(key)) {}
  int fd_;
  std::filesystem::path key_;  // the lock file's canonical path, this process's record of it
};

}  // namespace nexdyn

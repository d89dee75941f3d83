// The lock of an output folder (see run_lock.hpp).
#include "engine/run_lock.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>

namespace nexdyn {

namespace {

// The lock files this process holds (canonical paths): POSIX locks do not exclude their own
// process, so this set does.
std::mutex g_held_mutex;
std::set<std::filesystem::path> g_held;

OutputFolderBusy held_by(const std::filesystem::path& folder, long pid) {
  const std::string who = pid > 0 ? "process " + std::to_string(pid) : "another process";
  const std::string own = pid == static_cast<long>(getpid()) ? " (this one)" : "";
  return OutputFolderBusy(folder.string() + ": another run is writing this output folder (" + who + own +
                            " holds its lock " + kLockFileName + "); wait for it to end or stop it, or write "
                            "into another folder");
}

}  // namespace

std::shared_ptr<OutputLock> OutputLock::acquire(const std::filesystem::path& folder) {
  std::error_code ec;
  const std::filesystem::path directory = std::filesystem::canonical(folder, ec);
  if (ec) throw std::runtime_error(folder.string() + ": cannot lock the output folder: " + ec.message());
  const std::filesystem::path file = directory / kLockFileName;
  std::lock_guard<std::mutex> guard(g_held_mutex);
  // Checked before the file is opened: closing a second descriptor of it would drop the lock.
  if (g_held.count(file)) throw held_by(folder, static_cast<long>(getpid()));
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0)
    throw std::runtime_error((folder / kLockFileName).string() + ": cannot open the output folder's lock file: " +
                             std::strerror(errno));
  struct flock lock {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  if (::fcntl(fd, F_SETLK, &lock) != 0) {
    const int error = errno;
    struct flock holder {};
    holder.l_type = F_WRLCK;
    holder.l_whence = SEEK_SET;
    const long pid = ::fcntl(fd, F_GETLK, &holder) == 0 && holder.l_type != F_UNLCK ? holder.l_pid : 0;
    ::close(fd);
    if (error == EACCES || error == EAGAIN) throw held_by(folder, pid);
    throw std::runtime_error(file.string() + ": cannot lock the output folder: " + std::strerror(error));
  }
  g_held.insert(file);
  return std::shared_ptr<OutputLock>(new OutputLock(fd, file));
}

OutputLock::~OutputLock() {
  std::lock_guard<std::mutex> guard(g_held_mutex);
  g_held.erase(key_);
  ::close(fd_);  // drops the lock
}

}  // namespace nexdyn

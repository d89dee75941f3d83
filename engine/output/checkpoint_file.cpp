// Checkpoint file framing, CRC-32 and the durable atomic write (see checkpoint_file.hpp).
#include "engine/output/checkpoint_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <fstream>
#include <iterator>

namespace nexdyn {

namespace {

constexpr char kMagic[8] = {'N', 'X', 'D', 'Y', 'N', 'C', 'K', 'P'};
constexpr size_t kHeaderBytes = sizeof(kMagic) + sizeof(uint32_t) + sizeof(uint64_t) + sizeof(uint32_t);

const std::array<uint32_t, 256>& crc_table() {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  return table;
}

std::string errno_text() { return std::strerror(errno); }

// Writes all of `bytes` to fd; false on any error.
bool write_all(int fd, const char* bytes, size_t size) {
  while (size > 0) {
    const ssize_t written = ::write(fd, bytes, size);
    if (written < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    bytes += written;
    size -= static_cast<size_t>(written);
  }
  return true;
}

}  // namespace

uint32_t crc32(const void* data, size_t size, uint32_t crc) {
  const std::array<uint32_t, 256>& table = crc_table();
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  for (size_t i = 0; i < size; ++i) crc = table[(crc ^ p[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

void write_checkpoint_file(const std::filesystem::path& path, const std::string& payload) {
  std::string file(kMagic, sizeof(kMagic));
  auto append = [&](const auto& value) { file.append(reinterpret_cast<const char*>(&value), sizeof(value)); };
  append(kCheckpointFormat);
  append(static_cast<uint64_t>(payload.size()));
  append(crc32(payload.data(), payload.size()));
  file += payload;

  const std::filesystem::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw CheckpointError(tmp.string() + ": cannot open for writing: " + errno_text());
  const bool written = write_all(fd, file.data(), file.size()) && ::fsync(fd) == 0;
  const std::string why = written ? "" : errno_text();
  ::close(fd);
  if (!written) {
    ::unlink(tmp.c_str());
    throw CheckpointError(tmp.string() + ": write failed: " + why);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string reason = errno_text();
    ::unlink(tmp.c_str());
    throw CheckpointError(path.string() + ": cannot rename into place: " + reason);
  }
  // The rename itself is durable once the folder is synced.
  const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : ".";
  const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

std::string read_checkpoint_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CheckpointError(path.string() + ": cannot open");
  std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw CheckpointError(path.string() + ": read failed");
  const std::string what = path.string();
  if (file.size() < kHeaderBytes) throw CheckpointError(what + ": truncated header (" + std::to_string(file.size()) + " bytes)");
  if (file.compare(0, sizeof(kMagic), kMagic, sizeof(kMagic)) != 0)
    throw CheckpointError(what + ": not a NexDynIPC checkpoint (wrong magic)");
  size_t offset = sizeof(kMagic);
  auto take = [&](auto& value) {
    std::memcpy(&value, file.data() + offset, sizeof(value));
    offset += sizeof(value);
  };
  uint32_t format = 0, crc = 0;
  uint64_t size = 0;
  take(format);
  take(size);
  take(crc);
  if (format != kCheckpointFormat)
    throw CheckpointError(what + ": checkpoint format " + std::to_string(format) + ", this build reads " +
                          std::to_string(kCheckpointFormat));
  if (file.size() - kHeaderBytes != size)
    throw CheckpointError(what + ": truncated or padded: the header says " + std::to_string(size) +
                          " payload bytes, the file has " + std::to_string(file.size() - kHeaderBytes));
  if (crc32(file.data() + kHeaderBytes, size) != crc) throw CheckpointError(what + ": checksum mismatch (corrupt)");
  return file.substr(kHeaderBytes);
}

}  // namespace nexdyn

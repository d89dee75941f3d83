// Checkpoint files: a run's state as bytes, framed and checksummed, written atomically.
//
// File layout (little-endian, as the machine writes it; a checkpoint is read back on the machine
// and build that wrote it):
//
//   8 bytes  magic "NXDYNCKP"
//   4 bytes  format version (kCheckpointFormat)
//   8 bytes  payload size in bytes
//   4 bytes  CRC-32 of the payload
//   payload
//
// A file that is shorter or longer than its header says, has another magic or version, or whose
// payload fails its CRC is rejected with a sentence saying which. Writing goes to NAME.tmp, which
// is flushed to the disk (fsync) and renamed over NAME, then the folder is synced: a crash at any
// moment leaves either the old file or the new one, never half of one.
//
// The payload is a plain sequence of values; CheckpointWriter appends them and CheckpointReader
// takes them back in the same order, with every read bounds-checked.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace nexdyn {

// 2: generalized-alpha history and the energy balance; 3: the energy guard's record;
// 4: State and StepHistory (engine/output/step_checkpoint.hpp); 5, 6: sleeping bodies, damping;
// 7: the damping record without its end-of-step force, and MPM states
inline constexpr uint32_t kCheckpointFormat = 7;

// A checkpoint that cannot be used: unreadable, truncated, corrupt, or from another scene.
struct CheckpointError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320) of `size` bytes, continuing from `crc`.
uint32_t crc32(const void* data, size_t size, uint32_t crc = 0);

class CheckpointWriter {
 public:
  template <typename T>
  void put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    const char* p = reinterpret_cast<const char*>(&value);
    bytes_.append(p, sizeof(T));
  }
  template <typename T>
  void put_vector(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    put<uint64_t>(values.size());
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  }
  void put_string(const std::string& s) {
    put<uint64_t>(s.size());
    bytes_.append(s);
  }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

class CheckpointReader {
 public:
  // `what` names the source in error messages (the file).
  CheckpointReader(const std::string& bytes, std::string what) : bytes_(bytes), what_(std::move(what)) {}

  template <typename T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    T value;
    std::memcpy(&value, take(sizeof(T)), sizeof(T));
    return value;
  }
  // A vector written by put_vector; `expected` (when >= 0) is the length it must have.
  template <typename T>
  std::vector<T> get_vector(int64_t expected = -1) {
    const uint64_t count = get<uint64_t>();
    if (count > (bytes_.size() - offset_) / sizeof(T)) fail("an array longer than the rest of the file");
    if (expected >= 0 && count != static_cast<uint64_t>(expected))
      fail("an array of " + std::to_string(count) + " values where " + std::to_string(expected) + " belong");
    std::vector<T> values(count);
    if (count) std::memcpy(values.data(), take(count * sizeof(T)), count * sizeof(T));
    return values;
  }
  std::string get_string() {
    const uint64_t size = get<uint64_t>();
    if (size > bytes_.size() - offset_) fail("a string longer than the rest of the file");
    return std::string(take(size), size);
  }
  // Every byte must have been read: a longer payload is not this format.
  void expect_end() const {
    if (offset_ != bytes_.size()) fail(std::to_string(bytes_.size() - offset_) + " unread bytes at the end");
  }
  [[noreturn]] void fail(const std::string& why) const { throw CheckpointError(what_ + ": " + why); }

 private:
  const char* take(size_t n) {
    if (n > bytes_.size() - offset_) fail("truncated payload");
    const char* p = bytes_.data() + offset_;
    offset_ += n;
    return p;
  }
  const std::string& bytes_;
  std::string what_;
  size_t offset_ = 0;
};

// Frames `payload` (header, CRC) and writes it to `path` atomically and durably.
void write_checkpoint_file(const std::filesystem::path& path, const std::string& payload);
// The payload of a checkpoint file; CheckpointError naming the file and the fault otherwise.
std::string read_checkpoint_file(const std::filesystem::path& path);

}  // namespace nexdyn

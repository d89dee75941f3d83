// Checkpoint framing: CRC-32 against its published check value, round trips, and every kind of
// damage (flipped byte, truncation, padding, wrong magic, wrong format) rejected with a reason.
#include "engine/output/checkpoint_file.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

// The message of the CheckpointError that reading `path` throws ("" when it reads fine).
std::string read_error(const fs::path& path) {
  try {
    read_checkpoint_file(path);
  } catch (const CheckpointError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("crc32 gives the check value of the IEEE polynomial and chains over pieces") {
  const std::string digits = "123456789";
  CHECK(crc32(digits.data(), digits.size()) == 0xCBF43926u);
  CHECK(crc32(digits.data() + 4, 5, crc32(digits.data(), 4)) == 0xCBF43926u);
  CHECK(crc32(nullptr, 0) == 0u);
}

TEST_CASE("a checkpoint payload reads back as written, value by value") {
  CheckpointWriter out;
  out.put<int64_t>(-42);
  out.put(3.25);
  out.put_vector(std::vector<double>{1.0, -0.0, 1e300});
  out.put_string("scene.json");
  out.put_vector(std::vector<int32_t>{});
  const fs::path file = test::temp_dir("ckpt_roundtrip") / "a.ckpt";
  write_checkpoint_file(file, out.bytes());
  CHECK_FALSE(fs::exists(file.string() + ".tmp"));
  const std::string payload = read_checkpoint_file(file);
  CHECK(payload == out.bytes());
  CheckpointReader in(payload, file.string());
  CHECK(in.get<int64_t>() == -42);
  CHECK(in.get<double>() == 3.25);
  const std::vector<double> v = in.get_vector<double>(3);
  CHECK(v[2] == 1e300);
  CHECK(std::signbit(v[1]));
  CHECK(in.get_string() == "scene.json");
  CHECK(in.get_vector<int32_t>().empty());
  CHECK_NOTHROW(in.expect_end());
  CHECK_THROWS_AS(in.get<uint8_t>(), CheckpointError);
}

TEST_CASE("damaged checkpoint files are rejected with the reason") {
  const fs::path dir = test::temp_dir("ckpt_damage");
  const fs::path good = dir / "good.ckpt";
  CheckpointWriter out;
  for (int i = 0; i < 100; ++i) out.put<double>(i * 0.5);
  write_checkpoint_file(good, out.bytes());
  const std::string bytes = read_bytes(good);
  REQUIRE(read_error(good).empty());

  // Every single flipped bit in the payload is caught by the CRC.
  const size_t header = bytes.size() - out.bytes().size();
  int caught = 0, flips = 0;
  for (size_t k = header; k < bytes.size(); k += 37) {
    std::string bad = bytes;
    bad[k] = static_cast<char>(bad[k] ^ (1 << (k % 8)));
    write_bytes(dir / "flip.ckpt", bad);
    ++flips;
    caught += read_error(dir / "flip.ckpt").find("checksum mismatch") != std::string::npos;
  }
  CHECK(caught == flips);

  write_bytes(dir / "short.ckpt", bytes.substr(0, bytes.size() - 1));
  CHECK(read_error(dir / "short.ckpt").find("truncated") != std::string::npos);
  write_bytes(dir / "header.ckpt", bytes.substr(0, 10));
  CHECK(read_error(dir / "header.ckpt").find("truncated header") != std::string::npos);
  write_bytes(dir / "long.ckpt", bytes + "x");
  CHECK(read_error(dir / "long.ckpt").find("padded") != std::string::npos);
  std::string magic = bytes;
  magic[0] = 'M';
  write_bytes(dir / "magic.ckpt", magic);
  CHECK(read_error(dir / "magic.ckpt").find("wrong magic") != std::string::npos);
  std::string format = bytes;
  format[8] = static_cast<char>(format[8] + 1);
  write_bytes(dir / "format.ckpt", format);
  CHECK(read_error(dir / "format.ckpt").find("checkpoint format") != std::string::npos);
  CHECK(read_error(dir / "missing.ckpt").find("cannot open") != std::string::npos);
  // Every message names the file.
  CHECK(read_error(dir / "short.ckpt").find("short.ckpt") != std::string::npos);
}

TEST_CASE("a checkpoint reader refuses lengths that run past its data") {
  CheckpointWriter out;
  out.put<uint64_t>(uint64_t{1} << 60);  // an array "length" far beyond the bytes that follow
  out.put<double>(1.0);
  CheckpointReader in(out.bytes(), "test");
  CHECK_THROWS_AS(in.get_vector<double>(), CheckpointError);
  CheckpointReader strings(out.bytes(), "test");
  CHECK_THROWS_AS(strings.get_string(), CheckpointError);
  CheckpointWriter two;
  two.put_vector(std::vector<double>{1.0, 2.0});
  CheckpointReader wrong_length(two.bytes(), "test");
  CHECK_THROWS_AS(wrong_length.get_vector<double>(3), CheckpointError);
}

// Helpers shared by the engine tests: scenes written to temporary folders, the CLI run as a
// child process, stats.csv read back.
#pragma once

#include "engine/mesh/mesh_error.hpp"
#include "engine/run.hpp"
#include "engine/sparse/hessian_pattern.hpp"
#include "engine/scene/scene.hpp"

#include <Eigen/Core>
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace nexdyn::test {

// doctest's Approx(v).epsilon(e) accepts |a - v| < e (1 + max(|a|, |v|)): for values far below 1
// that is an absolute tolerance of about e, not a relative one (a 5% check of a 2 mm/s creep
// speed would accept 50 mm/s). relative(v, e) accepts |a - v| < e max(|a|, |v|) (and a = v = 0).
inline doctest::Approx relative(double value, double tolerance) {
  return doctest::Approx(value).epsilon(tolerance).scale(std::numeric_limits<double>::min());
}

// The message of the MeshError that fn() throws, or "<no MeshError thrown>": the mesh reader
// tests compare whole one-line messages.
template <typename Fn>
std::string mesh_error_of(Fn&& fn) {
  try {
    fn();
  } catch (const MeshError& error) {
    return error.what();
  }
  return "<no MeshError thrown>";
}

// A fresh empty folder under the system temp dir, unique per call.
inline std::filesystem::path temp_dir(const std::string& tag) {
  static std::mt19937_64 rng(std::random_device{}());
  const auto dir = std::filesystem::temp_directory_path() /
                   ("nexdyn_test_" + tag + "_" + std::to_string(rng() % 1000000000));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::filesystem::path write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

inline Scene scene_from_json(const std::string& json, const std::string& tag = "scene") {
  const auto dir = temp_dir(tag);
  return load_scene(write_text(dir / (tag + ".json"), json));
}

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// The nexdyn program of this test program's own build: BUILD/nexdyn beside BUILD/tests/. Found at
// run time, since the AddressSanitizer build links the test files as the plain build compiled
// them (tests/CMakeLists.txt), with the plain build's path in NEXDYN_CLI_PATH; that path is the
// fallback.
inline std::string cli_path() {
  static const std::string path = [] {
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    const std::filesystem::path beside = self.parent_path().parent_path() / "nexdyn";
    return !ec && std::filesystem::exists(beside, ec) ? beside.string() : std::string(NEXDYN_CLI_PATH);
  }();
  return path;
}

// Runs the nexdyn binary with the given argument string, with `env` ("NAME=VALUE ...") added to
// its environment.
inline CommandResult run_cli_with_env(const std::string& env, const std::string& args) {
  const std::string cmd = env + " " + cli_path() + " " + args + " 2>&1";
  CommandResult result;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return result;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) result.output.append(buf, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// Runs the nexdyn binary with the given argument string.
inline CommandResult run_cli(const std::string& args) { return run_cli_with_env("", args); }

// run_cli on `threads` threads (--threads is appended) with the test hook NEXDYN_TEST_SPLIT_LOOPS
// (engine/cli/main.cpp) set: the process must have cut at least one parallel loop into several
// chunks, or comparing it with another thread count proves nothing.
inline CommandResult run_cli_on_threads(const std::string& args, int threads) {
  const std::filesystem::path report = temp_dir("split_loops") / "count.txt";
  std::filesystem::remove(report);
  const CommandResult result = run_cli_with_env("NEXDYN_TEST_SPLIT_LOOPS=" + report.string(),
                                                args + " --threads " + std::to_string(threads));
  std::ifstream in(report);
  long long split = -1;
  in >> split;
  INFO("nexdyn " << args << " --threads " << threads << ": loops cut into several chunks: " << split);
  CHECK(split >= 1);
  return result;
}

// Field k (0-based) of a comma-separated row.
inline std::string csv_field(const std::string& row, int k) {
  std::stringstream in(row);
  std::string field;
  for (int i = 0; i <= k; ++i) std::getline(in, field, ',');
  return field;
}

// A stats.csv row without its wall_seconds field (the 14th): what must not depend on timing.
inline std::string without_wall_seconds(const std::string& row) {
  size_t begin = 0;
  for (int i = 0; i < 13 && begin != std::string::npos; ++i) begin = row.find(',', begin) + 1;
  const size_t end = row.find(',', begin);
  return row.substr(0, begin) + (end == std::string::npos ? "" : row.substr(end + 1));
}

inline std::vector<std::string> read_lines(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// x0 with every coordinate moved by a uniform random amount in [-amount, amount].
inline std::vector<double> perturbed(const std::vector<double>& x0, double amount, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<double> x = x0;
  for (double& xi : x) xi += u(rng);
  return x;
}

// The path of a shipped scene.
inline std::filesystem::path scene_path(const std::string& name) {
  return std::filesystem::path(NEXDYN_SOURCE_DIR) / "scenes" / name;
}

// The symmetric matrix stored as an upper-triangular CSC pattern with these values, dense.
inline Eigen::MatrixXd dense_from(const CscPattern& p, const std::vector<double>& values) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(p.num_dofs, p.num_dofs);
  for (int64_t c = 0; c < p.num_dofs; ++c)
    for (int64_t k = p.col_ptr[c]; k < p.col_ptr[c + 1]; ++k) {
      H(p.row_idx[k], c) = values[k];
      H(c, p.row_idx[k]) = values[k];
    }
  return H;
}

// Vertices n of a contact stencil from its 3n x 3n slab size.
inline int64_t stencil_size(int64_t slab_size) { return std::lround(std::sqrt(double(slab_size))) / 3; }

// H += every slab of the last compute_derivatives() of a contact potential (BarrierPotential or
// FrictionPotential: stencils (num x 4), slab_begin, column-major 3n x 3n local_hessians) at its
// vertices' rows and columns; absent and held vertices (-1) are skipped.
template <class Potential>
void add_contact_slabs(const Potential& contact, Eigen::MatrixXd& H) {
  const std::vector<int32_t>& st = contact.stencils();
  const std::vector<int64_t>& begin = contact.slab_begin();
  const std::vector<double>& slabs = contact.local_hessians();
  for (int64_t k = 0; k + 1 < static_cast<int64_t>(begin.size()); ++k) {
    const int64_t size = stencil_size(begin[k + 1] - begin[k]);
    for (int a = 0; a < size; ++a)
      for (int b = 0; b < size; ++b) {
        if (st[4 * k + a] < 0 || st[4 * k + b] < 0) continue;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            H(3 * st[4 * k + a] + r, 3 * st[4 * k + b] + c) += slabs[begin[k] + (3 * b + c) * 3 * size + 3 * a + r];
      }
  }
}

}  // namespace nexdyn::test

// Reading CCD query files and running kernels/ccd over them (see ccd_queries.hpp). Parsing is
// strict because the point of the file is exact ground truth: a silently skipped or truncated
// line would make the false-negative count meaningless.
#include "engine/ccd_queries.hpp"

#include "engine/parallel.hpp"
#include "kernels/ccd/ccd.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace nexdyn {
namespace {

[[noreturn]] void fail(const std::filesystem::path& file, int64_t line, const std::string& what) {
  throw std::runtime_error(file.string() + ":" + std::to_string(line) + ": " + what);
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  const size_t e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

// Whole-token conversion: "1.5x", "", "nan", "inf" and out-of-range values are errors.
bool parse_finite_double(const std::string& token, double& value) {
  if (token.empty()) return false;
  errno = 0;
  char* end = nullptr;
  value = std::strtod(token.c_str(), &end);
  if (end != token.c_str() + token.size()) return false;
  if (errno == ERANGE && std::abs(value) > 1.0) return false;  // overflow (underflow to subnormal is fine)
  return std::isfinite(value);
}

}  // namespace

CcdQuerySet read_ccd_queries(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open CCD query file");
  CcdQuerySet set;
  std::string line;
  int64_t line_no = 0;
  bool have_kind = false;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string text = trim(line);
    if (!have_kind) {
      if (text == "# kind: vertex-face") set.kind = CcdQueryKind::vertex_face;
      else if (text == "# kind: edge-edge") set.kind = CcdQueryKind::edge_edge;
      else fail(file, line_no, "expected \"# kind: vertex-face\" or \"# kind: edge-edge\", got \"" + text + "\"");
      have_kind = true;
      continue;
    }
    if (text.empty() || text[0] == '#') continue;
    std::istringstream fields(text);
    std::vector<std::string> tokens;
    for (std::string tok; fields >> tok;) tokens.push_back(tok);
    if (tokens.size() != 28)
      fail(file, line_no, "expected 28 fields (scene file index ground_truth and 24 coordinates), got " +
                              std::to_string(tokens.size()));
    if (tokens[3] != "0" && tokens[3] != "1")
      fail(file, line_no, "ground truth must be 0 or 1, got \"" + tokens[3] + "\"");
    set.truth.push_back(tokens[3] == "1" ? 1 : 0);
    for (int i = 0; i < 24; ++i) {
      double v = 0.0;
      if (!parse_finite_double(tokens[4 + i], v))
        fail(file, line_no, "coordinate " + std::to_string(i + 1) + " is not a finite number: \"" +
                                tokens[4 + i] + "\"");
      set.points.push_back(v);
    }
  }
  if (in.bad()) throw std::runtime_error(file.string() + ": read error");
  if (!have_kind) fail(file, 1, "empty file (expected \"# kind: vertex-face\" or \"# kind: edge-edge\")");
  if (set.truth.empty()) fail(file, line_no, "no queries in file");
  return set;
}

bool ccd_query_collides(CcdQueryKind kind, const double* q) {
  Eigen::Vector3d x[8];
  for (int i = 0; i < 8; ++i) x[i] = Eigen::Vector3d(q[3 * i], q[3 * i + 1], q[3 * i + 2]);
  double toi = 1.0;
  if (kind == CcdQueryKind::vertex_face)
    return point_triangle_touch_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], 1.0, toi);
  return edge_edge_touch_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], 1.0, toi);
}

CcdQueryStats run_ccd_queries(const CcdQuerySet& queries) {
  const int64_t n = queries.size();
  std::vector<uint8_t> reported(static_cast<size_t>(n), 0);
  const auto start = std::chrono::steady_clock::now();
  // Small fixed chunks: query costs vary by orders of magnitude (grazing motions).
  parallel_for(
      n,
      [&](int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i)
          reported[i] = ccd_query_collides(queries.kind, queries.points.data() + 24 * i) ? 1 : 0;
      },
      8);
  const auto stop = std::chrono::steady_clock::now();
  CcdQueryStats stats;
  stats.queries = n;
  stats.seconds = std::chrono::duration<double>(stop - start).count();
  for (int64_t i = 0; i < n; ++i) {
    stats.positives += queries.truth[i];
    stats.false_negatives += (queries.truth[i] && !reported[i]);
    stats.false_positives += (!queries.truth[i] && reported[i]);
  }
  stats.reported = std::move(reported);
  return stats;
}

CcdQueryStats run_ccd_queries(const std::filesystem::path& file) { return run_ccd_queries(read_ccd_queries(file)); }

}  // namespace nexdyn

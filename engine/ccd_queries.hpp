// The CCD query benchmark of `nexdyn ccd` (DESIGN.md section 6): reads a query file with exact
// ground truth (format in data/ccd/README.txt; Wang et al., "A Large Scale Benchmark and an
// Inclusion-Based Algorithm for Continuous Collision Detection", TOG 2021), runs the narrow-phase
// CCD of kernels/ccd on every query and counts false negatives / false positives.
//
// A query is "reported colliding" when the CCD returns true with tmax = 1 and
//   min_distance = kCcdQueryRelativeGap * (diagonal of the bounding box of the query's 8 points).
// Ground truth 1 means "the primitives touch exactly", so the gap is tiny, 1e-11 of the query's
// size: a query is reported when the primitives come within that gap or within the rounding slack
// of kernels/ccd (64 eps * max(1, |coordinate|), plus the degenerate-angle terms of
// ccd_distance.hpp). Every ground-truth-1 query must be reported (0 false negatives); a reported
// query with ground truth 0 is a false positive. Measured on the shipped Erleben sets: gaps from
// 0 to 1e-11 give the same false positives (37 and 48, ~3.3% of the queries), nearly all near
// misses by ~1e-17 (coordinates perturbed by 1e-16) that no double-precision evaluation separates;
// 1e-6 raises them to 56 and 93. A gap of exactly 0 is ~500x slower: grazing queries that stay
// just above the slack take kCcdMaxIterations tiny steps.
//
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace nexdyn {

inline constexpr double kCcdQueryRelativeGap = 1e-11;

enum class CcdQueryKind { vertex_face, edge_edge };

struct CcdQuerySet {
  CcdQueryKind kind = CcdQueryKind::vertex_face;
  std::vector<double> points;       // (num_queries x 24) 8 points x xyz, order as in the file
  std::vector<uint8_t> truth;       // (num_queries) exact ground truth, 1 = the primitives touch
  int64_t size() const { return int64_t(truth.size()); }
};

struct CcdQueryStats {
  int64_t queries = 0;
  int64_t positives = 0;        // queries with ground truth 1
  int64_t false_negatives = 0;  // truth 1, not reported
  int64_t false_positives = 0;  // truth 0, reported
  double seconds = 0.0;         // wall time of the CCD calls only (not parsing)
  std::vector<uint8_t> reported;  // (queries) the verdict of each, 1 = reported colliding
};

// Parses a query file. Throws std::runtime_error naming the file and line on any malformed input
// (missing or unknown kind line, wrong number of fields, a field that is not a finite number,
// ground truth other than 0/1, no queries at all).
CcdQuerySet read_ccd_queries(const std::filesystem::path& file);

// The CCD verdict for one query (24 doubles): true if reported colliding (see above).
bool ccd_query_collides(CcdQueryKind kind, const double* points24);

// Runs every query (in parallel over queries, results independent of the thread count).
CcdQueryStats run_ccd_queries(const CcdQuerySet& queries);

// read_ccd_queries + run_ccd_queries.
CcdQueryStats run_ccd_queries(const std::filesystem::path& file);

}  // namespace nexdyn

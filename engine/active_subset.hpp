// The part of the scene one Newton iteration works on: the vertices of the islands still being
// solved and the tets that touch them, as sorted, disjoint index ranges.
//
// Once most islands have converged (solver/newton.cpp), assembling the whole Hessian for the few
// that have not would cost far more than their factorisations; ranges keep the loops over the
// active part as cheap as over a small scene. Bodies are contiguous in vertex and tet order, so
// a handful of ranges usually covers everything active.
#pragma once

#include "engine/parallel.hpp"

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace nexdyn {

using IndexRanges = std::vector<std::pair<int64_t, int64_t>>;  // [begin, end), increasing, disjoint

struct ActiveSubset {
  IndexRanges vertices;
  IndexRanges tets;
  std::vector<uint8_t> vertex_mask;  // (num_vertices) 1 for the vertices in `vertices`
};

// Whether a stencil of 4 vertex ids (-1 = none) has a vertex in the mask (null mask: all do).
inline bool touches(const int32_t* stencil, const uint8_t* mask) {
  if (!mask) return true;
  for (int i = 0; i < 4; ++i)
    if (stencil[i] >= 0 && mask[stencil[i]]) return true;
  return false;
}

// Appends [begin, end) to sorted ranges (begin at or past the last end), extending the last range
// when adjacent; an empty range is skipped.
inline void append_range(IndexRanges& ranges, int64_t begin, int64_t end) {
  if (begin == end) return;
  if (!ranges.empty() && ranges.back().second == begin) ranges.back().second = end;
  else ranges.emplace_back(begin, end);
}

// Appends index i to sorted ranges (i increasing).
inline void append_index(IndexRanges& ranges, int64_t i) { append_range(ranges, i, i + 1); }

// The parts of two sorted range lists that overlap.
inline IndexRanges intersect_ranges(const IndexRanges& a, const IndexRanges& b) {
  IndexRanges out;
  for (size_t i = 0, j = 0; i < a.size() && j < b.size();) {
    const int64_t lo = std::max(a[i].first, b[j].first), hi = std::min(a[i].second, b[j].second);
    if (lo < hi) out.emplace_back(lo, hi);
    (a[i].second < b[j].second) ? ++i : ++j;
  }
  return out;
}

// Calls body(begin, end) over the ranges cut into pieces of at most `grain` items, in parallel.
// Pieces depend on the ranges and the grain only.
template <typename Body>
void parallel_for_ranges(const IndexRanges& ranges, int64_t grain, Body&& body) {
  std::vector<std::pair<int64_t, int64_t>> pieces;
  for (const auto& [begin, end] : ranges)
    for (int64_t b = begin; b < end; b += grain) pieces.emplace_back(b, std::min(end, b + grain));
  parallel_for(static_cast<int64_t>(pieces.size()), [&](int64_t first, int64_t last) {
    for (int64_t k = first; k < last; ++k) body(pieces[k].first, pieces[k].second);
  }, 1);
}

// The ranges of `ranges` mapped through a monotone map of range ends (e.g. vertex -> first value
// index of its columns): [map(begin), map(end)) each, adjacent results merged.
template <typename Map>
IndexRanges mapped_ranges(const IndexRanges& ranges, Map&& map) {
  IndexRanges out;
  for (const auto& [begin, end] : ranges) {
    const int64_t b = map(begin), e = map(end);
    if (b >= e) continue;
    if (!out.empty() && out.back().second == b) out.back().second = e;
    else out.emplace_back(b, e);
  }
  return out;
}

}  // namespace nexdyn

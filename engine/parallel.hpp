// Parallel loops and reductions for the whole engine: the one place that talks to TBB.
//
// Results must not depend on the number of threads. So ranges are cut into chunks whose size is
// fixed by the caller (never by the scheduler), every chunk writes its own partial result, and the
// partials are combined in chunk order. A sum over 1 thread and over 8 threads is the same double.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace nexdyn {

// Default number of items per chunk: large enough to amortise scheduling, small enough to balance
// two cores on the smallest scenes we care about.
inline constexpr int64_t kDefaultGrain = 256;

// Calls body(begin, end) over [0, n) in chunks of `grain` items, in parallel.
template <typename Body>
void parallel_for(int64_t n, Body&& body, int64_t grain = kDefaultGrain) {
  if (n <= 0) return;
  if (n <= grain) {
    body(int64_t{0}, n);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, n, grain),
                    [&](const tbb::blocked_range<int64_t>& r) { body(r.begin(), r.end()); },
                    tbb::simple_partitioner());
}

// Deterministic sum of chunk(begin, end) -> double over [0, n): the chunk boundaries are multiples
// of `grain` whatever the thread count, and the partial sums are added in chunk order.
template <typename Chunk>
double deterministic_sum(int64_t n, Chunk&& chunk, int64_t grain = kDefaultGrain) {
  if (n <= 0) return 0.0;
  const int64_t num_chunks = (n + grain - 1) / grain;
  if (num_chunks == 1) return chunk(int64_t{0}, n);
  std::vector<double> partial(static_cast<size_t>(num_chunks));
  tbb::parallel_for(
      tbb::blocked_range<int64_t>(0, num_chunks, 1),
      [&](const tbb::blocked_range<int64_t>& r) {
        for (int64_t c = r.begin(); c < r.end(); ++c)
          partial[c] = chunk(c * grain, std::min(n, (c + 1) * grain));
      },
      tbb::simple_partitioner());
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

}  // namespace nexdyn

// Parallel loops and reductions for the whole engine: the one place that talks to TBB.
//
// Results must not depend on the number of threads. So ranges are cut into chunks whose size is
// fixed by the caller (never by the scheduler), every chunk writes its own partial result, and the
// partials are combined in chunk order. A sum over 1 thread and over 8 threads is the same double.
//
// ThreadSanitizer builds (NEXDYN_PARALLEL_STD_THREADS, set by CMake for NEXDYN_SANITIZE=thread)
// run the same chunks on plain std::threads instead: Debian's TBB is not built with TSan, so TSan
// cannot see the ordering its scheduler provides and would report races that are not there,
// while thread start and join it does see. The chunks, and so the results, are the same.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <utility>
#include <vector>

namespace nexdyn {

#if NEXDYN_PARALLEL_STD_THREADS
// chunk(c) for c in [0, num_chunks) on up to max_allowed_parallelism threads.
template <typename Chunk>
void std_thread_chunks(int64_t num_chunks, Chunk&& chunk) {
  const int64_t threads = std::min<int64_t>(
      num_chunks, static_cast<int64_t>(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
  std::atomic<int64_t> next{0};
  auto work = [&] {
    for (int64_t c = next.fetch_add(1); c < num_chunks; c = next.fetch_add(1)) chunk(c);
  };
  std::vector<std::thread> pool;
  for (int64_t t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}
#endif

// How many loops were cut into more than one chunk since the process started (parallel_for,
// for_each_chunk, deterministic_sum and grouped_sum with more than one chunk; not run_both, whose
// two sides may be empty).
// A test that compares 1 and 2 threads asserts it grew during its run: a loop of one chunk runs
// on the calling thread alone, and then "the same on 1 and 2 threads" says nothing.
inline std::atomic<int64_t>& split_loop_count() {
  static std::atomic<int64_t> count{0};
  return count;
}

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
  split_loop_count().fetch_add(1, std::memory_order_relaxed);
#if NEXDYN_PARALLEL_STD_THREADS
  std_thread_chunks((n + grain - 1) / grain, [&](int64_t c) { body(c * grain, std::min(n, (c + 1) * grain)); });
#else
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, n, grain),
                    [&](const tbb::blocked_range<int64_t>& r) { body(r.begin(), r.end()); },
                    tbb::simple_partitioner());
#endif
}

// Calls chunk(c, begin, end) for chunks c = 0, 1, ... of [0, n), each `grain` items long (the
// last may be shorter), in parallel. The chunk boundaries depend on n and grain only, so a caller
// that writes chunk c's result to slot c and combines the slots in order gets the same result on
// any number of threads. Returns the number of chunks.
template <typename Chunk>
int64_t for_each_chunk(int64_t n, int64_t grain, Chunk&& chunk) {
  if (n <= 0) return 0;
  const int64_t num_chunks = (n + grain - 1) / grain;
  if (num_chunks > 1) split_loop_count().fetch_add(1, std::memory_order_relaxed);
#if NEXDYN_PARALLEL_STD_THREADS
  std_thread_chunks(num_chunks, [&](int64_t c) { chunk(c, c * grain, std::min(n, (c + 1) * grain)); });
  return num_chunks;
#endif
  tbb::parallel_for(
      tbb::blocked_range<int64_t>(0, num_chunks, 1),
      [&](const tbb::blocked_range<int64_t>& r) {
        for (int64_t c = r.begin(); c < r.end(); ++c)
          chunk(c, c * grain, std::min(n, (c + 1) * grain));
      },
      tbb::simple_partitioner());
  return num_chunks;
}

// Deterministic sum of chunk(begin, end) -> double over [0, n): the chunk boundaries are multiples
// of `grain` whatever the thread count, and the partial sums are added in chunk order.
template <typename Chunk>
double deterministic_sum(int64_t n, Chunk&& chunk, int64_t grain = kDefaultGrain) {
  if (n <= 0) return 0.0;
  if (n <= grain) return chunk(int64_t{0}, n);
  std::vector<double> partial(static_cast<size_t>((n + grain - 1) / grain));
  for_each_chunk(n, grain, [&](int64_t c, int64_t begin, int64_t end) { partial[c] = chunk(begin, end); });
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

// Deterministic sums per group over [0, n): item i belongs to group group_of(i) (-1: left out),
// and run(begin, end) returns the sum over a run of consecutive items of one group. Each chunk of
// `grain` items is cut into such runs, and the runs' sums are added to total[group] in item
// order, so every total is the same double on any number of threads. Grouped energies use it:
// the line search of the island solver (solver/newton.cpp) tests each group on its own.
template <typename GroupOf, typename Run>
void grouped_sum(int64_t n, int64_t grain, GroupOf&& group_of, Run&& run, double* total) {
  if (n <= 0) return;
  const int64_t num_chunks = (n + grain - 1) / grain;
  std::vector<std::vector<std::pair<int32_t, double>>> runs(static_cast<size_t>(num_chunks));
  for_each_chunk(n, grain, [&](int64_t c, int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end;) {
      const int32_t g = group_of(i);
      int64_t j = i + 1;
      while (j < end && group_of(j) == g) ++j;
      if (g >= 0) runs[c].emplace_back(g, run(i, j));
      i = j;
    }
  });
  for (const auto& chunk : runs)
    for (const auto& [g, sum] : chunk) total[g] += sum;
}

// Runs a() and b() at the same time (each may use parallel_for itself).
template <typename A, typename B>
void run_both(A&& a, B&& b) {
#if NEXDYN_PARALLEL_STD_THREADS
  std::thread other(b);
  a();
  other.join();
#else
  tbb::parallel_invoke(a, b);
#endif
}

}  // namespace nexdyn

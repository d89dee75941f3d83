// For the tests that compare 1 and 2 threads: run a piece of work on a given number of threads,
// and make sure that it really had loops to share out.
#pragma once

#include "engine/parallel.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <cstdint>

namespace nexdyn::test {

// At most `threads` threads until the end of the scope. A loop cut into one chunk runs on the
// calling thread whatever the thread count, and then "the same on 1 and 2 threads" proves
// nothing: so at the end of the scope at least `min_split_loops` loops must have been cut into
// several chunks (engine/parallel.hpp, split_loop_count). Tests about one kernel also check that
// its own loop is longer than its grain.
class ThreadsScope {
 public:
  explicit ThreadsScope(int threads, int64_t min_split_loops = 1)
      : limit_(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads)),
        threads_(threads),
        min_split_loops_(min_split_loops),
        before_(split_loop_count().load()) {}
  ~ThreadsScope() {
    const int64_t split = split_loop_count().load() - before_;
    INFO("loops cut into several chunks on ", threads_, " threads: ", split);
    CHECK(split >= min_split_loops_);
  }
  ThreadsScope(const ThreadsScope&) = delete;
  ThreadsScope& operator=(const ThreadsScope&) = delete;

 private:
  tbb::global_control limit_;
  int threads_;
  int64_t min_split_loops_;
  int64_t before_;
};

}  // namespace nexdyn::test

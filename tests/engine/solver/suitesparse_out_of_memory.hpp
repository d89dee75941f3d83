// Running out of memory inside CHOLMOD, for the tests of the solver's failure paths.
//
// CHOLMOD takes all its memory through SuiteSparse's configurable allocator
// (SuiteSparse_config.malloc_func and its siblings), and checks each result: when one comes back
// null it gives up with CHOLMOD_OUT_OF_MEMORY, exactly as when the machine's memory is exhausted.
// While an object of this class lives, every such allocation fails. It changes global state:
// use it only around calls the test makes itself (doctest runs one test at a time).
#pragma once

#include "engine/sparse/cholmod_runtime.hpp"

#include <SuiteSparse_config.h>

#include <cstddef>

namespace nexdyn::test {

class SuiteSparseOutOfMemory {
 public:
  // The engine's allocator is set up first, so that the first CholmodSolver made under this
  // object does not put it back in place of the failing one.
  SuiteSparseOutOfMemory() : saved_((nexdyn::set_up_cholmod_runtime(), SuiteSparse_config)) {
    SuiteSparse_config.malloc_func = [](size_t) -> void* { return nullptr; };
    SuiteSparse_config.calloc_func = [](size_t, size_t) -> void* { return nullptr; };
    SuiteSparse_config.realloc_func = [](void*, size_t) -> void* { return nullptr; };
  }
  ~SuiteSparseOutOfMemory() { SuiteSparse_config = saved_; }
  SuiteSparseOutOfMemory(const SuiteSparseOutOfMemory&) = delete;
  SuiteSparseOutOfMemory& operator=(const SuiteSparseOutOfMemory&) = delete;

 private:
  SuiteSparse_config_struct saved_;
};

}  // namespace nexdyn::test

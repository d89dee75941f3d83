// The allocator's policy (see allocation.hpp).
#include "engine/allocation.hpp"

#include <cstdlib>  // defines __GLIBC__ where the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace nexdyn {

void keep_freed_memory() {
#if defined(__GLIBC__)
  // Fixed values turn off glibc's own sliding threshold, which starts at 128 KiB.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

}  // namespace nexdyn

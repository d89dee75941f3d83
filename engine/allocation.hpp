// How the process's allocator treats the memory the engine frees.
//
// The broad phase, the CCD sweep and the contact pattern allocate buffers sized by the scene
// (primitive boxes, box lists, pair buffers: hundreds of MB at 10,000 bodies) and free them again,
// several times a Newton iteration. glibc hands blocks above its mmap threshold, and the free
// top of its heaps, back to the kernel at once, so every next search faulted the same pages in
// again and the kernel zeroed them: 45% of a falling 10,000-body pile's step was kernel time
// (docs/performance.md, "Freed memory kept"). keep_freed_memory() raises both limits, so that
// such blocks are reused in place. It changes no result, only where the bytes come from.
#pragma once

namespace nexdyn {

// Called once by a program before it simulates (the nexdyn command does); a no-op where the C
// library is not glibc. Free memory is then returned to the kernel only beyond 1 GiB at a heap's
// top, and blocks up to 32 MiB (glibc's largest threshold) come from the heaps.
void keep_freed_memory();

}  // namespace nexdyn

// The routines CHOLMOD imports from OpenMP, BLAS and LAPACK, defined by the engine itself.
//
// CHOLMOD reaches outside itself for two things: OpenMP regions (GOMP_parallel) and the dense
// kernels of its supernodes (dgemm_, dsyrk_, dtrsm_, dpotrf_ to factorise; dtrsv_, dgemv_ to
// solve). cholmod_runtime.cpp defines all seven. A definition in the executable comes first in
// the dynamic linker's lookup, so CHOLMOD's calls reach these and not libgomp's or the BLAS's:
//   - GOMP_parallel runs the region's body once on the calling thread. A one-thread region of
//     libgomp ends in a barrier whose release is a system call, once per supernode.
//   - The BLAS and LAPACK routines run Eigen's kernels on the calling thread. Debian's threaded
//     OpenBLAS takes a global lock on every call to get its buffers, so two islands factorised
//     side by side each took twice as long, and its serial build cannot be called from two
//     threads at all. Eigen's kernels take no lock and call no other thread.
// CHOLMOD's memory comes from an allocator that starts every block on a 64-byte boundary: where
// Eigen's kernels start their packets depends on the address, so without it the factor depended
// on which thread's malloc arena an island's arrays came from. Blocks of 8 MB and more start on a
// 2 MB boundary and ask for transparent huge pages, so that a fresh factor is faulted in 2 MB at a
// time. docs/performance.md ("Piles that come to rest", second to fourth rounds) has the figures.
#pragma once

namespace nexdyn {

// Points SuiteSparse's allocator at the aligned one (the first call does; later calls only
// answer) and returns whether CHOLMOD's calls to all seven routines reach the engine's
// definitions. Every CholmodSolver calls it before CHOLMOD allocates anything; that call is also
// what keeps these definitions in a program linked with the engine's static library.
bool set_up_cholmod_runtime();

}  // namespace nexdyn

// OpenBLAS on one thread in this process, for the factorization's BLAS calls.
//
// The numeric factorization (solve/supernodal_factorize.cpp) calls BLAS from its own two
// threads. OpenBLAS's pthread build adds a pool of its own on the same two cores, whose
// threads spin for their next block: at 100K, β = 0, the two-thread factorization took
// 406 ms with OpenBLAS's default against 36–58 ms with one OpenBLAS thread
// (docs/benchmarks.md "OpenBLAS's threads in the engine").
#pragma once

namespace hdeform {

// Sets OpenBLAS's thread count to 1, once per process (later calls return at once). A
// user's own OPENBLAS_NUM_THREADS is kept, for experiments. Does nothing when the BLAS
// loaded is not OpenBLAS. Called by the factorization before its first BLAS call, so every
// host of the engine (server, CLI, benches, tests) gets it without setting anything.
void use_one_blas_thread();

}  // namespace hdeform

// The AVX2 + FMA build of the sweep kernels (compiled with -mavx2 -mfma; used only where the
// CPU has both: supernodal_sweep.cpp checks). Measured against the baseline build in
// bench/solve_bench.cpp (Solve/N/beta:b/fused_*; docs/benchmarks.md).
#define HDEFORM_SWEEP_ISA sweep_avx2
#include "engine/simd/supernodal_sweep_impl.h"

#if !defined(__AVX2__) || !defined(__FMA__)
#error "supernodal_sweep_avx2.cpp must be compiled with -mavx2 -mfma"
#endif

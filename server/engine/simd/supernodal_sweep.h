// The supernode sweeps of supernodal_solve3 (SPEC.md §Solve): forward
// (L y = b) and backward (Lᵀ x = y) over a list of supernodes of CHOLMOD's supernodal factor,
// on an interleaved n×3 work array. Built once per instruction set (supernodal_sweep.cpp:
// the target's baseline; supernodal_sweep_avx2.cpp: AVX2 + FMA, x86-64 only) and chosen at
// run time, so one binary runs everywhere and uses the wide units where the CPU has them.
//
// Internal to the solve: supernodal_solve.cpp is its only user besides the tests and benches.
#pragma once

namespace hdeform {

// What a sweep reads and writes. rows: L->s, or a schedule's renumbered copy of it.
template <class T>
struct SweepArgs {
  const int *super, *pi, *px, *rows;
  const T* Lx;  // the factor's values (L->x, or its float copy)
  double* y;    // y[3k + c]: row k, right-hand side c
};

template <class T>
struct SweepKernels {
  // Supernodes list[0 … count) in that order (list = nullptr: 0 … count−1).
  void (*forward)(const SweepArgs<T>&, const int* list, int count);
  // Supernodes list[count−1 … 0] in that order (list = nullptr: count−1 … 0).
  void (*backward)(const SweepArgs<T>&, const int* list, int count);
};

template <class T>
const SweepKernels<T>& sweep_kernels();  // the build of kernel_isa() (cpu_features.h)

}  // namespace hdeform

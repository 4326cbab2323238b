// Keeps the OpenMP parallel regions a call starts on this thread to this thread alone.
//
// CHOLMOD 3 (Debian 12) opens its loops with num_threads(CHOLMOD_OMP_NUM_THREADS) = 4,
// which omp_set_num_threads cannot lower: four threads on two cores. Under load that made
// the numeric factorization 2–3× slower (100K capsule, β = 0: 608–1112 vs 290–398 ms;
// β = 0.5: 911–2144 vs 472–633 ms, alternated in one process, OMP_WAIT_POLICY=PASSIVE),
// and on a quiet machine those loops gain nothing (docs/benchmarks.md "CHOLMOD's own
// threads"). max-active-levels is a per-thread setting in libgomp and LLVM's libomp, so other
// threads' teams (other sessions' moves) keep both cores.
#pragma once

#include <omp.h>

namespace hdeform {

class SerialOpenMP {
 public:
  SerialOpenMP() : levels_(omp_get_max_active_levels()) { omp_set_max_active_levels(0); }
  ~SerialOpenMP() { omp_set_max_active_levels(levels_); }
  SerialOpenMP(const SerialOpenMP&) = delete;
  SerialOpenMP& operator=(const SerialOpenMP&) = delete;

 private:
  int levels_;
};

}  // namespace hdeform

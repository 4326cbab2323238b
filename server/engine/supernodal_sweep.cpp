// The baseline build of the sweep kernels, and the run-time choice between the builds.
#define HDEFORM_SWEEP_ISA sweep_generic
#include "supernodal_sweep_impl.h"

#include <atomic>

namespace hdeform {

#ifdef HDEFORM_HAVE_SWEEP_AVX2
namespace sweep_avx2 {
template <class T>
SweepKernels<T> kernels();  // supernodal_sweep_avx2.cpp
}
#endif

namespace {

bool cpu_has_avx2_fma() {
#if defined(__x86_64__) || defined(__i386__)
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

std::atomic<SweepIsa>& current_isa() {
  static std::atomic<SweepIsa> isa{sweep_isa_supported(SweepIsa::avx2) ? SweepIsa::avx2
                                                                       : SweepIsa::generic};
  return isa;
}

template <class T>
struct Builds {
  SweepKernels<T> generic = sweep_generic::kernels<T>();
#ifdef HDEFORM_HAVE_SWEEP_AVX2
  SweepKernels<T> avx2 = sweep_avx2::kernels<T>();
#else
  SweepKernels<T> avx2 = generic;  // never chosen: sweep_isa_supported says no
#endif
};

}  // namespace

bool sweep_isa_supported(SweepIsa isa) {
  switch (isa) {
    case SweepIsa::generic: return true;
    case SweepIsa::avx2:
#ifdef HDEFORM_HAVE_SWEEP_AVX2
      return cpu_has_avx2_fma();
#else
      return false;
#endif
  }
  return false;
}

SweepIsa sweep_isa() { return current_isa().load(std::memory_order_relaxed); }

bool set_sweep_isa(SweepIsa isa) {
  if (!sweep_isa_supported(isa)) return false;
  current_isa().store(isa, std::memory_order_relaxed);
  return true;
}

const char* sweep_isa_name(SweepIsa isa) { return isa == SweepIsa::avx2 ? "avx2" : "generic"; }

template <class T>
const SweepKernels<T>& sweep_kernels() {
  static const Builds<T> builds;
  return sweep_isa() == SweepIsa::avx2 ? builds.avx2 : builds.generic;
}

template const SweepKernels<double>& sweep_kernels<double>();
template const SweepKernels<float>& sweep_kernels<float>();

}  // namespace hdeform

// The baseline build of the sweep kernels, and the run-time choice between the builds.
#define HDEFORM_SWEEP_ISA sweep_generic
#include "engine/simd/supernodal_sweep_impl.h"

#include "engine/simd/cpu_features.h"

namespace hdeform {

#ifdef HDEFORM_HAVE_AVX2_KERNELS
namespace sweep_avx2 {
template <class T>
SweepKernels<T> kernels();  // supernodal_sweep_avx2.cpp
}
#endif

namespace {

template <class T>
struct Builds {
  SweepKernels<T> generic = sweep_generic::kernels<T>();
#ifdef HDEFORM_HAVE_AVX2_KERNELS
  SweepKernels<T> avx2 = sweep_avx2::kernels<T>();
#else
  SweepKernels<T> avx2 = generic;  // never chosen: isa_supported says no
#endif
};

}  // namespace

template <class T>
const SweepKernels<T>& sweep_kernels() {
  static const Builds<T> builds;
  return kernel_isa() == Isa::avx2 ? builds.avx2 : builds.generic;
}

template const SweepKernels<double>& sweep_kernels<double>();
template const SweepKernels<float>& sweep_kernels<float>();

}  // namespace hdeform

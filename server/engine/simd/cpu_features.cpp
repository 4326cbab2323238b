#include "engine/simd/cpu_features.h"

#include <atomic>

namespace hdeform {

namespace {

std::atomic<Isa>& current_isa() {
  static std::atomic<Isa> isa{isa_supported(Isa::avx2) ? Isa::avx2 : Isa::generic};
  return isa;
}

}  // namespace

bool isa_supported(Isa isa) {
  switch (isa) {
    case Isa::generic: return true;
    case Isa::avx2:
#if defined(HDEFORM_HAVE_AVX2_KERNELS) && (defined(__x86_64__) || defined(__i386__))
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
      return false;
#endif
  }
  return false;
}

Isa kernel_isa() { return current_isa().load(std::memory_order_relaxed); }

bool set_kernel_isa(Isa isa) {
  if (!isa_supported(isa)) return false;
  current_isa().store(isa, std::memory_order_relaxed);
  return true;
}

const char* isa_name(Isa isa) { return isa == Isa::avx2 ? "avx2" : "generic"; }

}  // namespace hdeform

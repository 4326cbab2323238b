// Which build of the engine's hand-vectorized kernels runs: the baseline x86-64 one, or the
// AVX2 + FMA one (files *_avx2.cpp, compiled with -mavx2 -mfma, x86-64 only). The default is
// the best this CPU supports, so one binary runs everywhere and uses the wide units where the
// CPU has them. Users: supernodal_sweep (the solve) and guidance (one handle's field).
#pragma once

namespace hdeform {

enum class Isa { generic, avx2 };

// True if this build has the kernels for `isa` and this CPU runs them.
bool isa_supported(Isa isa);
// The build the kernels use: the best supported one unless set_kernel_isa chose another
// (tests and benches compare them; results differ in rounding only).
Isa kernel_isa();
// Returns false (and changes nothing) if `isa` is not supported. Process-wide; not meant to
// be called while kernels run.
bool set_kernel_isa(Isa isa);
const char* isa_name(Isa isa);

}  // namespace hdeform

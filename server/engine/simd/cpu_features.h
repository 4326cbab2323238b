// Which build of the hand-vectorized kernels runs: the baseline x86-64 one, or the AVX2 one
// (files *_avx2.cpp, x86-64 only; the engine's also use FMA). The default is the best this CPU
// supports, so one binary runs everywhere and uses the wide units where the CPU has them.
// Users: supernodal_sweep (the solve), guidance (one handle's field), the measures and normals,
// and the service's frame quantization (server/service/quantize_avx2.cpp, same bytes).
#pragma once

namespace hdeform {

enum class Isa { generic, avx2 };

// True if this build has the kernels for `isa` and this CPU runs them.
bool isa_supported(Isa isa);
// The build the kernels use: the best supported one unless set_kernel_isa chose another
// (tests and benches compare them; results differ in rounding only, or not at all).
Isa kernel_isa();
// Returns false (and changes nothing) if `isa` is not supported. Process-wide; not meant to
// be called while kernels run.
bool set_kernel_isa(Isa isa);
const char* isa_name(Isa isa);

}  // namespace hdeform

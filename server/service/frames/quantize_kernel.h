// The loops of the QUANTIZED encodings (frame_encoding.h: bounding_box, quantize_onto,
// quantize_energies), the generic build and the AVX2 one (quantize_avx2.cpp, x86-64 only;
// chosen when the engine's kernel_isa() is Isa::avx2).
// Internal to frame_encoding.cpp (tests compare the builds through its functions): both
// write the same bytes and give the same answer for every input, NaN and infinities included.
#pragma once

#include <cstddef>
#include <cstdint>

namespace hdeform::service::detail {

// The grid of a QUANTIZED frame (deform.proto Box): per axis k, a position x goes to
// t = (x − lo[k]) · scale[k] in double (float would lose the last bits), clamped to [0, 65535]
// (NaN to 0) and then rounded to nearest. scale[k] = 65535 / extent, or 0 on a flat axis
// (every q is 0, decoded as lo).
struct QuantizeGrid {
  double lo[3];
  double scale[3];
};

// Vertices [begin, end) of p (xyz float32, 3 per vertex) and nrm (the same, or null: normal
// bytes 0) as 8 bytes each at out + 8·i: 3 × uint16 q, 2 × int8 octahedral normal. Returns
// false if a vertex is outside the grid: t = (x − lo)·scale rounds below 0 or above 65535, or
// x ≠ lo on a flat axis, or x is NaN.
bool quantize_range(const float* p, const float* nrm, std::size_t begin, std::size_t end,
                    const QuantizeGrid& grid, unsigned char* out);

// The same for the largest multiple of 8 vertices in [begin, end) (AVX2; callers check
// kernel_isa()); returns how many it did, from begin. `inside` is and-ed with its answer.
std::size_t quantize_range_avx2(const float* p, const float* nrm, std::size_t begin,
                                std::size_t end, const QuantizeGrid& grid, unsigned char* out,
                                bool* inside);

// lo[k] = min, hi[k] = max of lo[k], hi[k] and axis k of vertices [begin, end): a NaN
// vertex is skipped (a NaN already in lo or hi stays). The AVX2 build does the largest multiple of 8 and returns how many it did.
void box_range(const float* p, std::size_t begin, std::size_t end, float lo[3], float hi[3]);
std::size_t box_range_avx2(const float* p, std::size_t begin, std::size_t end, float lo[3],
                           float hi[3]);

// top = max(top, the finite values of e[begin, end)); AVX2: the largest multiple of 8, and
// returns how many it did.
void max_finite_range(const float* e, std::size_t begin, std::size_t end, float* top);
std::size_t max_finite_range_avx2(const float* e, std::size_t begin, std::size_t end, float* top);

// q[l] = round(clamp(e[l] · inv, 0, 1) · 65535), 65535 where e[l] is not finite, for l in
// [begin, end). AVX2: the largest multiple of 16, and returns how many it did.
void quantize_energy_range(const float* e, std::size_t begin, std::size_t end, float inv,
                           std::uint16_t* q);
std::size_t quantize_energy_range_avx2(const float* e, std::size_t begin, std::size_t end,
                                       float inv, std::uint16_t* q);

}  // namespace hdeform::service::detail

// The one-handle, no-stretch case of guidance_field (guidance.h) in AVX2 + FMA, four triangles
// at a time (guidance_rotation_avx2.cpp; used when kernel_isa() is Isa::avx2). Internal to
// guidance.cpp and its tests. Plain pointers only: this header is also compiled with
// -mavx2, where Eigen's types would change their alignment.
#pragma once

#include <complex>
#include <cstddef>

namespace hdeform::detail {

// For triangles l0 ≤ l < l1 in blocks of four, R_l the rotation of the unit quaternion
// (w, s·axis) with w + i s = turn[F0] · turn[F1] · turn[F2] (F row-major m × 3):
//   g + 9l ← (I − n nᵀ) R_lᵀ as 3 × 3 row-major (n = normals + 3l, row-major m × 3),
//   Rn + 3l ← R_l n as 3 doubles when Rn is not null (row-major m × 3).
// Returns the first triangle not done (l1 − (l1 − l0) mod 4); the caller does the rest.
std::ptrdiff_t guidance_rotation_avx2(const int* F, const double* normals,
                                      const std::complex<double>* turn, const double axis[3],
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, double* g,
                                      double* Rn);

// turn[v] = (cos(φ_v · third), sin(φ_v · third)) for v0 ≤ v < v1, φ = phi[v]. Arguments
// within ±kTurnPolyMax by polynomials (Taylor to x¹⁹ / x¹⁸: truncation below 1e-17,
// a few ulp of rounding), the rest by std::cos / std::sin.
inline constexpr double kTurnPolyMax = 1.1;  // > π/3: |φ θ/6| with φ ∈ [0, 1], θ ≤ 2π
void vertex_turns_avx2(const double* phi, std::ptrdiff_t v0, std::ptrdiff_t v1, double third,
                       std::complex<double>* turn);

}  // namespace hdeform::detail

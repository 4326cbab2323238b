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
//   R_xyzw + 4l ← (s·axis, w) when R_xyzw is not null (Eigen's quaternion coefficients).
// Returns the first triangle not done (l1 − (l1 − l0) mod 4); the caller does the rest.
std::ptrdiff_t guidance_rotation_avx2(const int* F, const double* normals,
                                      const std::complex<double>* turn, const double axis[3],
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, double* g,
                                      double* R_xyzw);

}  // namespace hdeform::detail

// The per-triangle loop of measure() (measures.h) in AVX2 + FMA
// (measure_triangles_avx2.cpp; used when kernel_isa() is Isa::avx2). Internal to measures.cpp
// and its tests. Plain pointers only: this header is also compiled with -mavx2, where
// Eigen's types would change their alignment.
#pragma once

#include <cstddef>

namespace hdeform::detail {

// Running sums and maxima of the measures over a range of triangles.
struct MeasureSums {
  double E = 0;              // Σ a_l ‖r_l‖²_F
  double iso = 0, conf = 0;  // Σ a_l e_iso, Σ a_l e_conf
  double area_deformed = 0;  // Σ a'_l
  double max_ef2 = 0, max_iso = 0, max_conf = 0;
  long flips = 0;
};

// measure()'s terms for triangles l0 ≤ l < l1 in blocks of four, added to `sums`:
// F (m × 3), X (n × 3), grads (m × 9: ∇φ₀, ∇φ₁, ∇φ₂), g (3m × 3), Rn (R_l n_l, m × 3), all
// row-major; area (m). `ef2` (m) and `face_w` (m × 3) are written where not null.
// Returns the first triangle not done (l1 − (l1 − l0) mod 4); the caller does the rest.
std::ptrdiff_t measure_triangles_avx2(const int* F, const double* X, const double* grads,
                                      const double* g, const double* area, const double* Rn,
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, float* ef2,
                                      double* face_w, MeasureSums& sums);

}  // namespace hdeform::detail

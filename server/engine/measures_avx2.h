// measure()'s per-triangle loop (measures.h, SPEC.md §Measures) in AVX2 + FMA, four triangles
// per vector (measures_avx2.cpp; used when kernel_isa() is Isa::avx2). Internal to
// measures.cpp and its tests. Plain pointers only: measures_avx2.cpp is compiled with
// -mavx2, where Eigen's types would change their alignment.
#pragma once

#include <cstddef>

namespace hdeform::detail {

// The sums and maxima measure() reduces over triangles (maxima start at 0: every term is ≥ 0).
struct MeasureSums {
  double E = 0, iso_sum = 0, conf_sum = 0, area_deformed = 0;
  double max_ef2 = 0, max_iso = 0, max_conf = 0;
  long flips = 0;
};

// Triangles l0 ≤ l < l1 in blocks of four, added to `acc`. Layouts (all row-major): F m × 3,
// X n × 3, grads m × 9, g 3m × 3 (block l at 9l), area m, normals m × 3, R_xyzw m × 4
// (Eigen's quaternion coefficients); ef2 (m floats) and face_w (m × 3) written if not null.
// Returns the first triangle not done (l1 − (l1 − l0) mod 4); the caller does the rest.
std::ptrdiff_t measure_triangles_avx2(const int* F, const double* X, const double* grads,
                                      const double* g, const double* area,
                                      const double* normals, const double* R_xyzw,
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, float* ef2,
                                      double* face_w, MeasureSums& acc);

}  // namespace hdeform::detail

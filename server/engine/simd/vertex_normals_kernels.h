// vertex_normals' two passes (vertex_normals.h) in AVX2 (vertex_normals_avx2.cpp; used when
// kernel_isa() is Isa::avx2), with the scalar loops' rounding: products rounded before they
// are subtracted, sums in ascending triangle order, ‖s‖² as (x² + y²) + z² (Eigen's order),
// then a division: the normals are bit for bit those of the scalar loops. Internal to
// vertex_normals.cpp and its tests. Plain pointers only: this header is also compiled with
// -mavx2, where Eigen's types would change their alignment.
#pragma once

#include <cstddef>

namespace hdeform::detail {

// face_w row t = (x₁ − x₀) × (x₂ − x₀) for triangles t0 ≤ t < t1 (F, X, face_w row-major).
void face_weights_avx2(const int* F, const double* X, std::ptrdiff_t t0, std::ptrdiff_t t1,
                       double* face_w);

// N row v = s / ‖s‖ (s itself where ‖s‖ is not > 0), s the sum of face_w rows over
// triangles[offsets[v] … offsets[v+1]), for vertices v0 ≤ v < v1.
void gather_normals_avx2(const int* offsets, const int* triangles, const double* face_w,
                         std::ptrdiff_t v0, std::ptrdiff_t v1, double* N);

}  // namespace hdeform::detail

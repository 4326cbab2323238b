// vertex_normals_kernels.h, compiled with -mavx2 -mfma -ffp-contract=off (no fused
// multiply-add may change the rounding). One row per vector, lanes x y z (the fourth lane
// masked off: rows are read and written as three doubles, never past them).
#include "engine/simd/vertex_normals_kernels.h"
#include "engine/simd/xyz_lanes_avx2.h"

#include <immintrin.h>

#if !defined(__AVX2__)
#error "vertex_normals_avx2.cpp must be compiled with -mavx2"
#endif

namespace hdeform::detail {

void face_weights_avx2(const int* F, const double* X, std::ptrdiff_t t0, std::ptrdiff_t t1,
                       double* face_w) {
  const __m256i xyz = _mm256_setr_epi64x(-1, -1, -1, 0);
  for (std::ptrdiff_t t = t0; t < t1; ++t) {
    const int* f = F + 3 * t;
    const __m256d x0 = load_row(X, f[0], xyz);
    const __m256d e1 = _mm256_sub_pd(load_row(X, f[1], xyz), x0);
    const __m256d e2 = _mm256_sub_pd(load_row(X, f[2], xyz), x0);
    _mm256_maskstore_pd(face_w + 3 * t, xyz, cross(e1, e2));  // as Eigen's cross
  }
}

void gather_normals_avx2(const int* offsets, const int* triangles, const double* face_w,
                         std::ptrdiff_t v0, std::ptrdiff_t v1, double* N) {
  const __m256i xyz = _mm256_setr_epi64x(-1, -1, -1, 0);
  for (std::ptrdiff_t v = v0; v < v1; ++v) {
    __m256d s = _mm256_setzero_pd();
    for (int i = offsets[v]; i < offsets[v + 1]; ++i)
      s = _mm256_add_pd(s, load_row(face_w, triangles[i], xyz));
    const __m256d sq = _mm256_mul_pd(s, s);
    const __m128d xy = _mm256_castpd256_pd128(sq);
    const __m128d len2 = _mm_add_sd(_mm_add_sd(xy, _mm_unpackhi_pd(xy, xy)),
                                    _mm256_extractf128_pd(sq, 1));  // (x² + y²) + z²
    const double len = _mm_cvtsd_f64(_mm_sqrt_sd(len2, len2));
    if (len > 0) s = _mm256_div_pd(s, _mm256_set1_pd(len));
    _mm256_maskstore_pd(N + 3 * v, xyz, s);
  }
}

}  // namespace hdeform::detail

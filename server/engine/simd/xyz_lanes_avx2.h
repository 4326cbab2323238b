// Vectors with lanes (x, y, z, ·) for the AVX2 kernels that work one row per vector
// (measure_triangles_avx2.cpp, vertex_normals_avx2.cpp). Include only from files compiled
// with -mavx2 -ffp-contract=off.
#pragma once

#include <immintrin.h>

#include <cstddef>

namespace hdeform::detail {

// Row v of an n × 3 row-major array: three doubles read, never past them (`xyz` masks
// lanes x, y, z; the fourth lane is 0).
inline __m256d load_row(const double* A, int v, __m256i xyz) {
  return _mm256_maskload_pd(A + 3 * static_cast<std::ptrdiff_t>(v), xyz);
}

// a × b = a.yzx · b.zxy − a.zxy · b.yzx, products rounded and then subtracted as in Eigen's
// cross (the file must be built without contraction): bit for bit Eigen's result.
inline __m256d cross(__m256d a, __m256d b) {
  return _mm256_sub_pd(
      _mm256_mul_pd(_mm256_permute4x64_pd(a, 0xC9), _mm256_permute4x64_pd(b, 0xD2)),
      _mm256_mul_pd(_mm256_permute4x64_pd(a, 0xD2), _mm256_permute4x64_pd(b, 0xC9)));
}

}  // namespace hdeform::detail

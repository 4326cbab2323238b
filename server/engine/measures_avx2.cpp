// measures_avx2.h, compiled with -mavx2 -mfma. Lanes are triangles; the per-triangle rows
// (gradients, g, normals, R_l) and the corners' positions are gathered into four-triangle
// vectors. The formulas are measures.cpp's, term for term; only the order of the sums
// differs (four lane sums, added at the end).
#include "measures_avx2.h"

#include <immintrin.h>

#if !defined(__AVX2__) || !defined(__FMA__)
#error "measures_avx2.cpp must be compiled with -mavx2 -mfma"
#endif

namespace hdeform::detail {

namespace {

inline __m256d gather(const double* base, __m128i idx) {
  return _mm256_mask_i32gather_pd(_mm256_setzero_pd(), base, idx,
                                  _mm256_castsi256_pd(_mm256_set1_epi64x(-1)), 8);
}
inline __m128i gather_int(const int* base, __m128i idx) {
  return _mm_mask_i32gather_epi32(_mm_setzero_si128(), base, idx, _mm_set1_epi32(-1), 4);
}
inline double hsum(__m256d v) {
  const __m128d s = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
  return _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)));
}
inline double hmax(__m256d v) {
  const __m128d s = _mm_max_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
  return _mm_cvtsd_f64(_mm_max_sd(s, _mm_unpackhi_pd(s, s)));
}

}  // namespace

std::ptrdiff_t measure_triangles_avx2(const int* F, const double* X, const double* grads,
                                      const double* g, const double* area,
                                      const double* normals, const double* R_xyzw,
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, float* ef2,
                                      double* face_w, MeasureSums& acc) {
  const __m128i by3 = _mm_setr_epi32(0, 3, 6, 9), by9 = _mm_setr_epi32(0, 9, 18, 27);
  const __m256d zero = _mm256_setzero_pd(), half = _mm256_set1_pd(0.5),
                two = _mm256_set1_pd(2.0);
  __m256d E = zero, iso = zero, conf = zero, area_def = zero;
  __m256d max_ef2 = zero, max_iso = zero, max_conf = zero;
  long flips = 0;
  std::ptrdiff_t l = l0;
  for (; l + 4 <= l1; l += 4) {
    // Corner positions: x[k][j] = X(F(l + lane, k), j).
    __m256d x[3][3];
    for (int k = 0; k < 3; ++k) {
      const __m128i v3 = _mm_mullo_epi32(gather_int(F + 3 * l + k, by3), _mm_set1_epi32(3));
      for (int j = 0; j < 3; ++j) x[k][j] = gather(X + j, v3);
    }
    // Y'_l(i, j) = Σ_k ∇φ_k[i] x_k[j]; r_l = Y'_l − g_l.
    const double* G = grads + 9 * l;
    const double* gl = g + 9 * l;
    __m256d r2 = zero, sum_sq = zero;
    for (int i = 0; i < 3; ++i) {
      const __m256d d0 = gather(G + i, by9), d1 = gather(G + 3 + i, by9),
                    d2 = gather(G + 6 + i, by9);
      for (int j = 0; j < 3; ++j) {
        const __m256d y = _mm256_fmadd_pd(
            d2, x[2][j], _mm256_fmadd_pd(d1, x[1][j], _mm256_mul_pd(d0, x[0][j])));
        const __m256d r = _mm256_sub_pd(y, gather(gl + 3 * i + j, by9));
        r2 = _mm256_fmadd_pd(r, r, r2);
        sum_sq = _mm256_fmadd_pd(y, y, sum_sq);
      }
    }
    const __m256d a = _mm256_loadu_pd(area + l);
    E = _mm256_fmadd_pd(a, r2, E);
    max_ef2 = _mm256_max_pd(r2, max_ef2);  // a NaN r2 leaves the max as it is (std::max's way)
    if (ef2) _mm_storeu_ps(ef2 + l, _mm256_cvtpd_ps(r2));

    // c = (x1 − x0) × (x2 − x0): twice the deformed area, the normals' weight.
    const __m256d e0 = _mm256_sub_pd(x[1][0], x[0][0]), e1 = _mm256_sub_pd(x[1][1], x[0][1]),
                  e2 = _mm256_sub_pd(x[1][2], x[0][2]);
    const __m256d f0 = _mm256_sub_pd(x[2][0], x[0][0]), f1 = _mm256_sub_pd(x[2][1], x[0][1]),
                  f2 = _mm256_sub_pd(x[2][2], x[0][2]);
    // Without FMA, as Eigen's cross product: the vertex normals built from these weights are
    // then bit for bit those of frames without measures (vertex_normals' own pass).
    const __m256d c0 = _mm256_sub_pd(_mm256_mul_pd(e1, f2), _mm256_mul_pd(e2, f1));
    const __m256d c1 = _mm256_sub_pd(_mm256_mul_pd(e2, f0), _mm256_mul_pd(e0, f2));
    const __m256d c2 = _mm256_sub_pd(_mm256_mul_pd(e0, f1), _mm256_mul_pd(e1, f0));
    if (face_w) {
      alignas(32) double c[3][4];
      _mm256_store_pd(c[0], c0);
      _mm256_store_pd(c[1], c1);
      _mm256_store_pd(c[2], c2);
      double* w = face_w + 3 * l;
      for (int t = 0; t < 4; ++t)
        for (int d = 0; d < 3; ++d) w[3 * t + d] = c[d][t];
    }
    const __m256d cc = _mm256_fmadd_pd(c2, c2, _mm256_fmadd_pd(c1, c1, _mm256_mul_pd(c0, c0)));
    const __m256d a_def = _mm256_mul_pd(half, _mm256_sqrt_pd(cc));
    area_def = _mm256_add_pd(area_def, a_def);

    // σ₁² + σ₂² = ‖Y'_l‖²_F, σ₁σ₂ = a'_l / a_l.
    const __m256d prod = _mm256_div_pd(a_def, a);
    const __m256d sum = _mm256_sqrt_pd(_mm256_max_pd(zero, _mm256_fmadd_pd(two, prod, sum_sq)));
    const __m256d e_iso = _mm256_add_pd(_mm256_fnmadd_pd(two, sum, sum_sq), two);
    const __m256d e_conf =
        _mm256_mul_pd(half, _mm256_max_pd(zero, _mm256_fnmadd_pd(two, prod, sum_sq)));
    iso = _mm256_fmadd_pd(a, e_iso, iso);
    conf = _mm256_fmadd_pd(a, e_conf, conf);
    max_iso = _mm256_max_pd(e_iso, max_iso);
    max_conf = _mm256_max_pd(e_conf, max_conf);

    // Flip: c · (R_l n_l) < 0, R_l n = n + w t + q × t with t = 2 q × n.
    const double* N = normals + 3 * l;
    const __m256d n0 = _mm256_setr_pd(N[0], N[3], N[6], N[9]);
    const __m256d n1 = _mm256_setr_pd(N[1], N[4], N[7], N[10]);
    const __m256d n2 = _mm256_setr_pd(N[2], N[5], N[8], N[11]);
    const __m128i by4 = _mm_setr_epi32(0, 4, 8, 12);
    const double* Q = R_xyzw + 4 * l;
    const __m256d qx = gather(Q, by4), qy = gather(Q + 1, by4), qz = gather(Q + 2, by4),
                  qw = gather(Q + 3, by4);
    const __m256d t0 = _mm256_mul_pd(two, _mm256_fmsub_pd(qy, n2, _mm256_mul_pd(qz, n1)));
    const __m256d t1 = _mm256_mul_pd(two, _mm256_fmsub_pd(qz, n0, _mm256_mul_pd(qx, n2)));
    const __m256d t2 = _mm256_mul_pd(two, _mm256_fmsub_pd(qx, n1, _mm256_mul_pd(qy, n0)));
    const __m256d m0 = _mm256_add_pd(_mm256_fmadd_pd(qw, t0, n0),
                                     _mm256_fmsub_pd(qy, t2, _mm256_mul_pd(qz, t1)));
    const __m256d m1 = _mm256_add_pd(_mm256_fmadd_pd(qw, t1, n1),
                                     _mm256_fmsub_pd(qz, t0, _mm256_mul_pd(qx, t2)));
    const __m256d m2 = _mm256_add_pd(_mm256_fmadd_pd(qw, t2, n2),
                                     _mm256_fmsub_pd(qx, t1, _mm256_mul_pd(qy, t0)));
    const __m256d dot = _mm256_fmadd_pd(c2, m2, _mm256_fmadd_pd(c1, m1, _mm256_mul_pd(c0, m0)));
    flips += __builtin_popcount(static_cast<unsigned>(
        _mm256_movemask_pd(_mm256_cmp_pd(dot, zero, _CMP_LT_OQ))));
  }
  acc.E += hsum(E);
  acc.iso_sum += hsum(iso);
  acc.conf_sum += hsum(conf);
  acc.area_deformed += hsum(area_def);
  const double mx[3] = {hmax(max_ef2), hmax(max_iso), hmax(max_conf)};
  if (mx[0] > acc.max_ef2) acc.max_ef2 = mx[0];
  if (mx[1] > acc.max_iso) acc.max_iso = mx[1];
  if (mx[2] > acc.max_conf) acc.max_conf = mx[2];
  acc.flips += flips;
  return l;
}

}  // namespace hdeform::detail

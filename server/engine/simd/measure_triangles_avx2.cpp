// measure_triangles.h, compiled with -mavx2 -mfma -ffp-contract=off. Each triangle is worked
// in one vector with lanes (x, y, z, 0): corners, edges, the rows of Y'_l and r_l, the cross
// product. Only its four per-triangle sums (‖r‖², ‖Y'‖², ‖c‖², c · R n) need a horizontal
// add, four triangles at once; the rest then runs with lanes = four triangles. No gathers:
// on this machine's CPU (AMD EPYC, Zen 4) a version with lanes = triangles throughout, its
// rows gathered, was no faster than the scalar loop (2.86 vs 2.97 ms, Phase/100000/measures).
#include "engine/simd/measure_triangles.h"
#include "engine/simd/xyz_lanes_avx2.h"

#include <immintrin.h>

#if !defined(__AVX2__) || !defined(__FMA__)
#error "measure_triangles_avx2.cpp must be compiled with -mavx2 -mfma"
#endif

namespace hdeform::detail {

namespace {

// The four per-lane vectors one triangle leaves for the horizontal sums.
struct TriangleLanes {
  __m256d rr, yy, cc, dot;
};

// Triangle l: f = F + 3l, G = grads + 9l, gl = g + 9l, rn = Rn + 3l, w = face_w + 3l.
// `xyz` masks the three lanes: rows are read and written as three doubles, never past them.
inline TriangleLanes triangle(const int* f, const double* X, const double* G, const double* gl,
                              const double* rn, double* w, __m256i xyz) {
  const __m256d x0 = load_row(X, f[0], xyz), x1 = load_row(X, f[1], xyz),
                x2 = load_row(X, f[2], xyz);
  const __m256d e1 = _mm256_sub_pd(x1, x0), e2 = _mm256_sub_pd(x2, x0);
  // Row i of Y'_l = Σ_k ∇φ_k[i] x_kᵀ = ∇φ₁[i] e₁ᵀ + ∇φ₂[i] e₂ᵀ (∇φ₀ = −∇φ₁ − ∇φ₂).
  __m256d rr = _mm256_setzero_pd(), yy = _mm256_setzero_pd();
  for (int i = 0; i < 3; ++i) {
    const __m256d y = _mm256_fmadd_pd(_mm256_broadcast_sd(G + 6 + i), e2,
                                      _mm256_mul_pd(_mm256_broadcast_sd(G + 3 + i), e1));
    const __m256d r = _mm256_sub_pd(y, _mm256_maskload_pd(gl + 3 * i, xyz));
    rr = _mm256_fmadd_pd(r, r, rr);
    yy = _mm256_fmadd_pd(y, y, yy);
  }
  // c = e₁ × e₂ as Eigen's cross: the vertex normals from these weights are bit for bit
  // those of frames without measures (vertex_normals' own pass).
  const __m256d c = cross(e1, e2);
  if (w) _mm256_maskstore_pd(w, xyz, c);
  return {rr, yy, _mm256_mul_pd(c, c), _mm256_mul_pd(c, _mm256_maskload_pd(rn, xyz))};
}

// Lane t of the result: the sum of v_t's four lanes.
inline __m256d lane_sums(__m256d v0, __m256d v1, __m256d v2, __m256d v3) {
  const __m256d h01 = _mm256_hadd_pd(v0, v1);  // v0[0]+v0[1], v1[0]+v1[1], v0[2]+v0[3], v1[2]+v1[3]
  const __m256d h23 = _mm256_hadd_pd(v2, v3);
  return _mm256_add_pd(_mm256_permute2f128_pd(h01, h23, 0x20),
                       _mm256_permute2f128_pd(h01, h23, 0x31));
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
                                      const double* g, const double* area, const double* Rn,
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, float* ef2,
                                      double* face_w, MeasureSums& sums) {
  const __m256i xyz = _mm256_setr_epi64x(-1, -1, -1, 0);
  const __m256d zero = _mm256_setzero_pd(), half = _mm256_set1_pd(0.5),
                two = _mm256_set1_pd(2.0);
  __m256d E = zero, iso = zero, conf = zero, area_def = zero;
  __m256d max_ef2 = zero, max_iso = zero, max_conf = zero;
  long flips = 0;
  std::ptrdiff_t l = l0;
  for (; l + 4 <= l1; l += 4) {
    TriangleLanes t[4];
    for (int k = 0; k < 4; ++k) {
      const std::ptrdiff_t lk = l + k;
      t[k] = triangle(F + 3 * lk, X, grads + 9 * lk, g + 9 * lk, Rn + 3 * lk,
                      face_w ? face_w + 3 * lk : nullptr, xyz);
    }
    // From here on, lanes are the four triangles.
    const __m256d r2 = lane_sums(t[0].rr, t[1].rr, t[2].rr, t[3].rr);
    const __m256d sum_sq = lane_sums(t[0].yy, t[1].yy, t[2].yy, t[3].yy);
    const __m256d cc = lane_sums(t[0].cc, t[1].cc, t[2].cc, t[3].cc);
    const __m256d dot = lane_sums(t[0].dot, t[1].dot, t[2].dot, t[3].dot);
    const __m256d a = _mm256_loadu_pd(area + l);
    E = _mm256_fmadd_pd(a, r2, E);
    max_ef2 = _mm256_max_pd(r2, max_ef2);  // a NaN r2 leaves the max as it is (std::max's way)
    if (ef2) _mm_storeu_ps(ef2 + l, _mm256_cvtpd_ps(r2));
    const __m256d a_def = _mm256_mul_pd(half, _mm256_sqrt_pd(cc));
    area_def = _mm256_add_pd(area_def, a_def);
    // σ₁² + σ₂² = ‖Y'_l‖²_F, σ₁σ₂ = a'_l / a_l (measures.cpp).
    const __m256d prod = _mm256_div_pd(a_def, a);
    const __m256d sum = _mm256_sqrt_pd(_mm256_max_pd(zero, _mm256_fmadd_pd(two, prod, sum_sq)));
    const __m256d e_iso = _mm256_add_pd(_mm256_fnmadd_pd(two, sum, sum_sq), two);
    const __m256d e_conf =
        _mm256_mul_pd(half, _mm256_max_pd(zero, _mm256_fnmadd_pd(two, prod, sum_sq)));
    iso = _mm256_fmadd_pd(a, e_iso, iso);
    conf = _mm256_fmadd_pd(a, e_conf, conf);
    max_iso = _mm256_max_pd(e_iso, max_iso);
    max_conf = _mm256_max_pd(e_conf, max_conf);
    flips += __builtin_popcount(
        static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(dot, zero, _CMP_LT_OQ))));
  }
  sums.E += hsum(E);
  sums.iso += hsum(iso);
  sums.conf += hsum(conf);
  sums.area_deformed += hsum(area_def);
  const double mx[3] = {hmax(max_ef2), hmax(max_iso), hmax(max_conf)};
  if (mx[0] > sums.max_ef2) sums.max_ef2 = mx[0];
  if (mx[1] > sums.max_iso) sums.max_iso = mx[1];
  if (mx[2] > sums.max_conf) sums.max_conf = mx[2];
  sums.flips += flips;
  return l;
}

}  // namespace hdeform::detail

// guidance_rotation.h, compiled with -mavx2 -mfma. Lanes are triangles: the turns and
// normals are loaded into four-triangle vectors, R_l and g_l computed as nine vectors each,
// and g_l transposed back to nine contiguous doubles per triangle (two 4 × 4 transposes and
// one column). Same formulas as guidance.cpp's loop (Eigen's quaternion → matrix).
#include "engine/simd/guidance_rotation.h"

#include <immintrin.h>

#include <cmath>

#if !defined(__AVX2__) || !defined(__FMA__)
#error "guidance_rotation_avx2.cpp must be compiled with -mavx2 -mfma"
#endif

namespace hdeform::detail {

namespace {

// Rows r0..r3 (four lanes each) → lane t's four values at out[t] (4 × 4 transpose).
inline void transpose_store(__m256d r0, __m256d r1, __m256d r2, __m256d r3, double* o0,
                            double* o1, double* o2, double* o3) {
  const __m256d a = _mm256_unpacklo_pd(r0, r1);  // r0[0] r1[0] r0[2] r1[2]
  const __m256d b = _mm256_unpackhi_pd(r0, r1);  // r0[1] r1[1] r0[3] r1[3]
  const __m256d c = _mm256_unpacklo_pd(r2, r3);
  const __m256d d = _mm256_unpackhi_pd(r2, r3);
  _mm256_storeu_pd(o0, _mm256_permute2f128_pd(a, c, 0x20));
  _mm256_storeu_pd(o1, _mm256_permute2f128_pd(b, d, 0x20));
  _mm256_storeu_pd(o2, _mm256_permute2f128_pd(a, c, 0x31));
  _mm256_storeu_pd(o3, _mm256_permute2f128_pd(b, d, 0x31));
}

// Lane j of a block's vectors is triangle kLane[j] of the four: the order in which
// corner_turns' unpacking leaves them (no shuffle spent to restore 0 1 2 3; the loads and
// stores of the block follow it instead).
constexpr int kLane[4] = {0, 2, 1, 3};

// The turns of corner k of the four triangles at f (F's rows) as re and im vectors, lanes in
// kLane's order: four 16-byte loads, where gathers measured slower (Zen 4).
inline void corner_turns(const int* f, int k, const double* T, __m256d& re, __m256d& im) {
  auto pair = [T](int v) { return _mm_loadu_pd(T + 2 * static_cast<std::ptrdiff_t>(v)); };
  const __m256d p01 = _mm256_insertf128_pd(_mm256_castpd128_pd256(pair(f[k])), pair(f[3 + k]), 1);
  const __m256d p23 =
      _mm256_insertf128_pd(_mm256_castpd128_pd256(pair(f[6 + k])), pair(f[9 + k]), 1);
  re = _mm256_unpacklo_pd(p01, p23);  // re of triangles 0 2 1 3
  im = _mm256_unpackhi_pd(p01, p23);
}

// Lanes of r0, r1, r2 → 12 contiguous doubles, triangle kLane[j] (lane j) at out[3 kLane[j] …].
inline void store_rows3(__m256d r0, __m256d r1, __m256d r2, double* out) {
  alignas(32) double c[3][4];
  _mm256_store_pd(c[0], r0);
  _mm256_store_pd(c[1], r1);
  _mm256_store_pd(c[2], r2);
  for (int j = 0; j < 4; ++j)
    for (int d = 0; d < 3; ++d) out[3 * kLane[j] + d] = c[d][j];
}

// sin x = x Σ (−1)^k x^2k / (2k+1)!, cos x = Σ (−1)^k x^2k / (2k)!, k = 0 … 9, in Horner
// form; the next terms are below 3e-18 for |x| ≤ kTurnPolyMax.
constexpr int kTerms = 10;
struct Taylor {
  double sin[kTerms], cos[kTerms];
};
constexpr Taylor kTaylor = [] {
  Taylor t{};
  double f = 1;  // k!
  for (int k = 0; k < 2 * kTerms; ++k) {
    if (k > 0) f *= k;
    const double sign = (k / 2) % 2 ? -1.0 : 1.0;
    (k % 2 ? t.sin : t.cos)[k / 2] = sign / f;
  }
  return t;
}();

}  // namespace

std::ptrdiff_t guidance_rotation_avx2(const int* F, const double* normals,
                                      const std::complex<double>* turn, const double axis[3],
                                      std::ptrdiff_t l0, std::ptrdiff_t l1, double* g,
                                      double* Rn) {
  const double* T = reinterpret_cast<const double*>(turn);  // re, im interleaved
  const __m256d k0 = _mm256_set1_pd(axis[0]), k1 = _mm256_set1_pd(axis[1]),
                k2 = _mm256_set1_pd(axis[2]);
  const __m256d one = _mm256_set1_pd(1.0);
  std::ptrdiff_t l = l0;
  for (; l + 4 <= l1; l += 4) {
    const int* f = F + 3 * l;
    // e^{i h θ/2} = a · b · c, the turns of the three corners (complex: re at 2v, im 2v+1).
    __m256d ar, ai, br, bi, cr, ci;
    corner_turns(f, 0, T, ar, ai);
    corner_turns(f, 1, T, br, bi);
    corner_turns(f, 2, T, cr, ci);
    const __m256d re = _mm256_sub_pd(_mm256_mul_pd(ar, br), _mm256_mul_pd(ai, bi));
    const __m256d im = _mm256_add_pd(_mm256_mul_pd(ar, bi), _mm256_mul_pd(ai, br));
    const __m256d w = _mm256_sub_pd(_mm256_mul_pd(re, cr), _mm256_mul_pd(im, ci));
    const __m256d s = _mm256_add_pd(_mm256_mul_pd(re, ci), _mm256_mul_pd(im, cr));
    const __m256d x = _mm256_mul_pd(s, k0), y = _mm256_mul_pd(s, k1), z = _mm256_mul_pd(s, k2);
    // Eigen's QuaternionBase::toRotationMatrix.
    const __m256d tx = _mm256_add_pd(x, x), ty = _mm256_add_pd(y, y), tz = _mm256_add_pd(z, z);
    const __m256d twx = _mm256_mul_pd(tx, w), twy = _mm256_mul_pd(ty, w),
                  twz = _mm256_mul_pd(tz, w);
    const __m256d txx = _mm256_mul_pd(tx, x), txy = _mm256_mul_pd(ty, x),
                  txz = _mm256_mul_pd(tz, x);
    const __m256d tyy = _mm256_mul_pd(ty, y), tyz = _mm256_mul_pd(tz, y),
                  tzz = _mm256_mul_pd(tz, z);
    const __m256d R00 = _mm256_sub_pd(one, _mm256_add_pd(tyy, tzz));
    const __m256d R01 = _mm256_sub_pd(txy, twz);
    const __m256d R02 = _mm256_add_pd(txz, twy);
    const __m256d R10 = _mm256_add_pd(txy, twz);
    const __m256d R11 = _mm256_sub_pd(one, _mm256_add_pd(txx, tzz));
    const __m256d R12 = _mm256_sub_pd(tyz, twx);
    const __m256d R20 = _mm256_sub_pd(txz, twy);
    const __m256d R21 = _mm256_add_pd(tyz, twx);
    const __m256d R22 = _mm256_sub_pd(one, _mm256_add_pd(txx, tyy));
    // The rest normals of the four triangles (12 contiguous doubles) as three vectors.
    const double* N = normals + 3 * l;
    const __m256d n0 = _mm256_setr_pd(N[0], N[6], N[3], N[9]);  // kLane's order
    const __m256d n1 = _mm256_setr_pd(N[1], N[7], N[4], N[10]);
    const __m256d n2 = _mm256_setr_pd(N[2], N[8], N[5], N[11]);
    const __m256d m0 = _mm256_fmadd_pd(R02, n2, _mm256_fmadd_pd(R01, n1, _mm256_mul_pd(R00, n0)));
    const __m256d m1 = _mm256_fmadd_pd(R12, n2, _mm256_fmadd_pd(R11, n1, _mm256_mul_pd(R10, n0)));
    const __m256d m2 = _mm256_fmadd_pd(R22, n2, _mm256_fmadd_pd(R21, n1, _mm256_mul_pd(R20, n0)));
    if (Rn) store_rows3(m0, m1, m2, Rn + 3 * l);
    // g_l[r][c] = R(c, r) − n_r (R n)_c
    const __m256d g0 = _mm256_fnmadd_pd(n0, m0, R00), g1 = _mm256_fnmadd_pd(n0, m1, R10),
                  g2 = _mm256_fnmadd_pd(n0, m2, R20);
    const __m256d g3 = _mm256_fnmadd_pd(n1, m0, R01), g4 = _mm256_fnmadd_pd(n1, m1, R11),
                  g5 = _mm256_fnmadd_pd(n1, m2, R21);
    const __m256d g6 = _mm256_fnmadd_pd(n2, m0, R02), g7 = _mm256_fnmadd_pd(n2, m1, R12),
                  g8 = _mm256_fnmadd_pd(n2, m2, R22);
    double* o = g + 9 * l;
    transpose_store(g0, g1, g2, g3, o, o + 18, o + 9, o + 27);  // lanes: triangles 0 2 1 3
    transpose_store(g4, g5, g6, g7, o + 4, o + 22, o + 13, o + 31);
    alignas(32) double last[4];
    _mm256_store_pd(last, g8);
    o[8] = last[0];
    o[26] = last[1];
    o[17] = last[2];
    o[35] = last[3];
  }
  return l;
}

void vertex_turns_avx2(const double* phi, std::ptrdiff_t v0, std::ptrdiff_t v1, double third,
                       std::complex<double>* turn) {
  const auto& [sc, cc] = kTaylor;
  const __m256d th = _mm256_set1_pd(third), lim = _mm256_set1_pd(kTurnPolyMax);
  const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffff));
  double* out = reinterpret_cast<double*>(turn);
  std::ptrdiff_t v = v0;
  for (; v + 4 <= v1; v += 4) {
    const __m256d x = _mm256_mul_pd(_mm256_loadu_pd(phi + v), th);
    // Outside the polynomials' range (or NaN): the four lanes the library way.
    if (_mm256_movemask_pd(_mm256_cmp_pd(_mm256_and_pd(x, abs_mask), lim, _CMP_LE_OQ)) != 0xf) {
      for (int t = 0; t < 4; ++t) turn[v + t] = {std::cos(phi[v + t] * third), std::sin(phi[v + t] * third)};
      continue;
    }
    const __m256d u = _mm256_mul_pd(x, x);
    __m256d s = _mm256_set1_pd(sc[kTerms - 1]), c = _mm256_set1_pd(cc[kTerms - 1]);
    for (int k = kTerms - 2; k >= 0; --k) {
      s = _mm256_fmadd_pd(s, u, _mm256_set1_pd(sc[k]));
      c = _mm256_fmadd_pd(c, u, _mm256_set1_pd(cc[k]));
    }
    s = _mm256_mul_pd(s, x);
    // (c, s) pairs of four vertices: 8 contiguous doubles.
    const __m256d lo = _mm256_unpacklo_pd(c, s);  // c0 s0 c2 s2
    const __m256d hi = _mm256_unpackhi_pd(c, s);  // c1 s1 c3 s3
    _mm256_storeu_pd(out + 2 * v, _mm256_permute2f128_pd(lo, hi, 0x20));
    _mm256_storeu_pd(out + 2 * v + 4, _mm256_permute2f128_pd(lo, hi, 0x31));
  }
  for (; v < v1; ++v) turn[v] = {std::cos(phi[v] * third), std::sin(phi[v] * third)};
}

}  // namespace hdeform::detail

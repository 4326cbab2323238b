// The QUANTIZED encodings' loops in AVX2, 8 vertices or 16 energies a step
// (quantize_kernel.h). Each operation is the generic loop's own, in the same order, with the
// operand orders chosen so NaN goes where the generic loop sends it: the same bytes
// (tests/service/test_frame_encoding.cpp). Measured: service_bench Encode/100000/* and
// docs/benchmarks.md "The encode in AVX2".
#include "service/frames/quantize_kernel.h"

#include <immintrin.h>

#include <cstdint>

namespace hdeform::service::detail {

namespace {

// 8 xyz triples (24 floats from p) as x, y, z lanes in vertex order.
inline void load_xyz8(const float* p, __m256& x, __m256& y, __m256& z) {
  const __m256 m03 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)),
                                          _mm_loadu_ps(p + 12), 1);  // x0 y0 z0 x1 | x4 y4 z4 x5
  const __m256 m14 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 4)),
                                          _mm_loadu_ps(p + 16), 1);  // y1 z1 x2 y2 | y5 z5 x6 y6
  const __m256 m25 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 8)),
                                          _mm_loadu_ps(p + 20), 1);  // z2 x3 y3 z3 | z6 x7 y7 z7
  const __m256 xy = _mm256_shuffle_ps(m14, m25, _MM_SHUFFLE(2, 1, 3, 2));  // x2 y2 x3 y3
  const __m256 yz = _mm256_shuffle_ps(m03, m14, _MM_SHUFFLE(1, 0, 2, 1));  // y0 z0 y1 z1
  x = _mm256_shuffle_ps(m03, xy, _MM_SHUFFLE(2, 0, 3, 0));
  y = _mm256_shuffle_ps(yz, xy, _MM_SHUFFLE(3, 1, 2, 0));
  z = _mm256_shuffle_ps(yz, m25, _MM_SHUFFLE(3, 0, 3, 1));
}

// Four positions of one axis: q in the low 16 bits of each int32; `bad` collects the lanes
// outside the grid. Operand orders are chosen so NaN goes where the generic loop sends it.
inline __m128i quantize4(__m128 xf, __m256d lo, __m256d scale, __m256d flat, __m256d& bad) {
  const __m256d x = _mm256_cvtps_pd(xf);
  const __m256d t = _mm256_mul_pd(_mm256_sub_pd(x, lo), scale);
  const __m256d ok = _mm256_and_pd(_mm256_cmp_pd(t, _mm256_set1_pd(-0.5), _CMP_GE_OQ),
                                   _mm256_cmp_pd(t, _mm256_set1_pd(65535.5), _CMP_LT_OQ));
  const __m256d off_flat = _mm256_and_pd(flat, _mm256_cmp_pd(x, lo, _CMP_NEQ_UQ));
  bad = _mm256_or_pd(bad, _mm256_or_pd(_mm256_andnot_pd(ok, _mm256_castsi256_pd(
                                                                _mm256_set1_epi64x(-1))),
                                       off_flat));
  // max(t, 0) is 0 for NaN, as the generic t > 0 ? … : 0; then min, then round to nearest.
  const __m256d c = _mm256_min_pd(_mm256_max_pd(t, _mm256_setzero_pd()), _mm256_set1_pd(65535.0));
  return _mm256_cvtpd_epi32(c);
}

inline __m256i quantize8(__m256 x, __m256d lo, __m256d scale, __m256d flat, __m256d& bad) {
  const __m128i a = quantize4(_mm256_castps256_ps128(x), lo, scale, flat, bad);
  const __m128i b = quantize4(_mm256_extractf128_ps(x, 1), lo, scale, flat, bad);
  return _mm256_set_m128i(b, a);
}

// Octahedral u, v of 8 normals, rounded to int32 (low byte = the int8; NaN gives 0x80000000,
// whose low byte 0 is what the generic loop's lrintf cast to int8 gives).
inline void octahedral8(__m256 x, __m256 y, __m256 z, __m256i& qu, __m256i& qv) {
  const __m256 sign = _mm256_set1_ps(-0.0f), zero = _mm256_setzero_ps();
  const __m256 one = _mm256_set1_ps(1.0f), minus_one = _mm256_set1_ps(-1.0f);
  const __m256 l1 = _mm256_add_ps(_mm256_add_ps(_mm256_andnot_ps(sign, x), _mm256_andnot_ps(sign, y)),
                                  _mm256_andnot_ps(sign, z));
  const __m256 inv = _mm256_and_ps(_mm256_cmp_ps(l1, zero, _CMP_GT_OQ), _mm256_div_ps(one, l1));
  __m256 u = _mm256_mul_ps(x, inv), v = _mm256_mul_ps(y, inv);
  const __m256 su = _mm256_blendv_ps(minus_one, one, _mm256_cmp_ps(u, zero, _CMP_GE_OQ));
  const __m256 sv = _mm256_blendv_ps(minus_one, one, _mm256_cmp_ps(v, zero, _CMP_GE_OQ));
  const __m256 fu = _mm256_mul_ps(_mm256_sub_ps(one, _mm256_andnot_ps(sign, v)), su);
  const __m256 fv = _mm256_mul_ps(_mm256_sub_ps(one, _mm256_andnot_ps(sign, u)), sv);
  const __m256 lower = _mm256_cmp_ps(z, zero, _CMP_LT_OQ);
  u = _mm256_blendv_ps(u, fu, lower);
  v = _mm256_blendv_ps(v, fv, lower);
  // clamp to [−1, 1] keeping NaN (max/min return their second operand on NaN), then · 127.
  const __m256 k = _mm256_set1_ps(127.0f);
  qu = _mm256_cvtps_epi32(_mm256_mul_ps(_mm256_min_ps(one, _mm256_max_ps(minus_one, u)), k));
  qv = _mm256_cvtps_epi32(_mm256_mul_ps(_mm256_min_ps(one, _mm256_max_ps(minus_one, v)), k));
}

}  // namespace

std::size_t quantize_range_avx2(const float* p, const float* nrm, std::size_t begin,
                                std::size_t end, const QuantizeGrid& grid, unsigned char* out,
                                bool* inside) {
  const std::size_t n8 = (end - begin) / 8 * 8;
  __m256d lo[3], scale[3], flat[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = _mm256_set1_pd(grid.lo[k]);
    scale[k] = _mm256_set1_pd(grid.scale[k]);
    flat[k] = _mm256_cmp_pd(scale[k], _mm256_setzero_pd(), _CMP_EQ_OQ);
  }
  const __m256i low8 = _mm256_set1_epi32(0xff);
  __m256d bad = _mm256_setzero_pd();
  for (std::size_t i = begin; i < begin + n8; i += 8) {
    __m256 x, y, z;
    load_xyz8(p + 3 * i, x, y, z);
    const __m256i qx = quantize8(x, lo[0], scale[0], flat[0], bad);
    const __m256i qy = quantize8(y, lo[1], scale[1], flat[1], bad);
    __m256i hi = quantize8(z, lo[2], scale[2], flat[2], bad);
    const __m256i lo32 = _mm256_or_si256(qx, _mm256_slli_epi32(qy, 16));  // every q ≤ 65535
    if (nrm) {
      __m256 nx, ny, nz;
      load_xyz8(nrm + 3 * i, nx, ny, nz);
      __m256i qu, qv;
      octahedral8(nx, ny, nz, qu, qv);
      hi = _mm256_or_si256(hi, _mm256_or_si256(_mm256_slli_epi32(_mm256_and_si256(qu, low8), 16),
                                               _mm256_slli_epi32(qv, 24)));
    }
    // Vertex j's 8 bytes are lo32[j], hi[j]: interleave, then put the 128-bit halves in order.
    const __m256i a = _mm256_unpacklo_epi32(lo32, hi);  // v0 v1 | v4 v5
    const __m256i b = _mm256_unpackhi_epi32(lo32, hi);  // v2 v3 | v6 v7
    auto* o = reinterpret_cast<__m256i*>(out + 8 * i);
    _mm256_storeu_si256(o, _mm256_permute2x128_si256(a, b, 0x20));
    _mm256_storeu_si256(o + 1, _mm256_permute2x128_si256(a, b, 0x31));
  }
  if (_mm256_movemask_pd(bad) != 0) *inside = false;
  return n8;
}

std::size_t box_range_avx2(const float* p, std::size_t begin, std::size_t end, float lo[3],
                           float hi[3]) {
  const std::size_t n8 = (end - begin) / 8 * 8;
  __m256 mn[3], mx[3];
  for (int k = 0; k < 3; ++k) {
    mn[k] = _mm256_set1_ps(lo[k]);
    mx[k] = _mm256_set1_ps(hi[k]);
  }
  for (std::size_t i = begin; i < begin + n8; i += 8) {
    __m256 v[3];
    load_xyz8(p + 3 * i, v[0], v[1], v[2]);
    for (int k = 0; k < 3; ++k) {  // x < m ? x : m, as std::min(m, x): NaN x leaves m
      mn[k] = _mm256_min_ps(v[k], mn[k]);
      mx[k] = _mm256_max_ps(v[k], mx[k]);
    }
  }
  for (int k = 0; k < 3; ++k) {
    alignas(32) float a[8], b[8];
    _mm256_store_ps(a, mn[k]);
    _mm256_store_ps(b, mx[k]);
    for (int j = 0; j < 8; ++j) {
      if (a[j] < lo[k]) lo[k] = a[j];
      if (b[j] > hi[k]) hi[k] = b[j];
    }
  }
  return n8;
}

std::size_t max_finite_range_avx2(const float* e, std::size_t begin, std::size_t end,
                                  float* top) {
  const std::size_t n8 = (end - begin) / 8 * 8;
  const __m256 sign = _mm256_set1_ps(-0.0f), inf = _mm256_set1_ps(__builtin_inff());
  __m256 m = _mm256_set1_ps(*top);
  for (std::size_t l = begin; l < begin + n8; l += 8) {
    const __m256 x = _mm256_loadu_ps(e + l);
    const __m256 finite = _mm256_cmp_ps(_mm256_andnot_ps(sign, x), inf, _CMP_LT_OQ);
    m = _mm256_max_ps(_mm256_blendv_ps(m, x, finite), m);  // a value not finite leaves m
  }
  alignas(32) float a[8];
  _mm256_store_ps(a, m);
  for (float x : a)
    if (x > *top) *top = x;
  return n8;
}

std::size_t quantize_energy_range_avx2(const float* e, std::size_t begin, std::size_t end,
                                       float inv, std::uint16_t* q) {
  const std::size_t n16 = (end - begin) / 16 * 16;
  const __m256 sign = _mm256_set1_ps(-0.0f), inf = _mm256_set1_ps(__builtin_inff());
  const __m256 vinv = _mm256_set1_ps(inv), zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 k = _mm256_set1_ps(65535.0f);
  const __m256i all = _mm256_set1_epi32(65535);
  auto eight = [&](const float* x8) {
    const __m256 x = _mm256_loadu_ps(x8);
    const __m256 finite = _mm256_cmp_ps(_mm256_andnot_ps(sign, x), inf, _CMP_LT_OQ);
    // clamp keeping NaN (0 · inf), whose int32 0x80000000 packs to 0, as lrintf's cast does
    const __m256 t = _mm256_min_ps(one, _mm256_max_ps(zero, _mm256_mul_ps(x, vinv)));
    const __m256i r = _mm256_cvtps_epi32(_mm256_mul_ps(t, k));
    return _mm256_blendv_epi8(all, r, _mm256_castps_si256(finite));
  };
  for (std::size_t l = begin; l < begin + n16; l += 16) {
    // packus saturates: [0, 65535] as is, 0x80000000 to 0; it packs within 128-bit halves.
    const __m256i packed = _mm256_packus_epi32(eight(e + l), eight(e + l + 8));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(q + l),
                        _mm256_permute4x64_epi64(packed, _MM_SHUFFLE(3, 1, 2, 0)));
  }
  return n16;
}

}  // namespace hdeform::service::detail

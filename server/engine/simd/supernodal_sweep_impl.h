// The sweep kernels of supernodal_sweep.h, compiled once per instruction set: included only
// by supernodal_sweep.cpp and supernodal_sweep_avx2.cpp, each defining HDEFORM_SWEEP_ISA (the
// namespace its kernels() lives in). Everything else here has internal linkage, so the two
// builds of these templates never meet at link time.
#ifndef HDEFORM_SWEEP_ISA
#error "define HDEFORM_SWEEP_ISA before including supernodal_sweep_impl.h"
#endif

#include "engine/simd/supernodal_sweep.h"

#include <cstddef>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#define HDEFORM_SWEEP_VECTOR 1
#endif

namespace hdeform {
namespace {

// CHOLMOD's supernodal layout (cholmod_core.h): supernode s holds columns
// k1 = super[s] … k2 = super[s+1]−1; its row indices are Ls[pi[s] … pi[s+1]), the first
// k2−k1 of them k1 … k2−1 (the dense diagonal block), the rest the off-diagonal rows; its
// values are the column-major nsrow × ncols block at Lx + px[s] (leading dimension nsrow).
template <class T>
struct Super {
  int k1, nc, nsrow;
  const int* rows;
  const T* x;  // column j at x + j·nsrow
};

template <class T>
inline Super<T> super_at(const SweepArgs<T>& a, int s) {
  Super<T> S;
  S.k1 = a.super[s];
  S.nc = a.super[s + 1] - S.k1;
  S.nsrow = a.pi[s + 1] - a.pi[s];
  S.rows = a.rows + a.pi[s];
  S.x = a.Lx + a.px[s];
  return S;
}

#ifdef HDEFORM_SWEEP_VECTOR
// Four factor entries of one column (rows i … i+3) as doubles.
inline __m256d load4(const double* p) { return _mm256_loadu_pd(p); }
inline __m256d load4(const float* p) { return _mm256_cvtps_pd(_mm_loadu_ps(p)); }

inline double hsum(__m256d v) {
  const __m128d s = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
  return _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)));
}

// y row r −= (xy, z)
inline void sub_row(double* yr, __m128d xy, double z) {
  _mm_storeu_pd(yr, _mm_sub_pd(_mm_loadu_pd(yr), xy));
  yr[2] -= z;
}
#endif

// Columns are processed in panels of W: the rows below a panel are read once per panel,
// each y row loaded/stored once for W factor columns (not once per column), while the W
// column streams of the factor are read contiguously. With AVX2 + FMA, four rows at a time:
// the factor entries as 4-wide vectors, the three right-hand sides as three accumulators,
// transposed to rows only where y is read or written (y keeps its three values per row).
//
// Measured alternatives. Earlier (Solve/10000/*, CI load present): padding y's rows to four
// doubles as GCC vectors, with an AVX2 clone, was slower than the scalar code (the work
// array grows by a third). The explicit AVX2 code here against the baseline build of the
// same file (Solve/100000/*/fused_* vs fused_generic_*, 2026-12-04, interleaved, quiet):
// two threads, double 4.39 vs 5.71 ms (β = 0) and 8.68 vs 12.4 ms (β = 0.5); float32
// 2.27 vs 3.81 and 5.42 vs 9.71 ms (docs/benchmarks.md, "AVX2 sweep kernels").

// Forward: solve the panel's W×W lower triangle, then y[rows[i]] −= L(i, panel) · x_panel
// for every row below it in the supernode (the diagonal block's rows and the off-diagonal
// ones alike: both are addressed through rows[]).
template <int W, class T>
inline void forward_panel(const Super<T>& S, int j0, double* y) {
  const T* c[W];
  for (int t = 0; t < W; ++t) c[t] = S.x + static_cast<std::ptrdiff_t>(j0 + t) * S.nsrow;
  double x0[W], x1[W], x2[W];
  double* yd = y + 3 * static_cast<std::ptrdiff_t>(S.k1 + j0);
  for (int t = 0; t < W; ++t) {
    const double d = c[t][j0 + t];
    x0[t] = yd[3 * t] / d;
    x1[t] = yd[3 * t + 1] / d;
    x2[t] = yd[3 * t + 2] / d;
    yd[3 * t] = x0[t];
    yd[3 * t + 1] = x1[t];
    yd[3 * t + 2] = x2[t];
    for (int u = t + 1; u < W; ++u) {
      const double l = c[t][j0 + u];
      yd[3 * u] -= l * x0[t];
      yd[3 * u + 1] -= l * x1[t];
      yd[3 * u + 2] -= l * x2[t];
    }
  }
  int i = j0 + W;
#ifdef HDEFORM_SWEEP_VECTOR
  __m256d X0[W], X1[W], X2[W];
  for (int t = 0; t < W; ++t) {
    X0[t] = _mm256_set1_pd(x0[t]);
    X1[t] = _mm256_set1_pd(x1[t]);
    X2[t] = _mm256_set1_pd(x2[t]);
  }
  for (; i + 4 <= S.nsrow; i += 4) {
    __m256d l = load4(c[0] + i);
    __m256d a0 = _mm256_mul_pd(l, X0[0]), a1 = _mm256_mul_pd(l, X1[0]),
            a2 = _mm256_mul_pd(l, X2[0]);
    for (int t = 1; t < W; ++t) {
      l = load4(c[t] + i);
      a0 = _mm256_fmadd_pd(l, X0[t], a0);
      a1 = _mm256_fmadd_pd(l, X1[t], a1);
      a2 = _mm256_fmadd_pd(l, X2[t], a2);
    }
    const __m256d even = _mm256_unpacklo_pd(a0, a1);  // rows i, i+2: (x, y) pairs
    const __m256d odd = _mm256_unpackhi_pd(a0, a1);   // rows i+1, i+3
    alignas(32) double z[4];
    _mm256_store_pd(z, a2);
    const int* r = S.rows + i;
    sub_row(y + 3 * static_cast<std::ptrdiff_t>(r[0]), _mm256_castpd256_pd128(even), z[0]);
    sub_row(y + 3 * static_cast<std::ptrdiff_t>(r[1]), _mm256_castpd256_pd128(odd), z[1]);
    sub_row(y + 3 * static_cast<std::ptrdiff_t>(r[2]), _mm256_extractf128_pd(even, 1), z[2]);
    sub_row(y + 3 * static_cast<std::ptrdiff_t>(r[3]), _mm256_extractf128_pd(odd, 1), z[3]);
  }
#endif
  for (; i < S.nsrow; ++i) {
    double a0 = 0, a1 = 0, a2 = 0;
    for (int t = 0; t < W; ++t) {
      const double l = c[t][i];
      a0 += l * x0[t];
      a1 += l * x1[t];
      a2 += l * x2[t];
    }
    double* yr = y + 3 * static_cast<std::ptrdiff_t>(S.rows[i]);
    yr[0] -= a0;
    yr[1] -= a1;
    yr[2] -= a2;
  }
}

// Backward (Lᵀ): x_j = (y_j − Σ_{i>j} L(i,j) x_{rows[i]}) / L(j,j). The rows below the
// panel are already final (later panels and later supernodes go first): dot products
// down the W contiguous factor columns, then the panel's own triangle from the bottom up.
template <int W, class T>
inline void backward_panel(const Super<T>& S, int j0, double* y) {
  const T* c[W];
  for (int t = 0; t < W; ++t) c[t] = S.x + static_cast<std::ptrdiff_t>(j0 + t) * S.nsrow;
  double a0[W] = {}, a1[W] = {}, a2[W] = {};
  int i = j0 + W;
#ifdef HDEFORM_SWEEP_VECTOR
  if (i + 4 <= S.nsrow) {
    __m256d A0[W], A1[W], A2[W];
    for (int t = 0; t < W; ++t) A0[t] = A1[t] = A2[t] = _mm256_setzero_pd();
    for (; i + 4 <= S.nsrow; i += 4) {
      const int* r = S.rows + i;
      const double* p0 = y + 3 * static_cast<std::ptrdiff_t>(r[0]);
      const double* p1 = y + 3 * static_cast<std::ptrdiff_t>(r[1]);
      const double* p2 = y + 3 * static_cast<std::ptrdiff_t>(r[2]);
      const double* p3 = y + 3 * static_cast<std::ptrdiff_t>(r[3]);
      const __m256d q02 =
          _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(p0)), _mm_loadu_pd(p2), 1);
      const __m256d q13 =
          _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(p1)), _mm_loadu_pd(p3), 1);
      const __m256d v0 = _mm256_unpacklo_pd(q02, q13);  // x of rows i … i+3
      const __m256d v1 = _mm256_unpackhi_pd(q02, q13);  // y
      const __m256d v2 = _mm256_set_pd(p3[2], p2[2], p1[2], p0[2]);
      for (int t = 0; t < W; ++t) {
        const __m256d l = load4(c[t] + i);
        A0[t] = _mm256_fmadd_pd(l, v0, A0[t]);
        A1[t] = _mm256_fmadd_pd(l, v1, A1[t]);
        A2[t] = _mm256_fmadd_pd(l, v2, A2[t]);
      }
    }
    for (int t = 0; t < W; ++t) {
      a0[t] = hsum(A0[t]);
      a1[t] = hsum(A1[t]);
      a2[t] = hsum(A2[t]);
    }
  }
#endif
  for (; i < S.nsrow; ++i) {
    const double* xr = y + 3 * static_cast<std::ptrdiff_t>(S.rows[i]);
    const double v0 = xr[0], v1 = xr[1], v2 = xr[2];
    for (int t = 0; t < W; ++t) {
      const double l = c[t][i];
      a0[t] += l * v0;
      a1[t] += l * v1;
      a2[t] += l * v2;
    }
  }
  double* yd = y + 3 * static_cast<std::ptrdiff_t>(S.k1 + j0);
  for (int t = W - 1; t >= 0; --t) {
    double v0 = yd[3 * t] - a0[t], v1 = yd[3 * t + 1] - a1[t], v2 = yd[3 * t + 2] - a2[t];
    for (int u = t + 1; u < W; ++u) {
      const double l = c[t][j0 + u];
      v0 -= l * yd[3 * u];
      v1 -= l * yd[3 * u + 1];
      v2 -= l * yd[3 * u + 2];
    }
    const double d = c[t][j0 + t];
    yd[3 * t] = v0 / d;
    yd[3 * t + 1] = v1 / d;
    yd[3 * t + 2] = v2 / d;
  }
}

constexpr int kPanel = 4;

#ifdef HDEFORM_SWEEP_VECTOR
// Forward panels of 8 with vectors: half the scattered y updates per factor entry, the 24
// broadcast x values partly from memory. Measured against 4 (Solve/100000/*, two runs
// alternated, quiet, 2026-12-04): β = 0.5 two threads 8.50 / 8.41 ms vs 9.92 / 9.28 ms,
// β = 0 within noise (4.54 / 4.77 vs 4.89 / 4.20 ms). Backward stays at 4: its 3·W vector
// accumulators must fit the 16 registers.
constexpr int kForwardPanel = 8;
#else
constexpr int kForwardPanel = kPanel;
#endif

template <class T>
void forward(const Super<T>& S, double* y) {
  int j = 0;
  for (; j + kForwardPanel <= S.nc; j += kForwardPanel) forward_panel<kForwardPanel>(S, j, y);
  if constexpr (kForwardPanel > kPanel)
    for (; j + kPanel <= S.nc; j += kPanel) forward_panel<kPanel>(S, j, y);
  switch (S.nc - j) {
    case 3: forward_panel<3>(S, j, y); break;
    case 2: forward_panel<2>(S, j, y); break;
    case 1: forward_panel<1>(S, j, y); break;
    default: break;
  }
}

template <class T>
void backward(const Super<T>& S, double* y) {
  // The panels of forward() in reverse: the ragged one (at the end) first.
  const int full = S.nc / kPanel * kPanel;
  switch (S.nc - full) {
    case 3: backward_panel<3>(S, full, y); break;
    case 2: backward_panel<2>(S, full, y); break;
    case 1: backward_panel<1>(S, full, y); break;
    default: break;
  }
  for (int j = full - kPanel; j >= 0; j -= kPanel) backward_panel<kPanel>(S, j, y);
}

template <class T>
void forward_sweep(const SweepArgs<T>& a, const int* list, int count) {
  for (int k = 0; k < count; ++k) forward(super_at(a, list ? list[k] : k), a.y);
}

template <class T>
void backward_sweep(const SweepArgs<T>& a, const int* list, int count) {
  for (int k = count - 1; k >= 0; --k) backward(super_at(a, list ? list[k] : k), a.y);
}

}  // namespace

namespace HDEFORM_SWEEP_ISA {
template <class T>
SweepKernels<T> kernels() {
  return {&forward_sweep<T>, &backward_sweep<T>};
}
template SweepKernels<double> kernels<double>();
template SweepKernels<float> kernels<float>();
}  // namespace HDEFORM_SWEEP_ISA

}  // namespace hdeform

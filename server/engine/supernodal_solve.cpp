#include "supernodal_solve.h"

#include <cblas.h>

namespace hdeform {

namespace {

// CHOLMOD's supernodal layout (cholmod_core.h): supernode s holds columns
// k1 = super[s] … k2 = super[s+1]−1; its row indices are Ls[pi[s] … pi[s+1]), the first
// k2−k1 of them k1 … k2−1 (the dense diagonal block), the rest the off-diagonal rows; its
// values are the column-major nsrow × ncols block at Lx + px[s] (leading dimension nsrow).
struct Super {
  int k1, nc, nsrow;
  const int* rows;
  const double* x;  // column j at x + j·nsrow
};

inline Super super_at(const int* super, const int* pi, const int* px, const int* Ls,
                      const double* Lx, int s) {
  Super S;
  S.k1 = super[s];
  S.nc = super[s + 1] - S.k1;
  S.nsrow = pi[s + 1] - pi[s];
  S.rows = Ls + pi[s];
  S.x = Lx + px[s];
  return S;
}

// Columns are processed in panels of W (≤ 4): the rows below a panel are read once per
// panel, each y row loaded/stored once for W factor columns (not once per column), while
// the W column streams of the factor are read contiguously.

// Forward: solve the panel's W×W lower triangle, then y[rows[i]] −= L(i, panel) · x_panel
// for every row below it in the supernode (the diagonal block's rows and the off-diagonal
// ones alike: both are addressed through rows[]).
template <int W>
inline void forward_panel(const Super& S, int j0, double* y) {
  const double* c[W];
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
  for (int i = j0 + W; i < S.nsrow; ++i) {
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
template <int W>
inline void backward_panel(const Super& S, int j0, double* y) {
  const double* c[W];
  for (int t = 0; t < W; ++t) c[t] = S.x + static_cast<std::ptrdiff_t>(j0 + t) * S.nsrow;
  double a0[W] = {}, a1[W] = {}, a2[W] = {};
  for (int i = j0 + W; i < S.nsrow; ++i) {
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

// Measured alternatives (bench Solve/10000/*, same machine, interleaved, CI load present):
// padding the rows to four doubles as GCC 4-wide vectors (with an AVX2+FMA clone) and
// panels of 8 were both slower than this scalar three-wide code with panels of 4 (β = 0.5:
// 5.0–5.3 ms vs 3.0–4.1 ms; β = 0: 1.4–1.7 vs 1.1–1.3 ms): the sweep is bound by the
// scattered y updates and the factor stream, and padding grows the work array by a third.
// BLAS cutoff (SupernodalWorkspace::blas_min_cols, default 0 = never): sending supernodes
// with ≥ C columns through OpenBLAS dtrsm + dgemm did not win at any C measured
// (Solve/N/beta:b/fused_blas:C, one interleaved run per size, 5 repetitions, medians, CI
// load present): 10K β = 0: in-house 0.95 ms vs 1.06–1.19 ms for C = 32…256; 10K β = 0.5:
// 4.30 vs 4.55–6.22 ms; 100K β = 0.5: 75.8 vs 84–138 ms; 100K β = 0: 46.0 vs 41.9–51.0 ms
// (C = 128 the only one below, within that run's noise). The path stays, tested, for a
// re-measurement on a quiet machine.
constexpr int kPanel = 4;

void forward(const Super& S, double* y) {
  int j = 0;
  for (; j + kPanel <= S.nc; j += kPanel) forward_panel<kPanel>(S, j, y);
  switch (S.nc - j) {
    case 3: forward_panel<3>(S, j, y); break;
    case 2: forward_panel<2>(S, j, y); break;
    case 1: forward_panel<1>(S, j, y); break;
    default: break;
  }
}

void backward(const Super& S, double* y) {
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

// BLAS path for one supernode. The nc rows of y at k1 are a column-major 3 × nc matrix
// (ld 3) = X_dᵀ, so the triangular solves are right-sided on Xᵀ.
void forward_blas(const Super& S, double* y, double* w) {
  double* yd = y + 3 * static_cast<std::ptrdiff_t>(S.k1);
  const int noff = S.nsrow - S.nc;
  cblas_dtrsm(CblasColMajor, CblasRight, CblasLower, CblasTrans, CblasNonUnit, 3, S.nc, 1.0,
              S.x, S.nsrow, yd, 3);
  if (noff == 0) return;
  cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, 3, noff, S.nc, 1.0, yd, 3, S.x + S.nc,
              S.nsrow, 0.0, w, 3);
  for (int i = 0; i < noff; ++i) {
    double* yr = y + 3 * static_cast<std::ptrdiff_t>(S.rows[S.nc + i]);
    yr[0] -= w[3 * i];
    yr[1] -= w[3 * i + 1];
    yr[2] -= w[3 * i + 2];
  }
}

void backward_blas(const Super& S, double* y, double* w) {
  double* yd = y + 3 * static_cast<std::ptrdiff_t>(S.k1);
  const int noff = S.nsrow - S.nc;
  if (noff > 0) {
    for (int i = 0; i < noff; ++i) {
      const double* xr = y + 3 * static_cast<std::ptrdiff_t>(S.rows[S.nc + i]);
      w[3 * i] = xr[0];
      w[3 * i + 1] = xr[1];
      w[3 * i + 2] = xr[2];
    }
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, 3, S.nc, noff, -1.0, w, 3,
                S.x + S.nc, S.nsrow, 1.0, yd, 3);
  }
  cblas_dtrsm(CblasColMajor, CblasRight, CblasLower, CblasNoTrans, CblasNonUnit, 3, S.nc, 1.0,
              S.x, S.nsrow, yd, 3);
}

}  // namespace

bool supernodal_solvable(const cholmod_factor* L) {
  return L && L->is_super && L->is_ll && L->xtype == CHOLMOD_REAL &&
         L->dtype == CHOLMOD_DOUBLE && L->itype == CHOLMOD_INT && L->Perm && L->super &&
         L->pi && L->px && L->s && L->x;
}

void supernodal_solve3(const cholmod_factor& L, const double* B, std::ptrdiff_t ldb, double* X,
                       std::ptrdiff_t ldx, SupernodalWorkspace& ws) {
  const auto n = static_cast<std::ptrdiff_t>(L.n);
  if (n == 0) return;
  const int cut = ws.blas_min_cols;
  ws.reserve(static_cast<std::size_t>(n), cut > 0 ? L.maxesize : 0);
  double* y = ws.data();
  double* w = ws.below();
  const int* perm = static_cast<const int*>(L.Perm);
  const int* super = static_cast<const int*>(L.super);
  const int* pi = static_cast<const int*>(L.pi);
  const int* px = static_cast<const int*>(L.px);
  const int* Ls = static_cast<const int*>(L.s);
  const double* Lx = static_cast<const double*>(L.x);
  const int nsuper = static_cast<int>(L.nsuper);

  // y = P b, interleaved: y[3k + c] = B(Perm[k], c).
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    const std::ptrdiff_t r = perm[k];
    y[3 * k] = B[r];
    y[3 * k + 1] = B[r + ldb];
    y[3 * k + 2] = B[r + 2 * ldb];
  }
  for (int s = 0; s < nsuper; ++s) {
    const Super S = super_at(super, pi, px, Ls, Lx, s);
    if (cut > 0 && S.nc >= cut)
      forward_blas(S, y, w);
    else
      forward(S, y);
  }
  for (int s = nsuper - 1; s >= 0; --s) {
    const Super S = super_at(super, pi, px, Ls, Lx, s);
    if (cut > 0 && S.nc >= cut)
      backward_blas(S, y, w);
    else
      backward(S, y);
  }
  // x = Pᵀ y (reads y only: X may alias B).
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    const std::ptrdiff_t r = perm[k];
    X[r] = y[3 * k];
    X[r + ldx] = y[3 * k + 1];
    X[r + 2 * ldx] = y[3 * k + 2];
  }
}

}  // namespace hdeform

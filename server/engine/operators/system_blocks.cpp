#include "engine/operators/system_blocks.h"

#include <algorithm>
#include <cstdint>

namespace hdeform {

namespace {

// Walks column c of X and (if given) Y in ascending row order, calling
// visit(row, x, has_x, y, has_y) once per row of the union.
template <class Visit>
void merge_column(const SparseMatrix& X, const SparseMatrix* Y, Eigen::Index c, Visit&& visit) {
  const int* xi = X.innerIndexPtr();
  const double* xv = X.valuePtr();
  int p = X.outerIndexPtr()[c];
  const int pe = X.outerIndexPtr()[c + 1];
  if (!Y) {
    for (; p < pe; ++p) visit(xi[p], xv[p], true, 0.0, false);
    return;
  }
  const int* yi = Y->innerIndexPtr();
  const double* yv = Y->valuePtr();
  int q = Y->outerIndexPtr()[c];
  const int qe = Y->outerIndexPtr()[c + 1];
  while (p < pe || q < qe) {
    const int rx = p < pe ? xi[p] : INT32_MAX, ry = q < qe ? yi[q] : INT32_MAX;
    if (rx == ry) visit(rx, xv[p++], true, yv[q++], true);
    else if (rx < ry) visit(rx, xv[p++], true, 0.0, false);
    else visit(ry, 0.0, false, yv[q++], true);
  }
}

// The union's value of the first matrix: what Eigen's `X + 0.0 * Y` stores (x + 0 where only
// X has the entry, 0 + 0·y where only Y has it).
double first_of(double x, bool has_x, double y, bool has_y) {
  return (has_x ? x : 0.0) + (has_y ? 0.0 * y : 0.0);
}

// FF and FC of K1 (and of K2 on the union pattern when K2 is given), in parallel over columns.
void split_square(const SparseMatrix& K1, const SparseMatrix* K2, const BlockLayout& b,
                  Blocks& out1, Blocks* out2) {
  const Eigen::Index n = K1.cols();
  out1.FF.resize(b.nF, b.nF);
  out1.FC.resize(b.nF, b.nC);
  int* ff = out1.FF.outerIndexPtr();
  int* fc = out1.FC.outerIndexPtr();
  auto free_row = [&](int r) { return b.region_of[static_cast<std::size_t>(r)] < 0; };
#pragma omp parallel
  {
#pragma omp for schedule(static)
    for (Eigen::Index c = 0; c < n; ++c) {
      int count = 0;
      merge_column(K1, K2, c, [&](int r, double, bool, double, bool) { count += free_row(r); });
      const auto j = static_cast<std::size_t>(c);
      (b.region_of[j] < 0 ? ff : fc)[b.block_index[j] + 1] = count;
    }
#pragma omp single
    {
      for (Eigen::Index j = 0; j < b.nF; ++j) ff[j + 1] += ff[j];
      for (Eigen::Index j = 0; j < b.nC; ++j) fc[j + 1] += fc[j];
      out1.FF.resizeNonZeros(ff[b.nF]);
      out1.FC.resizeNonZeros(fc[b.nC]);
      if (out2) {  // the same sizes and offsets; indices and values are filled below
        out2->FF = out1.FF;
        out2->FC = out1.FC;
      }
    }
#pragma omp for schedule(static)
    for (Eigen::Index c = 0; c < n; ++c) {
      const auto j = static_cast<std::size_t>(c);
      const bool free_col = b.region_of[j] < 0;
      SparseMatrix& M1 = free_col ? out1.FF : out1.FC;
      SparseMatrix* M2 = out2 ? (free_col ? &out2->FF : &out2->FC) : nullptr;
      int k = M1.outerIndexPtr()[b.block_index[j]];
      merge_column(K1, K2, c, [&](int r, double x, bool has_x, double y, bool has_y) {
        if (!free_row(r)) return;
        M1.innerIndexPtr()[k] = b.block_index[static_cast<std::size_t>(r)];
        if (M2) {
          M2->innerIndexPtr()[k] = M1.innerIndexPtr()[k];
          M1.valuePtr()[k] = first_of(x, has_x, y, has_y);
          M2->valuePtr()[k] = first_of(y, has_y, x, has_x);
        } else {
          M1.valuePtr()[k] = x;
        }
        ++k;
      });
    }
  }
}

// (GtW1)_F (and (GtW2)_F on the union pattern), row-major: a transposing pass, serial.
void split_rows(const SparseMatrix& W1, const SparseMatrix* W2, const BlockLayout& b,
                SparseMatrixR& out1, SparseMatrixR* out2) {
  const Eigen::Index cols = W1.cols();
  out1.resize(b.nF, cols);
  int* outer = out1.outerIndexPtr();
  auto free_row = [&](int r) { return b.region_of[static_cast<std::size_t>(r)] < 0; };
  for (Eigen::Index c = 0; c < cols; ++c)
    merge_column(W1, W2, c, [&](int r, double, bool, double, bool) {
      if (free_row(r)) ++outer[b.block_index[static_cast<std::size_t>(r)] + 1];
    });
  for (Eigen::Index i = 0; i < b.nF; ++i) outer[i + 1] += outer[i];
  out1.resizeNonZeros(outer[b.nF]);
  if (out2) *out2 = out1;
  std::vector<int> next(outer, outer + b.nF);
  for (Eigen::Index c = 0; c < cols; ++c)  // ascending c: each row's columns come out sorted
    merge_column(W1, W2, c, [&](int r, double x, bool has_x, double y, bool has_y) {
      if (!free_row(r)) return;
      const int k = next[static_cast<std::size_t>(b.block_index[static_cast<std::size_t>(r)])]++;
      out1.innerIndexPtr()[k] = static_cast<int>(c);
      if (out2) {
        out1.valuePtr()[k] = first_of(x, has_x, y, has_y);
        out2->valuePtr()[k] = first_of(y, has_y, x, has_x);
        out2->innerIndexPtr()[k] = static_cast<int>(c);
      } else {
        out1.valuePtr()[k] = x;
      }
    });
}

}  // namespace

Blocks split(const SparseMatrix& K, const SparseMatrix* GtW, const BlockLayout& layout) {
  Blocks out;
  split_square(K, nullptr, layout, out, nullptr);
  if (GtW) split_rows(*GtW, nullptr, layout, out.GtW_F, nullptr);
  return out;
}

void split_union(const SparseMatrix& K1, const SparseMatrix& K2, const SparseMatrix* GtW1,
                 const SparseMatrix* GtW2, const BlockLayout& layout, Blocks& out1,
                 Blocks& out2) {
  split_square(K1, &K2, layout, out1, &out2);
  if (GtW1 && GtW2) split_rows(*GtW1, GtW2, layout, out1.GtW_F, &out2.GtW_F);
}

SparseMatrixR free_rows_gta(const Triangles& F, const TriangleGradients& grads,
                            const Eigen::VectorXd& areas, const VertexTriangles& vt,
                            const std::vector<int>& free_) {
  const auto nF = static_cast<Eigen::Index>(free_.size());
  SparseMatrixR R(nF, 3 * F.rows());
  int* outer = R.outerIndexPtr();
  for (Eigen::Index i = 0; i < nF; ++i) {
    const auto v = static_cast<std::size_t>(free_[static_cast<std::size_t>(i)]);
    outer[i + 1] = outer[i] + 3 * (vt.offsets[v + 1] - vt.offsets[v]);
  }
  R.resizeNonZeros(outer[nF]);
  int* inner = R.innerIndexPtr();
  double* values = R.valuePtr();
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < nF; ++i) {
    const int v = free_[static_cast<std::size_t>(i)];
    int k = outer[i];
    for (int t = vt.offsets[v]; t < vt.offsets[v + 1]; ++t) {  // ascending triangles
      const int l = vt.triangles[static_cast<std::size_t>(t)];
      const int c = F(l, 0) == v ? 0 : (F(l, 1) == v ? 1 : 2);
      for (int d = 0; d < 3; ++d) {
        inner[k] = 3 * l + d;
        values[k++] = grads(l, 3 * c + d) * areas[l];  // Gᵀ A's entry: ∇φ times a_l
      }
    }
  }
  return R;
}

}  // namespace hdeform

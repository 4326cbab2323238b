#include "engine/operators/sparse_times3.h"

#include "engine/runtime/two_threads.h"

#include <cassert>

namespace hdeform {

void sparse_times3(const SparseMatrixR& A, const GuidanceField& X, Eigen::MatrixXd& Y) {
  assert(A.isCompressed() && A.cols() == X.rows());
  const Eigen::Index rows = A.rows();
  Y.resize(rows, 3);
  const auto* outer = A.outerIndexPtr();
  const auto* inner = A.innerIndexPtr();
  const double* a = A.valuePtr();
  const double* x = X.data();  // row j at x + 3j
  double* y0 = Y.col(0).data();
  double* y1 = Y.col(1).data();
  double* y2 = Y.col(2).data();
  for_chunks(rows, [&](Eigen::Index i0, Eigen::Index i1, int) {
    for (Eigen::Index i = i0; i < i1; ++i) {
      double s0 = 0, s1 = 0, s2 = 0;
      for (auto p = outer[i]; p < outer[i + 1]; ++p) {
        const double v = a[p];
        const double* xj = x + 3 * static_cast<Eigen::Index>(inner[p]);
        s0 += v * xj[0];
        s1 += v * xj[1];
        s2 += v * xj[2];
      }
      y0[i] = s0;
      y1[i] = s1;
      y2[i] = s2;
    }
  });
}

namespace {

// Row i of Y = B − K X goes to y + i·row, its columns col apart.
void residual_rows(const SparseMatrix& K, const Eigen::MatrixXd& X, const Eigen::MatrixXd& B,
                   double* y, Eigen::Index row, Eigen::Index col) {
  assert(K.isCompressed() && K.rows() == K.cols() && X.rows() == K.cols() && B.rows() == K.rows());
  assert(X.cols() == 3 && B.cols() == 3 && y != X.data());
  const Eigen::Index n = K.rows();
  const auto* outer = K.outerIndexPtr();
  const auto* inner = K.innerIndexPtr();
  const double* k = K.valuePtr();
  const double *x0 = X.col(0).data(), *x1 = X.col(1).data(), *x2 = X.col(2).data();
  const double *b0 = B.col(0).data(), *b1 = B.col(1).data(), *b2 = B.col(2).data();
  for_chunks(n, [&](Eigen::Index i0, Eigen::Index i1, int) {
    for (Eigen::Index i = i0; i < i1; ++i) {
      double s0 = 0, s1 = 0, s2 = 0;
      for (auto p = outer[i]; p < outer[i + 1]; ++p) {
        const double v = k[p];
        const Eigen::Index j = inner[p];
        s0 += v * x0[j];
        s1 += v * x1[j];
        s2 += v * x2[j];
      }
      double* yi = y + i * row;
      yi[0] = b0[i] - s0;
      yi[col] = b1[i] - s1;
      yi[2 * col] = b2[i] - s2;
    }
  });
}

}  // namespace

void symmetric_residual3(const SparseMatrix& K, const Eigen::MatrixXd& X, const Eigen::MatrixXd& B,
                         Eigen::MatrixXd& Y) {
  Y.resize(K.rows(), 3);
  residual_rows(K, X, B, Y.data(), 1, Y.rows());
}

void symmetric_residual3(const SparseMatrix& K, const Eigen::MatrixXd& X, const Eigen::MatrixXd& B,
                         Rows3& Y) {
  Y.resize(K.rows(), 3);
  residual_rows(K, X, B, Y.data(), 3, 1);
}

}  // namespace hdeform

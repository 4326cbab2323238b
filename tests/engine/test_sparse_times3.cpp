// sparse_times3.h against Eigen's products: the same bits (the kernels sum each row in Eigen's
// order), whatever the OpenMP thread count.
#include "engine/operators/sparse_times3.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <random>
#include <vector>

namespace hdeform {
namespace {

// A random symmetric n × n matrix with about `per_row` entries a row (and a full diagonal).
SparseMatrix random_symmetric(int n, int per_row, std::mt19937& rng) {
  std::uniform_int_distribution<int> col(0, n - 1);
  std::uniform_real_distribution<double> val(-1, 1);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 4.0 + val(rng));
    for (int k = 0; k < per_row / 2; ++k) {
      const int j = col(rng);
      const double v = val(rng);
      t.emplace_back(i, j, v);
      t.emplace_back(j, i, v);
    }
  }
  SparseMatrix K(n, n);
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

class SparseTimes3 : public ::testing::TestWithParam<int> {};  // OpenMP threads

TEST_P(SparseTimes3, RowMajorTimesGuidanceIsEigensProductBitForBit) {
  omp_set_num_threads(GetParam());
  std::mt19937 rng(7);
  const int rows = 5000, cols = 3 * 9000;
  std::uniform_int_distribution<int> col(0, cols - 1);
  std::uniform_real_distribution<double> val(-1, 1);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < rows; ++i)
    for (int k = 0; k < i % 23; ++k) t.emplace_back(i, col(rng), val(rng));  // some rows empty
  SparseMatrixR A(rows, cols);
  A.setFromTriplets(t.begin(), t.end());
  GuidanceField g(cols, 3);
  for (Eigen::Index i = 0; i < g.size(); ++i) g.data()[i] = val(rng) * 1e3;
  Eigen::MatrixXd expected(rows, 3);
  expected.noalias() = A * g;
  Eigen::MatrixXd got;
  sparse_times3(A, g, got);
  EXPECT_EQ(got, expected);
  omp_set_num_threads(omp_get_num_procs());
}

TEST_P(SparseTimes3, SymmetricResidualIsEigensBitForBit) {
  omp_set_num_threads(GetParam());
  std::mt19937 rng(11);
  const int n = 7000;
  const SparseMatrix K = random_symmetric(n, 14, rng);
  std::uniform_real_distribution<double> val(-1, 1);
  Eigen::MatrixXd X(n, 3), B(n, 3);
  for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] = val(rng), B.data()[i] = val(rng);
  Eigen::MatrixXd expected = B;
  expected.noalias() -= K.transpose() * X;  // what the drag refinement ran before the kernel
  Eigen::MatrixXd got(3, 3);                // wrong size: the kernel resizes
  symmetric_residual3(K, X, B, got);
  EXPECT_EQ(got, expected);
  // And it is the residual: K·X + Y = B to rounding.
  EXPECT_LT((K * X + got - B).cwiseAbs().maxCoeff(), 1e-12);
  Rows3 rows;  // the row-major output (the drag refinement's): the same bits
  symmetric_residual3(K, X, B, rows);
  EXPECT_EQ(Eigen::MatrixXd(rows), expected);
  omp_set_num_threads(omp_get_num_procs());
}

INSTANTIATE_TEST_SUITE_P(Threads, SparseTimes3, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hdeform

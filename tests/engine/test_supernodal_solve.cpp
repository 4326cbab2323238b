// supernodal_solve3 (the fused K_FF solve of SPEC.md §Solve over CHOLMOD's factor) against
// cholmod_solve: the bundled meshes and a procedural capsule at β = 0 and β > 0, through
// both kinds of factorization Factorization builds (own analysis; shared wide analysis).
#include "fixtures.h"
#include "procedural.h"
#include "solver.h"
#include "supernodal_solve.h"

#include <gtest/gtest.h>

#include <thread>

namespace hdeform {
namespace {

// K = (1 − β) L + β Reg (β raw; β = 0: the Laplacian alone, its narrow pattern), with the
// constrained rows and columns removed: K_FF as the engine builds it.
SparseMatrix k_ff(const PreparedMesh& pm, const Constraints& c, double beta) {
  std::vector<char> fixed(static_cast<std::size_t>(pm.n()), 0);
  for (int v : c.fixed) fixed[v] = 1;
  for (const auto& h : c.handles)
    for (int v : h) fixed[v] = 1;
  std::vector<int> index(fixed.size(), -1);
  int nF = 0;
  for (std::size_t v = 0; v < fixed.size(); ++v)
    if (!fixed[v]) index[v] = nF++;
  const SparseMatrix K = beta == 0 ? SparseMatrix(pm.L()) : SparseMatrix((1 - beta) * pm.L() + beta * pm.Reg());
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index col = 0; col < K.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(K, col); it; ++it)
      if (index[it.row()] >= 0 && index[col] >= 0)
        t.emplace_back(index[it.row()], index[col], it.value());
  SparseMatrix K_FF(nF, nF);
  K_FF.setFromTriplets(t.begin(), t.end());
  return K_FF;
}

double rel_max_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

Eigen::MatrixXd fused(const Factorization& f, const Eigen::MatrixXd& B, SupernodalWorkspace& ws) {
  Eigen::MatrixXd X(B.rows(), 3);
  supernodal_solve3(*f.factor(), B.data(), B.rows(), X.data(), X.rows(), ws);
  return X;
}

// Both factorization kinds at β = 0 and two β > 0 on one model; random B.
void check_model(const PreparedMesh& pm, const Constraints& c, SupernodalWorkspace& ws) {
  std::srand(11);
  const Factorization f0(k_ff(pm, c, 0.0));
  ASSERT_TRUE(supernodal_solvable(f0.factor()));
  const Eigen::MatrixXd B0 = Eigen::MatrixXd::Random(f0.size(), 3);
  EXPECT_LT(rel_max_diff(fused(f0, B0, ws), f0.solve_cholmod(B0)), 1e-12) << "beta 0";
  EXPECT_LT(rel_max_diff(f0.solve(B0), f0.solve_cholmod(B0)), 1e-12) << "beta 0, solve()";
  // The BLAS path (dtrsm + dgemm) for supernodes of ≥ cut columns, alone and mixed.
  for (int cut : {1, 4, 16}) {
    SupernodalWorkspace wb;
    wb.blas_min_cols = cut;
    EXPECT_LT(rel_max_diff(fused(f0, B0, wb), f0.solve_cholmod(B0)), 1e-12) << "blas " << cut;
  }

  const SparseMatrix K1 = k_ff(pm, c, 0.3);
  const Factorization wide(K1);  // own analysis of the wide pattern
  const Eigen::MatrixXd B1 = Eigen::MatrixXd::Random(wide.size(), 3);
  EXPECT_LT(rel_max_diff(fused(wide, B1, ws), wide.solve_cholmod(B1)), 1e-12) << "beta 0.3";
  const Factorization shared(wide, k_ff(pm, c, 0.7));  // numeric on the shared analysis
  ASSERT_TRUE(supernodal_solvable(shared.factor()));
  EXPECT_LT(rel_max_diff(fused(shared, B1, ws), shared.solve_cholmod(B1)), 1e-12) << "beta 0.7";
  EXPECT_LT(rel_max_diff(shared.solve(B1), shared.solve_cholmod(B1)), 1e-12);
  for (int cut : {1, 8}) {
    SupernodalWorkspace wb;
    wb.blas_min_cols = cut;
    EXPECT_LT(rel_max_diff(fused(shared, B1, wb), shared.solve_cholmod(B1)), 1e-12) << cut;
  }
  // The residual too, not only agreement with CHOLMOD.
  const Eigen::MatrixXd X1 = fused(wide, B1, ws);
  EXPECT_LT((K1 * X1 - B1).cwiseAbs().maxCoeff(), 1e-9 * (K1 * X1).cwiseAbs().maxCoeff());
}

TEST(SupernodalSolve, MatchesCholmodOnBundledModels) {
  SupernodalWorkspace ws;  // one workspace across every model and factorization size
  for (const char* name : {"cactus", "bar"}) {
    SCOPED_TRACE(name);
    const test::Benchmark b = test::load_benchmark(name);
    check_model(*b.mesh, b.constraints, ws);
  }
}

TEST(SupernodalSolve, MatchesCholmodOnProceduralCapsule) {
  procedural::CapsuleCase cc = procedural::capsule_case(3000);
  const auto pm = PreparedMesh::create(std::move(cc.mesh));
  Constraints c;
  c.fixed = cc.base;
  c.handles = {cc.cap};
  SupernodalWorkspace ws;
  check_model(*pm, c, ws);
}

// Workspace reuse: a large factor, then a smaller one, then the large one again, with the
// same workspace; results equal a fresh workspace's bit for bit.
TEST(SupernodalSolve, WorkspaceReuseAcrossSizes) {
  const test::Benchmark cactus = test::load_benchmark("cactus");
  const test::Benchmark bar = test::load_benchmark("bar");
  const Factorization fa(k_ff(*cactus.mesh, cactus.constraints, 0.0));
  const Factorization fb(k_ff(*bar.mesh, bar.constraints, 0.0));
  ASSERT_NE(fa.size(), fb.size());
  std::srand(3);
  const Eigen::MatrixXd Ba = Eigen::MatrixXd::Random(fa.size(), 3);
  const Eigen::MatrixXd Bb = Eigen::MatrixXd::Random(fb.size(), 3);
  SupernodalWorkspace ws, fresh_a, fresh_b;
  const Eigen::MatrixXd Xa1 = fused(fa, Ba, ws);
  const Eigen::MatrixXd Xb = fused(fb, Bb, ws);
  const Eigen::MatrixXd Xa2 = fused(fa, Ba, ws);
  EXPECT_EQ(Xa1, Xa2);
  EXPECT_EQ(Xa1, fused(fa, Ba, fresh_a));
  EXPECT_EQ(Xb, fused(fb, Bb, fresh_b));
  EXPECT_GE(ws.capacity_rows(), static_cast<std::size_t>(std::max(fa.size(), fb.size())));
}

// In place (X aliases B), and B with a leading dimension larger than n.
TEST(SupernodalSolve, AliasingAndLeadingDimension) {
  const test::Benchmark bar = test::load_benchmark("bar");
  const Factorization f(k_ff(*bar.mesh, bar.constraints, 0.0));
  std::srand(5);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  SupernodalWorkspace ws;
  const Eigen::MatrixXd X = fused(f, B, ws);
  Eigen::MatrixXd inplace = B;
  supernodal_solve3(*f.factor(), inplace.data(), inplace.rows(), inplace.data(), inplace.rows(), ws);
  EXPECT_EQ(inplace, X);
  Eigen::MatrixXd padded = Eigen::MatrixXd::Zero(f.size() + 7, 3);
  padded.topRows(f.size()) = B;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(f.size() + 2, 3);
  supernodal_solve3(*f.factor(), padded.data(), padded.rows(), out.data(), out.rows(), ws);
  EXPECT_EQ(out.topRows(f.size()), X);
  EXPECT_EQ(out.bottomRows(2), Eigen::MatrixXd::Zero(2, 3));
}

// Tiny systems: 1×1, 2×2, a small SPD tridiagonal; and n = 0 through Factorization.
TEST(SupernodalSolve, TinyAndEmpty) {
  SupernodalWorkspace ws;
  for (int n : {1, 2, 3, 5, 17}) {
    std::vector<Eigen::Triplet<double>> t;
    for (int i = 0; i < n; ++i) {
      t.emplace_back(i, i, 4.0 + i);
      if (i + 1 < n) {
        t.emplace_back(i, i + 1, -1.0);
        t.emplace_back(i + 1, i, -1.0);
      }
    }
    SparseMatrix K(n, n);
    K.setFromTriplets(t.begin(), t.end());
    const Factorization f(K);
    ASSERT_TRUE(supernodal_solvable(f.factor())) << n;
    std::srand(n);
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 3);
    EXPECT_LT(rel_max_diff(fused(f, B, ws), f.solve_cholmod(B)), 1e-12) << n;
    EXPECT_LT((K * fused(f, B, ws) - B).cwiseAbs().maxCoeff(), 1e-13) << n;
  }
  const Factorization empty{SparseMatrix(0, 0)};
  EXPECT_EQ(empty.factor(), nullptr);
  EXPECT_FALSE(supernodal_solvable(nullptr));
  EXPECT_EQ(empty.solve(Eigen::MatrixXd(0, 3)).rows(), 0);
}

// Factorization::solve from two threads on one factor (thread_local workspaces) gives the
// single-threaded bits.
TEST(SupernodalSolve, ConcurrentSolvesAgree) {
  const test::Benchmark cactus = test::load_benchmark("cactus");
  const Factorization f(k_ff(*cactus.mesh, cactus.constraints, 0.0));
  std::srand(9);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  const Eigen::MatrixXd ref = f.solve(B);
  Eigen::MatrixXd r1, r2;
  std::thread t1([&] { for (int i = 0; i < 20; ++i) r1 = f.solve(B); });
  std::thread t2([&] { for (int i = 0; i < 20; ++i) r2 = f.solve(B); });
  t1.join();
  t2.join();
  EXPECT_EQ(r1, ref);
  EXPECT_EQ(r2, ref);
}

}  // namespace
}  // namespace hdeform

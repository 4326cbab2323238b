// supernodal_solve3 (the fused K_FF solve of SPEC.md §Solve over CHOLMOD's factor) against
// cholmod_solve: the bundled meshes and a procedural capsule at β = 0 and β > 0, through
// both kinds of factorization SupernodalFactorization builds (own analysis; shared wide analysis).
#include "each_isa.h"
#include "engine/solve/supernodal_factorization.h"
#include "engine/solve/supernodal_solve.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <thread>

// Counts operator new calls (for the allocation-free check below); engine_tests-wide.
// noinline: GCC's -Wmismatched-new-delete otherwise sees malloc/free through them.
namespace {
std::atomic<long> g_news{0};
}
[[gnu::noinline]] void* operator new(std::size_t size) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void* operator new[](std::size_t size) { return ::operator new(size); }
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete[](void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace hdeform {
namespace {

using test::k_ff;
using test::same_bits;

double rel_max_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

Eigen::MatrixXd fused(const SupernodalFactorization& f, const Eigen::MatrixXd& B, SupernodalWorkspace& ws) {
  Eigen::MatrixXd X(B.rows(), 3);
  supernodal_solve3(*f.factor(), B.data(), B.rows(), X.data(), X.rows(), ws);
  return X;
}

// Both factorization kinds at β = 0 and two β > 0 on one model; random B.
void check_model(const PreparedMesh& pm, const Constraints& c, SupernodalWorkspace& ws) {
  std::srand(11);
  const SupernodalFactorization f0(k_ff(pm, c, 0.0));
  ASSERT_TRUE(supernodal_solvable(f0.factor()));
  const Eigen::MatrixXd B0 = Eigen::MatrixXd::Random(f0.size(), 3);
  EXPECT_LT(rel_max_diff(fused(f0, B0, ws), f0.solve_cholmod(B0)), 1e-12) << "beta 0";
  EXPECT_LT(rel_max_diff(f0.solve(B0), f0.solve_cholmod(B0)), 1e-12) << "beta 0, solve()";

  const SparseMatrix K1 = k_ff(pm, c, 0.3);
  const SupernodalFactorization wide(K1);  // own analysis of the wide pattern
  const Eigen::MatrixXd B1 = Eigen::MatrixXd::Random(wide.size(), 3);
  EXPECT_LT(rel_max_diff(fused(wide, B1, ws), wide.solve_cholmod(B1)), 1e-12) << "beta 0.3";
  const SupernodalFactorization shared(wide, k_ff(pm, c, 0.7));  // numeric on the shared analysis
  ASSERT_TRUE(supernodal_solvable(shared.factor()));
  EXPECT_LT(rel_max_diff(fused(shared, B1, ws), shared.solve_cholmod(B1)), 1e-12) << "beta 0.7";
  EXPECT_LT(rel_max_diff(shared.solve(B1), shared.solve_cholmod(B1)), 1e-12);
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
  const test::Benchmark b = test::capsule_benchmark(3000);
  SupernodalWorkspace ws;
  check_model(*b.mesh, b.constraints, ws);
}

// Workspace reuse: a large factor, then a smaller one, then the large one again, with the
// same workspace; results equal a fresh workspace's bit for bit.
TEST(SupernodalSolve, WorkspaceReuseAcrossSizes) {
  const test::Benchmark cactus = test::load_benchmark("cactus");
  const test::Benchmark bar = test::load_benchmark("bar");
  const SupernodalFactorization fa(k_ff(*cactus.mesh, cactus.constraints, 0.0));
  const SupernodalFactorization fb(k_ff(*bar.mesh, bar.constraints, 0.0));
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
  const SupernodalFactorization f(k_ff(*bar.mesh, bar.constraints, 0.0));
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

// Tiny systems: 1×1, 2×2, a small SPD tridiagonal; and n = 0 through SupernodalFactorization.
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
    const SupernodalFactorization f(K);
    ASSERT_TRUE(supernodal_solvable(f.factor())) << n;
    std::srand(n);
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 3);
    EXPECT_LT(rel_max_diff(fused(f, B, ws), f.solve_cholmod(B)), 1e-12) << n;
    EXPECT_LT((K * fused(f, B, ws) - B).cwiseAbs().maxCoeff(), 1e-13) << n;
  }
  const SupernodalFactorization empty{SparseMatrix(0, 0)};
  EXPECT_EQ(empty.factor(), nullptr);
  EXPECT_FALSE(supernodal_solvable(nullptr));
  EXPECT_EQ(empty.solve(Eigen::MatrixXd(0, 3)).rows(), 0);
}

// SupernodalFactorization::solve from two threads on one factor (thread_local workspaces) gives the
// single-threaded bits.
TEST(SupernodalSolve, ConcurrentSolvesAgree) {
  const test::Benchmark cactus = test::load_benchmark("cactus");
  const SupernodalFactorization f(k_ff(*cactus.mesh, cactus.constraints, 0.0));
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

// ---------------------------------------------------------------------------------------
// SupernodalFactorization::solve3: the two-thread schedule and float32 factor values, on a capsule
// large enough to be split (K_FF ≥ 20K rows).

Eigen::MatrixXd solve3(const SupernodalFactorization& f, const Eigen::MatrixXd& B, SolvePrecision p,
                       int threads) {
  Eigen::MatrixXd X(B.rows(), 3);
  f.solve3(B.data(), X.data(), p, threads);
  return X;
}

// max over columns of ‖a − b‖₂ / ‖b‖₂
double rel_col2(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  double r = 0;
  for (int c = 0; c < b.cols(); ++c) r = std::max(r, (a.col(c) - b.col(c)).norm() / b.col(c).norm());
  return r;
}

// A priori bound for the float32-factor solve, relative to the exact solve, per column in
// the 2-norm. L̃ = L + E with |E| ≤ u|L| entrywise (round to nearest, u = 2⁻²⁴), so
// ‖E‖₂ ≤ u ‖|L|‖₂ ≤ u √(‖L‖₁ ‖L‖∞) =: e. The float solve is exact for A + ΔA,
// ΔA = E Lᵀ + L Eᵀ + E Eᵀ; x − x̃ = A⁻¹ ΔA x̃ gives, with ‖A⁻¹L‖ = 1/√λmin,
// ‖Lᵀ‖ = √λmax:
//   ‖x − x̃‖ / ‖x̃‖ ≤ e (√λmax + e) / λmin + e / √λmin   (plus the double solve's own
//   rounding, ~1e-13 here). λmax ≤ Gershgorin's bound; λmin from inverse iteration (which
//   overestimates it: halved for safety).
double float32_bound(const SupernodalFactorization& f, const SparseMatrix& K) {
  const cholmod_factor& L = *f.factor();
  const int* super = static_cast<const int*>(L.super);
  const int* pi = static_cast<const int*>(L.pi);
  const int* px = static_cast<const int*>(L.px);
  const int* Ls = static_cast<const int*>(L.s);
  const double* Lx = static_cast<const double*>(L.x);
  std::vector<double> row_sum(L.n, 0.0);
  double norm1 = 0;
  for (std::size_t s = 0; s < L.nsuper; ++s) {
    const int nsrow = pi[s + 1] - pi[s];
    for (int j = 0; j < super[s + 1] - super[s]; ++j) {
      double col = 0;
      for (int i = j; i < nsrow; ++i) {  // the diagonal block's upper part is not L
        const double v = std::abs(Lx[px[s] + static_cast<std::ptrdiff_t>(j) * nsrow + i]);
        col += v;
        row_sum[Ls[pi[s] + i]] += v;
      }
      norm1 = std::max(norm1, col);
    }
  }
  const double norm_inf = *std::max_element(row_sum.begin(), row_sum.end());
  const double e = std::ldexp(1.0, -24) * std::sqrt(norm1 * norm_inf);
  double lmax = 0;
  for (Eigen::Index c = 0; c < K.outerSize(); ++c) {
    double sum = 0;
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) sum += std::abs(it.value());
    lmax = std::max(lmax, sum);  // K symmetric: column sums = row sums
  }
  Eigen::MatrixXd v = Eigen::MatrixXd::Ones(K.rows(), 3);
  v.col(1).setLinSpaced(-1, 1);
  v.col(2) = v.col(1).cwiseAbs2();
  double lmin = 0;
  for (int it = 0; it < 60; ++it) {
    v = solve3(f, v, SolvePrecision::float64, 2);
    for (int c = 0; c < 3; ++c) v.col(c).normalize();
  }
  lmin = (v.col(0).transpose() * K * v.col(0)).value();
  for (int c = 1; c < 3; ++c) lmin = std::min(lmin, (v.col(c).transpose() * K * v.col(c)).value());
  lmin *= 0.5;
  const double bound = e * (std::sqrt(lmax) + e) / lmin + e / std::sqrt(lmin);
  std::printf("  float32 bound: u*sqrt(|L|_1 |L|_inf) = %.3g, lambda_max <= %.4g, "
              "lambda_min ~ %.4g (halved), bound %.3g\n", e, lmax, lmin, bound);
  return bound;
}

struct BigCase {
  std::shared_ptr<const PreparedMesh> pm;
  Constraints c;
};

const BigCase& big_case() {
  static const BigCase bc = [] {
    test::Benchmark t = test::capsule_benchmark(40000);
    return BigCase{std::move(t.mesh), std::move(t.constraints)};
  }();
  return bc;
}

void check_scheduled(double beta) {
  const BigCase& bc = big_case();
  const SparseMatrix K = k_ff(*bc.pm, bc.c, beta);
  const SupernodalFactorization f(K);
  ASSERT_GE(f.size(), 30000);
  const SupernodalSchedule& sch = f.schedule();
  ASSERT_TRUE(sch.split());
  const auto t0 = std::chrono::steady_clock::now();
  const SupernodalSchedule again(*f.factor());
  std::printf("  schedule built in %.2f ms (%.2f MB)\n",
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count(),
              static_cast<double>(again.memory_bytes()) / (1 << 20));
  double total = 0;
  for (int i = 0; i <= sch.parts(); ++i) total += sch.work(i);
  std::printf("  beta %g: n = %d, %d parts, largest %.3f, top %.3f, two-thread critical path "
              "%.3f of %.3g factor entries\n",
              beta, f.size(), sch.parts(), sch.work(0) / total, sch.work(sch.parts()) / total,
              sch.critical_path() / total, total);
  std::srand(21);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  const Eigen::MatrixXd X1 = solve3(f, B, SolvePrecision::float64, 1);
  const Eigen::MatrixXd X2 = solve3(f, B, SolvePrecision::float64, 2);
  EXPECT_TRUE(same_bits(X1, X2));
  for (int rep = 0; rep < 5; ++rep)  // thread timing differs between runs, the bits do not
    EXPECT_TRUE(same_bits(solve3(f, B, SolvePrecision::float64, 2), X2));
  EXPECT_LT(rel_max_diff(X2, f.solve_cholmod(B)), 1e-12);
  EXPECT_TRUE(same_bits(f.solve(B), X2));
  // Two callers at once: one gets the helper thread, the other runs alone; same bits.
  {
    Eigen::MatrixXd r[2] = {Eigen::MatrixXd(B.rows(), 3), Eigen::MatrixXd(B.rows(), 3)};
    bool ok[2] = {true, true};
    auto work = [&](int i) {
      for (int rep = 0; rep < 8; ++rep) {
        f.solve3(B.data(), r[i].data(), SolvePrecision::float64, 2);
        ok[i] = ok[i] && same_bits(r[i], X2);
      }
    };
    std::thread t0(work, 0), t1(work, 1);
    t0.join();
    t1.join();
    EXPECT_TRUE(ok[0] && ok[1]);
  }
  // In place.
  Eigen::MatrixXd inplace = B;
  f.solve3(inplace.data(), inplace.data(), SolvePrecision::float64, 2);
  EXPECT_TRUE(same_bits(inplace, X2));

  // No allocation after the first call of each kind on this thread (Eigen allocates
  // through malloc, not operator new: Y is preallocated anyway).
  Eigen::MatrixXd Y(B.rows(), 3);
  f.solve3(B.data(), Y.data(), SolvePrecision::float32, 2);
  const long news = g_news.load();
  for (int threads : {1, 2})
    for (SolvePrecision p : {SolvePrecision::float64, SolvePrecision::float32})
      f.solve3(B.data(), Y.data(), p, threads);
  EXPECT_EQ(g_news.load(), news);

  const Eigen::MatrixXd F1 = solve3(f, B, SolvePrecision::float32, 1);
  const Eigen::MatrixXd F2 = solve3(f, B, SolvePrecision::float32, 2);
  EXPECT_TRUE(same_bits(F1, F2));
  // Row-major B and X (solve3_rows, the drag refinement's layout): the same bits.
  using Rows = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
  const Rows B_rows = B;
  for (int threads : {1, 2}) {
    Rows X_rows(B.rows(), 3);
    f.solve3_rows(B_rows.data(), X_rows.data(), SolvePrecision::float64, threads);
    EXPECT_TRUE(same_bits(Eigen::MatrixXd(X_rows), X2));
    f.solve3_rows(B_rows.data(), X_rows.data(), SolvePrecision::float32, threads);
    EXPECT_TRUE(same_bits(Eigen::MatrixXd(X_rows), F2));
  }
  EXPECT_TRUE(same_bits(solve3(f, B, SolvePrecision::float32, 2), F2));
  const double err2 = rel_col2(X2, F2), errmax = rel_max_diff(F2, X2);
  const double bound = float32_bound(f, K);
  std::printf("  beta %g: float32 vs float64: max rel error %.3g (max norm), %.3g (column "
              "2-norm), bound %.3g\n", beta, errmax, err2, bound);
  EXPECT_LT(err2, bound);
  EXPECT_LT(errmax, 1e-3);  // what the engine can live with (mm on a metre-sized model)
}

TEST(SupernodalSolve, ScheduledTwoThreadsBeta0) { check_scheduled(0.0); }
TEST(SupernodalSolve, ScheduledTwoThreadsBetaPositive) { check_scheduled(0.3); }

// Small factors are not split and still solve through solve3 with either thread count.
TEST(SupernodalSolve, Solve3SmallUnsplit) {
  const test::Benchmark bar = test::load_benchmark("bar");
  const SupernodalFactorization f(k_ff(*bar.mesh, bar.constraints, 0.0));
  EXPECT_FALSE(f.schedule().split());
  std::srand(4);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  const Eigen::MatrixXd X = solve3(f, B, SolvePrecision::float64, 2);
  EXPECT_TRUE(same_bits(X, solve3(f, B, SolvePrecision::float64, 1)));
  EXPECT_LT(rel_max_diff(X, f.solve_cholmod(B)), 1e-12);
  const std::size_t before = f.memory_bytes();
  EXPECT_LT(rel_max_diff(solve3(f, B, SolvePrecision::float32, 2), X), 1e-3);
  EXPECT_EQ(f.memory_bytes(), before + f.factor()->xsize * sizeof(float));
}

// ---------------------------------------------------------------------------------------
// Each build of the sweep kernels this CPU runs (supernodal_sweep.h) passes the checks
// above; the tests above used the default one, the best supported.

TEST(SupernodalSweep, DefaultIsTheBestSupported) {
  EXPECT_EQ(kernel_isa(), isa_supported(Isa::avx2) ? Isa::avx2 : Isa::generic);
  EXPECT_TRUE(isa_supported(Isa::generic));
}

class SolveOnEachIsa : public test::OnEachIsa {};

TEST_P(SolveOnEachIsa, MatchesCholmod) {
  SupernodalWorkspace ws;
  const test::Benchmark cactus = test::load_benchmark("cactus");
  check_model(*cactus.mesh, cactus.constraints, ws);
}

TEST_P(SolveOnEachIsa, ScheduledBeta0) { check_scheduled(0.0); }
TEST_P(SolveOnEachIsa, ScheduledBetaPositive) { check_scheduled(0.3); }

// The builds differ in rounding only (FMA, the order of the four-row sums).
TEST_P(SolveOnEachIsa, AgreesWithTheOtherBuild) {
  const BigCase& bc = big_case();
  const SupernodalFactorization f(k_ff(*bc.pm, bc.c, 0.3));
  std::srand(21);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  const Eigen::MatrixXd X = solve3(f, B, SolvePrecision::float64, 2);
  const Isa other = GetParam() == Isa::avx2 ? Isa::generic : Isa::avx2;
  if (!set_kernel_isa(other)) GTEST_SKIP() << "only one build runs here";
  const Eigen::MatrixXd Y = solve3(f, B, SolvePrecision::float64, 2);
  EXPECT_LT(rel_max_diff(X, Y), 1e-12);
  EXPECT_FALSE(same_bits(X, Y)) << "the two builds ran the same code";
}

INSTANTIATE_TEST_SUITE_P(Isa, SolveOnEachIsa, test::kEachIsa, test::isa_param_name);

}  // namespace
}  // namespace hdeform

// supernodal_factorize (the two-core numeric factorization over CHOLMOD's symbolic analysis)
// against cholmod_factorize on the same analysis: the bundled meshes and procedural capsules
// at β = 0 and β > 0; one thread and two give the same bits; a matrix that is not positive
// definite is refused, by the kernel and by SupernodalFactorization.
#include "engine/solve/supernodal_factorization.h"
#include "engine/solve/supernodal_factorize.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace hdeform {
namespace {

using test::k_ff;

// Two copies of one symbolic analysis of K: `ref` factored by CHOLMOD, `ours` by the kernel.
struct Pair {
  CholmodLLT ref, ours;
  std::unique_ptr<SupernodalFactorPlan> plan;
};

void analyse(Pair& p, const SparseMatrix& K, std::size_t min_rows) {
  p.ref.analyzePattern(K);
  ASSERT_NE(p.ref.factor(), nullptr);
  ASSERT_TRUE(p.ref.factor()->is_super);
  p.ours.adopt_analysis(p.ref);
  p.plan = std::make_unique<SupernodalFactorPlan>(*p.ref.factor(), min_rows);
}

double rel_max_diff(const cholmod_factor& a, const cholmod_factor& b) {
  const double* x = static_cast<const double*>(a.x);
  const double* y = static_cast<const double*>(b.x);
  double diff = 0, scale = 0;
  for (std::size_t i = 0; i < a.xsize; ++i) {
    diff = std::max(diff, std::abs(x[i] - y[i]));
    scale = std::max(scale, std::abs(y[i]));
  }
  return diff / scale;
}

bool same_bits(const cholmod_factor& a, const cholmod_factor& b) {
  return a.xsize == b.xsize && std::memcmp(a.x, b.x, a.xsize * sizeof(double)) == 0;
}

// K factored by CHOLMOD and by the kernel (forced split: min_rows 0) on 1 and 2 threads.
void check(const SparseMatrix& K, const char* what) {
  SCOPED_TRACE(what);
  Pair p;
  analyse(p, K, 0);
  p.ref.factorize(K);
  ASSERT_EQ(p.ref.info(), Eigen::Success);
  p.ours.factorize_supernodal(K, *p.plan, 1);
  ASSERT_EQ(p.ours.info(), Eigen::Success);
  EXPECT_EQ(p.ours.factor()->minor, p.ours.factor()->n);
  EXPECT_LT(rel_max_diff(*p.ours.factor(), *p.ref.factor()), 1e-12);
  CholmodLLT two;
  two.adopt_analysis(p.ref);
  for (int rep = 0; rep < 3; ++rep) {  // thread timing differs between runs, the bits do not
    two.factorize_supernodal(K, *p.plan, 2);
    ASSERT_EQ(two.info(), Eigen::Success);
    EXPECT_TRUE(same_bits(*two.factor(), *p.ours.factor()));
  }
  // Without a split (one thread, supernode order): equal to CHOLMOD as well.
  const SupernodalFactorPlan serial(*p.ref.factor(), std::numeric_limits<std::size_t>::max());
  EXPECT_FALSE(serial.split().split());
  CholmodLLT one;
  one.adopt_analysis(p.ref);
  one.factorize_supernodal(K, serial, 2);
  ASSERT_EQ(one.info(), Eigen::Success);
  EXPECT_LT(rel_max_diff(*one.factor(), *p.ref.factor()), 1e-12);
  // A factor solves: K x = b to round-off.
  std::srand(5);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(K.rows(), 3);
  const Eigen::MatrixXd X = two.solve_concurrently(B);
  EXPECT_LT((K.selfadjointView<Eigen::Lower>() * X - B).cwiseAbs().maxCoeff(),
            1e-9 * B.cwiseAbs().maxCoeff() * K.cwiseAbs().sum() / static_cast<double>(K.rows()));
}

void check_model(const PreparedMesh& pm, const Constraints& c) {
  check(k_ff(pm, c, 0.0), "beta 0");
  check(k_ff(pm, c, 0.3), "beta 0.3");
}

TEST(SupernodalFactorize, MatchesCholmodOnBundledModels) {
  for (const char* name : {"cactus", "bar"}) {
    SCOPED_TRACE(name);
    const test::Benchmark b = test::load_benchmark(name);
    check_model(*b.mesh, b.constraints);
  }
}

TEST(SupernodalFactorize, MatchesCholmodOnProceduralCapsules) {
  for (int n : {3000, 40000}) {
    SCOPED_TRACE(n);
    const test::Benchmark b = test::capsule_benchmark(n);
    check_model(*b.mesh, b.constraints);
  }
}

// The kernel calls BLAS from its own two threads; OpenBLAS's pool beside them made the
// factorization 7× slower (one_blas_thread.h). Fails with OpenBLAS's default on a 2-core host.
TEST(SupernodalFactorize, LeavesOpenBlasOnOneThread) {
  using GetThreads = int (*)();
  const auto get = reinterpret_cast<GetThreads>(::dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
  if (!get) GTEST_SKIP() << "the BLAS loaded is not OpenBLAS";
  if (std::getenv("OPENBLAS_NUM_THREADS")) GTEST_SKIP() << "a user's OPENBLAS_NUM_THREADS is kept";
  const int before = get();
  const test::Benchmark b = test::capsule_benchmark(3000);
  const SparseMatrix K = k_ff(*b.mesh, b.constraints, 0.0);
  Pair p;
  analyse(p, K, 0);
  p.ours.factorize_supernodal(K, *p.plan, 2);
  ASSERT_EQ(p.ours.info(), Eigen::Success);
  EXPECT_EQ(get(), 1) << "OpenBLAS ran " << before << " threads before the factorization";
}

// The default plan splits a large factor; print where the work goes (the bench measures it).
TEST(SupernodalFactorize, DefaultPlanSplitsLargeFactors) {
  const test::Benchmark b = test::capsule_benchmark(40000);
  const PreparedMesh* pm = b.mesh.get();
  const Constraints& c = b.constraints;
  for (double beta : {0.0, 0.5}) {
    const SupernodalFactorization f(k_ff(*pm, c, beta));
    ASSERT_GE(f.size(), 20000);
    CholmodLLT llt;
    llt.analyzePattern(k_ff(*pm, c, beta));
    const SupernodalFactorPlan plan(*llt.factor());
    const TreeSplit& s = plan.split();
    ASSERT_TRUE(s.split());
    double total = 0;  // the top's two-lane supernodes count half
    for (double w : s.work) total += w;
    std::printf("  beta %g: %.3g flop, %zu parts, top %.3f, two-thread critical path %.3f of "
                "the flops\n", beta, plan.flops(), s.parts.size(), s.work.back() / total,
                s.critical / plan.flops());
    EXPECT_LE(total, plan.flops());
    EXPECT_LT(s.critical, 0.8 * total);
  }
}

// Not positive definite: the kernel names the column, SupernodalFactorization refuses the system,
// and a NaN is refused the same way (dpotrf's check).
TEST(SupernodalFactorize, RefusesIndefiniteMatrices) {
  const test::Benchmark b = test::load_benchmark("bar");
  const SparseMatrix K = k_ff(*b.mesh, b.constraints, 0.0);
  for (int variant = 0; variant < 2; ++variant) {
    SparseMatrix bad = K;
    const int j = static_cast<int>(K.rows()) / 2;
    bad.coeffRef(j, j) = variant == 0 ? -1.0 : std::numeric_limits<double>::quiet_NaN();
    for (std::size_t min_rows : {std::size_t{0}, std::numeric_limits<std::size_t>::max()}) {
      Pair p;
      analyse(p, bad, min_rows);
      const SparseMatrix& cbad = bad;
      cholmod_sparse a = Eigen::viewAsCholmod(cbad.selfadjointView<Eigen::Lower>());
      ASSERT_TRUE(cholmod_change_factor(CHOLMOD_REAL, 1, 1, 1, 1,
                                        const_cast<cholmod_factor*>(p.ours.factor()),
                                        &p.ours.cholmod()));
      const int col = supernodal_factorize(*const_cast<cholmod_factor*>(p.ours.factor()), a,
                                           *p.plan, 2);
      EXPECT_GE(col, 0) << variant;
      EXPECT_LT(col, K.rows());
      EXPECT_EQ(p.ours.factor()->minor, static_cast<std::size_t>(col));
    }
    EXPECT_THROW(SupernodalFactorization{bad}, InvalidInput) << variant;
  }
}

}  // namespace
}  // namespace hdeform

namespace hdeform {
namespace {

// A matrix with entries outside the analysed pattern (β > 0's wide K_FF on β = 0's analysis)
// is a programming error: refused, not scattered into another supernode's rows.
TEST(SupernodalFactorize, RefusesAMatrixOutsideThePattern) {
  const test::Benchmark b = test::load_benchmark("bar");
  const SparseMatrix narrow = test::k_ff(*b.mesh, b.constraints, 0.0);
  const SparseMatrix wide = test::k_ff(*b.mesh, b.constraints, 0.5);
  for (std::size_t min_rows : {std::size_t{0}, std::numeric_limits<std::size_t>::max()}) {
    CholmodLLT llt;
    llt.analyzePattern(narrow);
    const SupernodalFactorPlan plan(*llt.factor(), min_rows);
    EXPECT_THROW(llt.factorize_supernodal(wide, plan, 2), std::logic_error);
  }
}

}  // namespace
}  // namespace hdeform

namespace hdeform {
namespace {

// A pivot that fails inside a part, in a small top supernode and in a two-lane one (the two
// threads then skip work, never a barrier): refused every time, on one thread and two, and
// the call returns (a deadlock here hangs the test).
TEST(SupernodalFactorize, FailuresAnywhereInTheTreeReturn) {
  const test::Benchmark b = test::capsule_benchmark(40000);
  const PreparedMesh* pm = b.mesh.get();
  const Constraints& c = b.constraints;
  for (double beta : {0.0, 0.5}) {
    const SparseMatrix K = test::k_ff(*pm, c, beta);
    CholmodLLT sym;
    sym.analyzePattern(K);
    const cholmod_factor& L = *sym.factor();
    const SupernodalFactorPlan plan(L);
    ASSERT_TRUE(plan.split().split());
    ASSERT_FALSE(plan.two_lane().empty());
    const int* super = static_cast<const int*>(L.super);
    const int* perm = static_cast<const int*>(L.Perm);
    std::vector<std::pair<const char*, int>> where = {
        {"part", plan.split().parts.front().front()},
        {"first two-lane", plan.two_lane().front()},
        {"last two-lane", plan.two_lane().back()}};
    for (int s : plan.split().top)
      if (!std::binary_search(plan.two_lane().begin(), plan.two_lane().end(), s)) {
        where.push_back({"small top", s});
        break;
      }
    for (const auto& [what, s] : where) {
      SCOPED_TRACE(std::string(what) + ", beta " + std::to_string(beta));
      SparseMatrix bad = K;
      const int j = perm[super[s]];  // the supernode's first column, in K's numbering
      bad.coeffRef(j, j) = -1.0;
      for (int threads : {1, 2, 2, 2, 2}) {
        CholmodLLT llt;
        llt.adopt_analysis(sym);
        llt.factorize_supernodal(bad, plan, threads);
        EXPECT_EQ(llt.info(), Eigen::NumericalIssue);
        EXPECT_GE(llt.factor()->minor, static_cast<std::size_t>(super[s]));
        EXPECT_LT(llt.factor()->minor, L.n);
      }
    }
  }
}

}  // namespace
}  // namespace hdeform

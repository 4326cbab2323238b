// The per-mesh nested dissection (vertex_ordering.h) restricted to a constraint set's free
// vertices, against METIS run on K_FF itself: the same solutions, a comparable fill, and
// the constraint set's factorizations built from it.
#include "engine/runtime/run_beside.h"
#include "engine/runtime/serial_openmp.h"
#include "engine/solve/supernodal_factorization.h"
#include "engine/solve/vertex_ordering.h"
#include "fixtures.h"
#include "fixtures/procedural.h"
#include "fixtures/sanitizers.h"

#include <Eigen/CholmodSupport>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <csignal>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <utility>

namespace hdeform {
namespace {

using test::free_vertices;
using test::k_ff;

bool is_permutation_of_iota(std::vector<int> p) {
  std::sort(p.begin(), p.end());
  for (std::size_t i = 0; i < p.size(); ++i)
    if (p[i] != static_cast<int>(i)) return false;
  return true;
}

TEST(VertexOrdering, RestrictKeepsTheRelativeOrderOfTheFreeVertices) {
  // Vertices 0..5 eliminated in the order 4 0 5 2 1 3; free vertices 1, 2, 4 are rows 0, 1, 2.
  const std::vector<int> order{4, 0, 5, 2, 1, 3};
  EXPECT_EQ(restrict_order(order, {1, 2, 4}), (std::vector<int>{2, 1, 0}));
  EXPECT_EQ(restrict_order(order, {}), std::vector<int>{});
  EXPECT_THROW(restrict_order({0, 1, 1}, {1, 2}), std::logic_error);  // not a permutation
  EXPECT_THROW(restrict_order(order, {7}), std::out_of_range);
}

// Solutions through the restricted order equal METIS-on-K_FF's; the fill stays close.
// max_ratio: the factor's nnz through the mesh order over METIS-on-K_FF's.
void check_model(const char* name, const PreparedMesh& pm, const Constraints& c,
                 double max_ratio = 1.3) {
  SCOPED_TRACE(name);
  const std::vector<int> free = free_vertices(pm, c);
  const std::vector<int>& order = pm.order();
  ASSERT_EQ(order.size(), static_cast<std::size_t>(pm.n()));
  EXPECT_TRUE(is_permutation_of_iota(order));
  EXPECT_EQ(nested_dissection(validate_mesh(pm.mesh()).edges), order)
      << "METIS is deterministic";
  for (double beta : {0.0, 0.4}) {
    const SparseMatrix K = k_ff(pm, c, beta);
    const auto perm = restrict_order(beta == 0 ? pm.order() : pm.wide_order(), free);
    ASSERT_TRUE(is_permutation_of_iota(perm));
    const SupernodalFactorization metis(K, false);
    const SupernodalFactorization given(K, false, &perm);
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(K.rows(), 3);
    const Eigen::MatrixXd X = given.solve_cholmod(B), Xm = metis.solve_cholmod(B);
    EXPECT_LT((X - Xm).cwiseAbs().maxCoeff(), 1e-10 * Xm.cwiseAbs().maxCoeff()) << beta;
    EXPECT_LT((K * X - B).cwiseAbs().maxCoeff(), 1e-9 * B.cwiseAbs().maxCoeff()) << beta;
    // The kernel over the given-order factor too (its schedule is built from that factor).
    EXPECT_LT((given.solve(B) - X).cwiseAbs().maxCoeff(), 1e-12 * X.cwiseAbs().maxCoeff());
    const double ratio = static_cast<double>(given.factor()->xsize) /
                         static_cast<double>(metis.factor()->xsize);
    std::printf("[ measured ] %s beta %.1f: factor nnz %zu (mesh order) vs %zu (METIS on K_FF), "
                "ratio %.3f\n",
                name, beta, static_cast<std::size_t>(given.factor()->xsize),
                static_cast<std::size_t>(metis.factor()->xsize), ratio);
    EXPECT_LT(ratio, max_ratio) << "the restricted order lost METIS's fill";
  }
}

TEST(VertexOrdering, RestrictedMeshOrderSolvesLikeMetisOnKFF) {
  std::srand(5);
  for (const char* name : {"cactus", "bar"}) {
    const test::Benchmark b = test::load_benchmark(name);
    check_model(name, *b.mesh, b.constraints);
  }
  procedural::CapsuleCase cc = procedural::capsule_case(8000);
  const auto pm = PreparedMesh::create(std::move(cc.mesh));
  Constraints c;
  c.fixed = cc.base;
  c.handles = {cc.cap};
  check_model("capsule 8K", *pm, c);
}

// Above kSplitOrderFrom the order is METIS's separator, then each half by METIS on a thread
// of its own: a permutation, the same on every call, with METIS's fill (a lost edge in a
// half's graph or a vertex mapped back to the wrong id would not keep it: halves ordered
// backwards give 3.1× and 5.8×). One METIS call on this capsule gives 1.045 and 1.058.
TEST(VertexOrdering, SplitOrderKeepsMetisFill) {
  procedural::CapsuleCase cc = procedural::capsule_case(30000);
  const auto pm = PreparedMesh::create(std::move(cc.mesh));
  ASSERT_GE(static_cast<std::size_t>(pm->n()), kSplitOrderFrom);
  Constraints c;
  c.fixed = cc.base;
  c.handles = {cc.cap};
  check_model("capsule 30K", *pm, c, 1.08);
  EXPECT_EQ(nested_dissection(pm->L(), pm->Reg()), pm->wide_order());
}

// validate_mesh's edge graph is L's pattern without the diagonal, plus the edges whose
// cotangent weights cancel (L drops exact zeros: bar's right triangles have them). METIS
// gives it one order, whoever asks: one call below kSplitOrderFrom, the split order above;
// a mesh with a border and a vertex no triangle uses (an empty column) included.
TEST(VertexOrdering, EdgeGraphIsLsPatternWithItsZeros) {
  auto check = [](const char* name, TriMesh mesh, bool zeros) {
    SCOPED_TRACE(name);
    const EdgePattern edges = validate_mesh(mesh).edges;
    ASSERT_EQ(edges.start.size(), static_cast<std::size_t>(mesh.num_vertices()) + 1);
    const auto pm = PreparedMesh::create(std::move(mesh), PrepareOrder::on_first_use);
    ASSERT_FALSE(pm->has_order());
    const SparseMatrix& L = pm->L();
    const auto& V = pm->mesh().V;
    const auto& F = pm->mesh().F;
    std::size_t cancelled = 0;
    for (int v = 0; v < pm->n(); ++v) {
      std::vector<int> in_L;
      for (SparseMatrix::InnerIterator it(L, v); it; ++it)
        if (it.row() > v) in_L.push_back(static_cast<int>(it.row()));
      const std::vector<int> graph(edges.rows.begin() + edges.start[v],
                                   edges.rows.begin() + edges.start[v + 1]);
      ASSERT_TRUE(std::includes(graph.begin(), graph.end(), in_L.begin(), in_L.end()))
          << "column " << v;
      for (int w : graph) {
        if (std::binary_search(in_L.begin(), in_L.end(), w)) continue;
        // An edge L lacks: the cotangents of its opposite angles sum to zero.
        ++cancelled;
        double cot_sum = 0;
        for (int l = 0; l < F.rows(); ++l) {
          int iv = -1, iw = -1;
          for (int k = 0; k < 3; ++k) {
            if (F(l, k) == v) iv = k;
            if (F(l, k) == w) iw = k;
          }
          if (iv < 0 || iw < 0) continue;
          const Eigen::RowVector3d o = V.row(F(l, 3 - iv - iw));
          const Eigen::RowVector3d a = V.row(v) - o, b = V.row(w) - o;
          cot_sum += a.dot(b) / a.cross(b).norm();
        }
        EXPECT_NEAR(cot_sum, 0.0, 1e-12) << "edge " << v << "–" << w;
      }
    }
    EXPECT_EQ(cancelled > 0, zeros);
    const std::vector<int> order = nested_dissection(edges);
    EXPECT_EQ(pm->order(), order) << "order() orders the same graph";
    if (!zeros) {
      EXPECT_EQ(order, nested_dissection(L)) << "the graph is L's pattern";
    }
  };
  check("cactus", read_mesh(test::data_path("botsch-sorkine/cactus.off")).mesh, false);
  check("bar", read_mesh(test::data_path("botsch-sorkine/bar.off")).mesh, true);
  procedural::CapsuleCase small = procedural::capsule_case(8000);
  small.mesh.V.conservativeResize(small.mesh.V.rows() + 1, 3);
  small.mesh.V.row(small.mesh.V.rows() - 1) = Eigen::RowVector3d(9, 9, 9);  // unreferenced
  check("capsule 8K + 1", std::move(small.mesh), false);
  procedural::CapsuleCase large = procedural::capsule_case(30000);
  ASSERT_GE(static_cast<std::size_t>(large.mesh.num_vertices()), kSplitOrderFrom);
  check("capsule 30K", std::move(large.mesh), false);
  EXPECT_THROW(nested_dissection(EdgePattern{{0, 2}, {1}}), std::logic_error);
}

// create() orders the edge graph beside the operators (PrepareOrder::with_operators, its
// default): the order is there when it returns, the one order() computes on first use.
TEST(VertexOrdering, CreateOrdersBesideTheOperators) {
  for (int n : {8000, 30000}) {
    procedural::CapsuleCase cc = procedural::capsule_case(n);
    const auto now = PreparedMesh::create(cc.mesh);
    const auto later = PreparedMesh::create(std::move(cc.mesh), PrepareOrder::on_first_use);
    ASSERT_TRUE(now->has_order());
    EXPECT_GT(now->build_timings().order_ms, 0.0);
    ASSERT_FALSE(later->has_order());
    EXPECT_EQ(now->order(), later->order());
    EXPECT_FALSE(now->adopt_order(later->order(), false)) << "already there";
    EXPECT_EQ(now->L().nonZeros(), later->L().nonZeros());
  }
}

// A symmetric n × n matrix with the given edges (i, j) off the diagonal, each once.
SparseMatrix pattern(int n, const std::vector<std::pair<int, int>>& edges) {
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) t.emplace_back(i, i, 4.0);
  for (auto [i, j] : edges) t.emplace_back(i, j, -1.0), t.emplace_back(j, i, -1.0);
  SparseMatrix M(n, n);
  M.setFromTriplets(t.begin(), t.end());
  return M;
}

// An n-vertex grid graph's pattern (rows of 100, the last row short).
SparseMatrix grid(int n) {
  std::vector<std::pair<int, int>> edges;
  for (int v = 0; v < n; ++v)
    for (int w : {v % 100 ? v - 1 : -1, v - 100})
      if (w >= 0) edges.emplace_back(v, w);
  return pattern(n, edges);
}

// METIS called once through CHOLMOD, as below kSplitOrderFrom.
std::vector<int> one_metis_call(const SparseMatrix& A) {
  cholmod_common c;
  cholmod_start(&c);
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  std::vector<int> order(static_cast<std::size_t>(A.rows()));
  const int ok = cholmod_metis(&a, nullptr, 0, 0, order.data(), &c);
  cholmod_finish(&c);
  EXPECT_TRUE(ok);
  return order;
}

// The split starts at kSplitOrderFrom vertices exactly: one vertex fewer is METIS's one call;
// from it on, a separator and two halves, each half drawing METIS's stream from its start, so
// the order differs from the one call's.
TEST(VertexOrdering, SplitOrderStartsAtItsThreshold) {
  const int n = static_cast<int>(kSplitOrderFrom);
  const SparseMatrix below = grid(n - 1), at = grid(n);
  EXPECT_EQ(nested_dissection(below), one_metis_call(below));
  const std::vector<int> split = nested_dissection(at);
  EXPECT_TRUE(is_permutation_of_iota(split));
  EXPECT_NE(split, one_metis_call(at));
}

}  // namespace
}  // namespace hdeform

// A malloc that fails the k-th call on a thread that asked for it, for the test below; the
// sanitizers bring their own malloc, so it is left out of their builds.
#if !HDEFORM_SANITIZED
namespace {
thread_local long mallocs_until_failure = -1;  // −1: never
}  // namespace
extern "C" void* __libc_malloc(std::size_t size);
extern "C" void* malloc(std::size_t size) {
  if (mallocs_until_failure >= 0 && mallocs_until_failure-- == 0) return nullptr;
  return __libc_malloc(size);
}
#endif

namespace hdeform {
namespace {

// Memory running out anywhere in the split order is an exception, never the end of the
// process: METIS_NodeND traps its allocation failures itself, and the separator call, which
// Debian's METIS leaves untrapped, is trapped by vertex_ordering.cpp. A child process fails
// the caller's k-th allocation for k = 0, 1, 2, … through the separator and past it, then
// orders with nothing failing; the signal handlers end as they began.
TEST(VertexOrdering, SplitOrderOutOfMemoryIsAnError) {
#if HDEFORM_SANITIZED
  GTEST_SKIP() << "the sanitizers' malloc cannot be made to fail";
#else
  procedural::CapsuleCase cc = procedural::capsule_case(30000);
  const auto pm = PreparedMesh::create(std::move(cc.mesh));
  const SparseMatrix& L = pm->L();
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const auto abort_handler = std::signal(SIGABRT, SIG_DFL);
    std::signal(SIGABRT, abort_handler);
    std::freopen("/dev/null", "w", stdout);  // METIS prints each failure and its memory
    int in_separator = 0, elsewhere = 0;
    bool past_it = false;  // a failure after the separator's
    // Each k up to the separator's first allocation, then every 17th through it.
    for (long k = 0; k < 5000 && !past_it; k += in_separator ? 17 : 1) {
      mallocs_until_failure = k;
      try {
        nested_dissection(L);
      } catch (const std::exception& e) {
        if (std::strstr(e.what(), "vertex separator")) {
          ++in_separator;
        } else {
          ++elsewhere;
          past_it = in_separator > 0;
        }
      }
      mallocs_until_failure = -1;
    }
    std::fprintf(stderr, "[ measured ] failed allocations: %d in the separator, %d elsewhere\n",
                 in_separator, elsewhere);
    const bool ordered = is_permutation_of_iota(nested_dissection(L));
    const bool handlers = std::signal(SIGABRT, abort_handler) == abort_handler;
    // More than one: the first is gk_malloc_init's own, before the trap is set.
    ::_exit(in_separator < 2 ? 3 : !ordered ? 4 : !handlers ? 5 : 0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "a failed allocation ended the process (signal "
                                 << (WIFSIGNALED(status) ? WTERMSIG(status) : 0) << ")";
  EXPECT_NE(WEXITSTATUS(status), 3) << "no allocation failed inside the separator's trap";
  EXPECT_NE(WEXITSTATUS(status), 4) << "no order after the failures";
  EXPECT_NE(WEXITSTATUS(status), 5) << "the failures left GKlib's signal handler in place";
  EXPECT_EQ(WEXITSTATUS(status), 0);
#endif
}

// Graphs above kSplitOrderFrom that METIS's separator could trip on: no edge at all (the
// identity, as below it), and many small components (every vertex once).
TEST(VertexOrdering, SplitOrderTakesEdgelessAndScatteredGraphs) {
  const int n = static_cast<int>(kSplitOrderFrom) + 3000;
  const SparseMatrix I = pattern(n, {});
  std::vector<int> identity(static_cast<std::size_t>(n));
  std::iota(identity.begin(), identity.end(), 0);
  EXPECT_EQ(nested_dissection(I), identity);
  std::vector<std::pair<int, int>> edges;
  for (int v = 0; v + 2 < n; v += 3)  // disjoint triangles
    for (auto e : {std::pair{v + 1, v}, {v + 2, v}, {v + 2, v + 1}}) edges.push_back(e);
  const SparseMatrix T = pattern(n, edges);
  const std::vector<int> order = nested_dissection(T);
  EXPECT_TRUE(is_permutation_of_iota(order));
  EXPECT_EQ(nested_dissection(T), order);
}

// METIS's draws come from the stream vertex_ordering.cpp keeps, not libc's: a program's own
// rand() sequence goes on as if METIS had not run (it would skip ahead with GKlib's own).
TEST(VertexOrdering, MetisDrawsFromItsOwnStream) {
  const test::Benchmark b = test::load_benchmark("bar");
  std::srand(20261206);
  const int first = std::rand();
  std::srand(20261206);
  ASSERT_FALSE(nested_dissection(b.mesh->L()).empty());
  EXPECT_EQ(std::rand(), first) << "METIS drew from libc's rand(): the per-thread stream is not "
                                   "in effect (is gk_randint64 exported from this program?)";
}

// The graph is the union of the patterns' strictly lower parts: a diagonal adds no edge, an
// edge both parts hold is one, and vertices without edges are still ordered.
TEST(VertexOrdering, GraphIsTheUnionOfTheLowerPatterns) {
  const SparseMatrix diagonal = pattern(5, {});
  EXPECT_EQ(nested_dissection(diagonal), (std::vector<int>{0, 1, 2, 3, 4}));
  // A path 0–1–2–3–4 and vertex 5 alone, split over two parts that share the edge 1–2.
  const SparseMatrix A = pattern(6, {{1, 0}, {2, 1}}), B = pattern(6, {{2, 1}, {3, 2}, {4, 3}});
  const std::vector<int> order = nested_dissection(A, B);
  EXPECT_TRUE(is_permutation_of_iota(order));
  EXPECT_EQ(order, nested_dissection(pattern(6, {{1, 0}, {2, 1}, {3, 2}, {4, 3}})));
  EXPECT_THROW(nested_dissection(A, pattern(5, {})), std::logic_error);
}

// Two constraint sets on one mesh: the first computes the mesh's orderings (β = 0 at open,
// the wide one at its first β > 0), the second none. Their deformations are the engine's
// usual ones (test_thesis_table.cpp checks the benchmark's through this same path).
TEST(VertexOrdering, ConstraintSetsShareTheMeshOrder) {
  test::Benchmark b = test::load_benchmark("cactus");
  b.mesh = PreparedMesh::create(b.mesh->mesh(), PrepareOrder::on_first_use);
  ConstraintSet first(b.mesh, b.constraints);
  EXPECT_GT(first.open_timings().system.ordering_ms, 0.0);
  first.prepare(Beta{0.3});
  EXPECT_GT(first.last_build_timings().ordering_ms, 0.0);
  Constraints other = b.constraints;
  other.handles[0].resize(other.handles[0].size() / 2);
  ConstraintSet second(b.mesh, other);
  EXPECT_EQ(second.open_timings().system.ordering_ms, 0.0);
  second.prepare(Beta{0.3});
  EXPECT_EQ(second.last_build_timings().ordering_ms, 0.0);
}

}  // namespace
}  // namespace hdeform

namespace hdeform {
namespace {

// An order that fails in create() (memory running out in it) fails no open: the mesh keeps
// its edge graph and order() orders it on first use. With no beside thread and serial
// loops the order runs on this thread right after the operators, and the allocations
// before it are the same in every run: the next one is made to fail.
TEST(VertexOrdering, AnOrderThatFailsInCreateIsComputedOnFirstUse) {
#if HDEFORM_SANITIZED
  GTEST_SKIP() << "the sanitizers' malloc cannot be made to fail";
#else
  const TriMesh mesh = procedural::capsule_case(8000).mesh;
  const int limit = beside_threads().limit;
  set_beside_thread_limit(0);
  SerialOpenMP serial;
  constexpr long kMany = 1L << 40;
  mallocs_until_failure = kMany;
  PreparedMesh::create(mesh, PrepareOrder::on_first_use);  // validation and operators alone
  const long before_order = kMany - mallocs_until_failure;
  mallocs_until_failure = before_order;
  std::shared_ptr<const PreparedMesh> pm;
  try {
    pm = PreparedMesh::create(mesh, PrepareOrder::with_operators);
  } catch (const std::exception& e) {
    ADD_FAILURE() << "the open failed: " << e.what();
  }
  const bool failed = mallocs_until_failure == -1;
  mallocs_until_failure = -1;
  set_beside_thread_limit(limit);
  ASSERT_TRUE(failed) << "no allocation failed";
  ASSERT_TRUE(pm);
  EXPECT_FALSE(pm->has_order()) << "the failed order is not there";
  EXPECT_EQ(pm->order(), nested_dissection(validate_mesh(mesh).edges));
#endif
}

// An order kept from an earlier process (the service's state store) is taken as it is, a
// bad one is refused, and the same order gives the same frame bits as the METIS call did.
TEST(VertexOrdering, AnAdoptedOrderIsTakenAsItIsAndABadOneIsRefused) {
  const test::Benchmark b = test::load_benchmark("bar");
  const PreparedMesh& computed = *b.mesh;
  auto fresh = [&] { return PreparedMesh::create(computed.mesh(), PrepareOrder::on_first_use); };

  const auto refused = fresh();
  std::vector<int> shorter(computed.order().begin(), computed.order().end() - 1);
  EXPECT_FALSE(refused->adopt_order(shorter, false)) << "wrong size";
  std::vector<int> twice = computed.order();
  twice[1] = twice[0];
  EXPECT_FALSE(refused->adopt_order(twice, false)) << "a vertex twice";
  std::vector<int> outside = computed.order();
  outside[0] = refused->n();
  EXPECT_FALSE(refused->adopt_order(outside, true)) << "an id out of range";
  EXPECT_FALSE(refused->has_order());
  EXPECT_FALSE(refused->has_wide_order());

  // Any permutation is taken, and kept: a later adopt or call does not replace it.
  const auto reversed = fresh();
  std::vector<int> rev(static_cast<std::size_t>(reversed->n()));
  std::iota(rev.rbegin(), rev.rend(), 0);
  ASSERT_TRUE(reversed->adopt_order(rev, false));
  EXPECT_TRUE(reversed->has_order());
  double ms = -1;
  EXPECT_EQ(reversed->order(&ms), rev);
  EXPECT_EQ(ms, 0) << "no METIS call";
  EXPECT_FALSE(reversed->adopt_order(computed.order(), false)) << "already there";
  EXPECT_EQ(reversed->order(), rev);

  // The computed orders adopted by a fresh copy: the same factors, so the same bits.
  const auto adopted = fresh();
  ASSERT_TRUE(adopted->adopt_order(computed.order(), false));
  ASSERT_TRUE(adopted->adopt_order(computed.wide_order(), true));
  EXPECT_TRUE(adopted->has_wide_order());
  const ConstraintSet a(adopted, b.constraints), c(b.mesh, b.constraints);
  HandleTransform t;
  t.translation = Eigen::Vector3d(0.1, 0.3, -0.2);
  t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  for (double beta : {0.0, 0.4}) {
    const Frame fa = a.update(std::span(&t, 1), {beta, BetaUnits::area});
    const Frame fc = c.update(std::span(&t, 1), {beta, BetaUnits::area});
    EXPECT_EQ(fa.positions, fc.positions) << "beta " << beta;
  }
}

}  // namespace
}  // namespace hdeform

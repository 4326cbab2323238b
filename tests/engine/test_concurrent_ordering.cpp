// nested_dissection's calls at once (vertex_ordering.cpp: METIS's per-thread random stream
// and signal trap, and the two-thread order from kSplitOrderFrom vertices), in kernel_tests so
// that scripts/tsan.sh race-checks them (engine_tests replaces operator new, as TSan does).
#include "engine/solve/vertex_ordering.h"
#include "fixtures.h"
#include "fixtures/procedural.h"

#include <gtest/gtest.h>

#include <csignal>
#include <thread>
#include <vector>

namespace hdeform {
namespace {

// Calls at once, with no lock between them, still give each its serial order: each thread
// has its own METIS random stream (with libc's one stream, interleaved draws change them).
// One call on a mesh below kSplitOrderFrom (one thread), one above it (two threads).
void check_concurrent_calls(const PreparedMesh& pm, int rounds) {
  const SparseMatrix& L = pm.L();
  const SparseMatrix R = pm.Reg();
  const std::vector<int> narrow = nested_dissection(L), wide = nested_dissection(L, R);
  const int kRounds = rounds;
  std::vector<std::vector<std::vector<int>>> got(4, std::vector<std::vector<int>>(kRounds));
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < got.size(); ++k)
    threads.emplace_back([&, k] {
      for (auto& order : got[k]) order = k % 2 ? nested_dissection(L, R) : nested_dissection(L);
    });
  for (auto& t : threads) t.join();
  for (std::size_t k = 0; k < got.size(); ++k)
    for (int r = 0; r < kRounds; ++r) EXPECT_EQ(got[k][r], k % 2 ? wide : narrow) << k << " " << r;
}

TEST(VertexOrdering, ConcurrentCallsGiveTheSerialOrder) {
  check_concurrent_calls(*test::load_benchmark("bar").mesh, 4);
}

TEST(VertexOrdering, ConcurrentSplitCallsGiveTheSerialOrder) {
  procedural::CapsuleCase cc = procedural::capsule_case(25000);
  const auto pm = PreparedMesh::create(std::move(cc.mesh));
  ASSERT_GE(static_cast<std::size_t>(pm->n()), kSplitOrderFrom);
  check_concurrent_calls(*pm, 2);
}

// GKlib traps SIGABRT and SIGTERM while METIS runs. Calls at once, ending in any order, leave
// the process's handlers as they were (GKlib's own save and restore per call can leave its
// handler installed for good).
TEST(VertexOrdering, ConcurrentCallsLeaveTheSignalHandlersAlone) {
  const test::Benchmark b = test::load_benchmark("bar");
  const SparseMatrix& L = b.mesh->L();
  const SparseMatrix& R = b.mesh->Reg();
  const auto before_abort = std::signal(SIGABRT, SIG_DFL);
  const auto before_terminate = std::signal(SIGTERM, SIG_IGN);
  std::vector<std::thread> threads;
  for (int k = 0; k < 4; ++k)
    threads.emplace_back([&, k] {
      for (int r = 0; r < 6; ++r)
        EXPECT_FALSE((k % 2 ? nested_dissection(L, R) : nested_dissection(L)).empty());
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(std::signal(SIGABRT, before_abort), SIG_DFL);
  EXPECT_EQ(std::signal(SIGTERM, before_terminate), SIG_IGN);
}

}  // namespace
}  // namespace hdeform

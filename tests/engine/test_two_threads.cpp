// two_threads.h: claimed work runs every item exactly once whether the helper joins on time,
// late or never; for_chunks' chunks are fixed by n alone. In kernel_tests, so that
// scripts/tsan.sh race-checks the helper's join-or-close handshake.
#include "engine/runtime/two_threads.h"
#include "engine/runtime/warm_cores.h"
#include "engine/solve/supernodal_factorization.h"
#include "fixtures.h"
#include "helper_busy.h"

#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace hdeform {
namespace {

// Runs for_chunks over n and checks each index is visited once, in the chunk the formula
// names.
void expect_each_index_once(std::ptrdiff_t n) {
  std::vector<int> seen(static_cast<std::size_t>(n), 0);  // each index written by one thread
  std::atomic<int> chunks{0};
  for_chunks(n, [&](std::ptrdiff_t b, std::ptrdiff_t e, int c) {
    EXPECT_EQ(b, c * n / kChunks);
    EXPECT_EQ(e, (c + 1) * n / kChunks);
    for (std::ptrdiff_t i = b; i < e; ++i) ++seen[static_cast<std::size_t>(i)];
    chunks.fetch_add(1);
  });
  EXPECT_EQ(chunks.load(), kChunks);
  for (std::ptrdiff_t i = 0; i < n; ++i) ASSERT_EQ(seen[static_cast<std::size_t>(i)], 1) << i;
}

TEST(TwoThreads, ForChunksVisitsEachIndexOnce) {
  for (int rep = 0; rep < 200; ++rep)  // back to back: the helper joins some and misses some
    for (std::ptrdiff_t n : {0, 1, 7, 8, 9, 1000, 100003}) expect_each_index_once(n);
}

TEST(TwoThreads, ForChunksWithTheHelperBusyRunsOnTheCaller) {
  test::run_with_helper_busy([] {
    const auto caller = std::this_thread::get_id();
    for_chunks(1000, [&](std::ptrdiff_t, std::ptrdiff_t, int) {
      EXPECT_EQ(std::this_thread::get_id(), caller);
    });
    expect_each_index_once(100003);
  });
}

// The helper joins only after the caller has claimed and done every item: it finds nothing
// left, and the caller waits for it before returning (its part reads the caller's stack).
TEST(TwoThreads, AHelperThatJoinsLateFindsNothingLeft) {
  struct Ctx {
    Claims items{64};
    std::atomic<int> runs{0}, by_helper{0};
    std::atomic<bool> helper_came{false}, caller_done{false};
  } ctx;
  auto fn = [](void* p, int tid) {
    auto& c = *static_cast<Ctx*>(p);
    if (tid == 1) {
      while (!c.caller_done.load()) std::this_thread::yield();  // a late helper
      c.helper_came = true;
    }
    c.items.run(tid, [&](int) {
      c.runs.fetch_add(1);
      if (tid == 1) c.by_helper.fetch_add(1);
    });
    if (tid == 0) {
      c.caller_done = true;
      // Wait a while for the helper to join (it usually does within microseconds).
      for (int i = 0; i < 2000 && !c.helper_came.load(); ++i)
        std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
  };
  Helper::instance().offer(fn, &ctx);
  EXPECT_EQ(ctx.runs.load(), 64);
  EXPECT_EQ(ctx.by_helper.load(), 0);
  EXPECT_TRUE(ctx.helper_came.load()) << "the helper never joined within 1 s";
}

// Many short offers back to back: whether the helper joins or the caller closes first, each
// item runs once and nothing of an offer outlives it (TSan sees the stack reuse).
TEST(TwoThreads, ShortOffersBackToBack) {
  int joined = 0;
  for (int rep = 0; rep < 5000; ++rep) {
    struct Ctx {
      Claims items{3};
      std::atomic<int> runs{0};
      std::atomic<bool> helper{false};
    } ctx;
    auto fn = [](void* p, int tid) {
      auto& c = *static_cast<Ctx*>(p);
      if (tid == 1) c.helper = true;
      c.items.run(tid, [&](int) { c.runs.fetch_add(1); });
    };
    Helper::instance().offer(fn, &ctx);
    ASSERT_EQ(ctx.runs.load(), 3) << rep;
    joined += ctx.helper.load();
  }
  RecordProperty("helper_joined", joined);
}

// run() still makes a team of two (the factorization's barriers rely on it).
TEST(TwoThreads, RunAlwaysRunsBothParts) {
  for (int rep = 0; rep < 1000; ++rep) {
    std::atomic<int> parts{0};
    Barrier2 bar;
    struct Ctx {
      std::atomic<int>* parts;
      Barrier2* bar;
    } ctx{&parts, &bar};
    ASSERT_TRUE(Helper::instance().run(
        [](void* p, int) {
          auto& c = *static_cast<Ctx*>(p);
          c.parts->fetch_add(1);
          c.bar->arrive_and_wait();
        },
        &ctx));
    ASSERT_EQ(parts.load(), 2);
  }
}

// The helper never shares its caller's CPU. The service's case: spinners on every CPU (warm
// cores: no CPU is idle, so the scheduler would wake the helper where it last ran) and a
// caller that moves between CPUs (frames run on whichever worker thread is free). Without
// Helper::keep_off_caller_cpu about half of these calls ran both parts on one CPU.
TEST(TwoThreads, TheHelperRunsOffItsCallersCpu) {
  cpu_set_t process;
  ASSERT_EQ(sched_getaffinity(getpid(), sizeof process, &process), 0);
  std::vector<int> cpus;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &process)) cpus.push_back(c);
  if (cpus.size() < 2) GTEST_SKIP() << "one CPU: the helper has nowhere else to run";
  // A first call reads the process's CPUs before this thread (the main one) is pinned. Calls
  // that found the helper busy (earlier tests) leave its placement free for a while.
  ASSERT_TRUE(Helper::instance().run([](void*, int) {}, nullptr));
  std::this_thread::sleep_for(std::chrono::nanoseconds(Helper::kSharedForNs));
  WarmCores warm(static_cast<int>(cpus.size()), std::chrono::seconds(60));
  warm.extend();
  cpu_set_t mine;
  ASSERT_EQ(pthread_getaffinity_np(pthread_self(), sizeof mine, &mine), 0);
  for (int rep = 0; rep < 40; ++rep) {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpus[static_cast<std::size_t>(rep) % 2], &one);
    ASSERT_EQ(pthread_setaffinity_np(pthread_self(), sizeof one, &one), 0);
    std::atomic<int> where[2] = {-1, -1};
    ASSERT_TRUE(Helper::instance().run(
        [](void* p, int tid) { static_cast<std::atomic<int>*>(p)[tid].store(sched_getcpu()); },
        where));
    EXPECT_NE(where[0].load(), where[1].load()) << "call " << rep << ": both parts on one CPU";
  }
  pthread_setaffinity_np(pthread_self(), sizeof mine, &mine);
}

// The scheduled solve's phases are claimed (Claims): on two threads, in both precisions, the
// bits of one thread, solve after solve, and with a second caller that finds the helper busy.
TEST(TwoThreads, ClaimedSolveGivesTheBitsOfOneThread) {
  const test::Benchmark b = test::capsule_benchmark(40000);
  const SupernodalFactorization f(test::k_ff(*b.mesh, b.constraints, 0.0));
  ASSERT_TRUE(f.schedule().split());
  std::srand(3);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  for (SolvePrecision p : {SolvePrecision::float64, SolvePrecision::float32}) {
    Eigen::MatrixXd one(B.rows(), 3), two(B.rows(), 3), other(B.rows(), 3);
    f.solve3(B.data(), one.data(), p, 1);
    std::thread second([&] {
      for (int rep = 0; rep < 4; ++rep) {
        f.solve3(B.data(), other.data(), p, 2);
        EXPECT_TRUE(test::same_bits(other, one));
      }
    });
    for (int rep = 0; rep < 4; ++rep) {
      f.solve3(B.data(), two.data(), p, 2);
      EXPECT_TRUE(test::same_bits(two, one));
    }
    second.join();
  }
}

}  // namespace
}  // namespace hdeform

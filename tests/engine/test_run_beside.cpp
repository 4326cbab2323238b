// run_beside (engine/runtime/run_beside.h): the threads a call starts beside its caller come
// from one budget, never more at once than its limit, and a call without one does both parts
// on its caller with the same result. In kernel_tests, so scripts/tsan.sh race-checks it.
#include "engine/deform/deformer.h"
#include "engine/runtime/run_beside.h"
#include "engine/solve/vertex_ordering.h"
#include "fixtures/procedural.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

namespace hdeform {
namespace {

// Sets the process's limit for one test and puts the one before back.
struct Limit {
  int before = beside_threads().limit;
  explicit Limit(int n) { set_beside_thread_limit(n); }
  ~Limit() { set_beside_thread_limit(before); }
};

TEST(RunBeside, SideRunsOnAThreadOfTheBudgetAndGivesItBack) {
  Limit limit(2);
  const BesideThreads before = beside_threads();
  const auto caller = std::this_thread::get_id();
  std::thread::id main_on, side_on;
  int running_during_side = -1;
  run_beside([&] { main_on = std::this_thread::get_id(); },
             [&] {
               side_on = std::this_thread::get_id();
               running_during_side = beside_threads().running;
             });
  EXPECT_EQ(main_on, caller);
  EXPECT_NE(side_on, caller);
  EXPECT_EQ(running_during_side, before.running + 1);
  const BesideThreads after = beside_threads();
  EXPECT_EQ(after.running, before.running);
  EXPECT_EQ(after.started, before.started + 1);
  EXPECT_EQ(after.refused, before.refused);
}

TEST(RunBeside, SpentBudgetRunsBothPartsOnTheCallerInTurn) {
  Limit limit(0);
  const BesideThreads before = beside_threads();
  const auto caller = std::this_thread::get_id();
  std::vector<std::pair<char, std::thread::id>> ran;
  run_beside([&] { ran.emplace_back('m', std::this_thread::get_id()); },
             [&] { ran.emplace_back('s', std::this_thread::get_id()); });
  ASSERT_EQ(ran.size(), 2u);
  EXPECT_EQ(ran[0], std::make_pair('m', caller));
  EXPECT_EQ(ran[1], std::make_pair('s', caller));
  const BesideThreads after = beside_threads();
  EXPECT_EQ(after.started, before.started);
  EXPECT_EQ(after.refused, before.refused + 1);
}

// Eight callers at once with a limit of one: never two side threads at once, and every
// call still runs both parts.
TEST(RunBeside, CallsAtOnceNeverHoldMoreThreadsThanTheLimit) {
  Limit limit(1);
  const BesideThreads before = beside_threads();
  std::atomic<int> beside_now{0}, most{0}, mains{0}, sides{0};
  std::vector<std::thread> callers;
  for (int k = 0; k < 8; ++k)
    callers.emplace_back([&] {
      const auto caller = std::this_thread::get_id();
      for (int r = 0; r < 5; ++r)
        run_beside([&] { ++mains; std::this_thread::sleep_for(std::chrono::milliseconds(2)); },
                   [&] {
                     ++sides;
                     if (std::this_thread::get_id() == caller) return;
                     const int now = ++beside_now;
                     int seen = most.load();
                     while (now > seen && !most.compare_exchange_weak(seen, now)) {
                     }
                     std::this_thread::sleep_for(std::chrono::milliseconds(3));
                     --beside_now;
                   });
    });
  for (auto& t : callers) t.join();
  EXPECT_EQ(mains.load(), 40);
  EXPECT_EQ(sides.load(), 40);
  EXPECT_EQ(most.load(), 1);
  const BesideThreads after = beside_threads();
  EXPECT_EQ(after.running, before.running);
  EXPECT_EQ(after.started - before.started + after.refused - before.refused, 40u);
  EXPECT_GT(after.refused, before.refused);  // 8 callers, 1 thread: some ran alone
}

TEST(RunBeside, MainsExceptionWaitsForTheSideAndGivesTheThreadBack) {
  Limit limit(2);
  const BesideThreads before = beside_threads();
  std::atomic<bool> side_done{false};
  EXPECT_THROW(run_beside([] { throw std::runtime_error("main"); },
                          [&] {
                            std::this_thread::sleep_for(std::chrono::milliseconds(20));
                            side_done = true;
                          }),
               std::runtime_error);
  EXPECT_TRUE(side_done.load());  // run_beside never leaves a part running behind it
  EXPECT_EQ(beside_threads().running, before.running);
}

TEST(RunBeside, SidesExceptionReachesTheCaller) {
  for (int n : {0, 2}) {  // on a thread of its own, and on the caller
    Limit limit(n);
    const BesideThreads before = beside_threads();
    bool main_ran = false;
    try {
      run_beside([&] { main_ran = true; }, [] { throw std::invalid_argument("side"); });
      ADD_FAILURE() << "no exception, limit " << n;
    } catch (const std::invalid_argument& e) {
      EXPECT_STREQ(e.what(), "side");
    }
    EXPECT_TRUE(main_ran) << n;
    EXPECT_EQ(beside_threads().running, before.running) << n;
  }
}

// The split nested dissection's second half on the caller gives the same order as on a
// thread of its own.
TEST(RunBeside, SplitOrderWithoutABesideThreadIsTheSame) {
  procedural::CapsuleCase cc = procedural::capsule_case(25000);
  const auto pm = PreparedMesh::create(std::move(cc.mesh));
  ASSERT_GE(static_cast<std::size_t>(pm->n()), kSplitOrderFrom);
  std::vector<int> two, one;
  {
    Limit limit(2);
    const auto started = beside_threads().started;
    two = nested_dissection(pm->L());
    EXPECT_EQ(beside_threads().started, started + 1);
  }
  {
    Limit limit(0);
    const auto refused = beside_threads().refused;
    one = nested_dissection(pm->L());
    EXPECT_EQ(beside_threads().refused, refused + 1);
  }
  EXPECT_EQ(one, two);
}

}  // namespace
}  // namespace hdeform

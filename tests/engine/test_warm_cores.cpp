// The spinners that keep the cores awake through a drag (warm_cores.h): they spin only
// between extend() and its deadline, never when off, and stop at once when destroyed.
#include "engine/runtime/warm_cores.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

namespace hdeform {
namespace {

using namespace std::chrono_literals;

// Polls `pred` for up to 10 s (a loaded CI machine may be slow to run a nice-19 thread).
template <class Pred>
bool eventually(Pred pred) {
  const auto end = std::chrono::steady_clock::now() + 10s;
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(1ms);
  }
  return pred();
}

TEST(WarmCores, SpinFromExtendUntilTheWindowPasses) {
  WarmCores warm(2, 100ms);
  std::this_thread::sleep_for(20ms);
  EXPECT_EQ(warm.spinning(), 0) << "spinning before any extend()";
  const auto t0 = std::chrono::steady_clock::now();
  warm.extend();
  EXPECT_TRUE(eventually([&] { return warm.spinning() == 2; }));
  EXPECT_TRUE(eventually([&] { return warm.spinning() == 0; }));
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 100ms) << "stopped before the window";
}

TEST(WarmCores, ExtendAgainKeepsThemSpinning) {
  WarmCores warm(1, 1s);  // far longer than a move's gap, even on a loaded machine
  warm.extend();
  ASSERT_TRUE(eventually([&] { return warm.spinning() == 1; }));
  // A 20 Hz drag: every 50 ms an extend() pushes the deadline.
  for (int i = 0; i < 8; ++i) {
    std::this_thread::sleep_for(50ms);
    warm.extend();
    EXPECT_EQ(warm.spinning(), 1) << "move " << i;
  }
  EXPECT_TRUE(eventually([&] { return warm.spinning() == 0; }));
  // Asleep again, a later drag wakes them.
  warm.extend();
  EXPECT_TRUE(eventually([&] { return warm.spinning() == 1; }));
}

TEST(WarmCores, OffNeverSpins) {
  WarmCores zero_window(2, 0ms);
  zero_window.extend();
  WarmCores no_threads(0, 100ms);
  no_threads.extend();
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(zero_window.spinning(), 0);
  EXPECT_EQ(no_threads.spinning(), 0);
}

TEST(WarmCores, SetWindowZeroStopsThemAtOnce) {
  WarmCores warm(2, 10s);
  warm.extend();
  ASSERT_TRUE(eventually([&] { return warm.spinning() == 2; }));
  warm.set_window(0ms);
  EXPECT_TRUE(eventually([&] { return warm.spinning() == 0; }));
  warm.extend();  // off: no effect
  std::this_thread::sleep_for(30ms);
  EXPECT_EQ(warm.spinning(), 0);
}

TEST(WarmCores, DestroyedWhileSpinningJoinsPromptly) {
  const auto t0 = std::chrono::steady_clock::now();
  {
    WarmCores warm(2, 60s);
    warm.extend();
    ASSERT_TRUE(eventually([&] { return warm.spinning() == 2; }));
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 20s);
}

TEST(WarmCores, CpuMaxQuota) {
  EXPECT_EQ(cpu_max_has_quota("max 100000\n"), false);
  EXPECT_EQ(cpu_max_has_quota("200000 100000\n"), true);
  EXPECT_EQ(cpu_max_has_quota("50000 100000"), true);
  EXPECT_EQ(cpu_max_has_quota(""), std::nullopt);
  EXPECT_EQ(cpu_max_has_quota("max"), std::nullopt);
  EXPECT_EQ(cpu_max_has_quota("max abc"), std::nullopt);
  EXPECT_EQ(cpu_max_has_quota("-5 100000"), std::nullopt);
  EXPECT_EQ(cpu_max_has_quota("12x 100000"), std::nullopt);
}

}  // namespace
}  // namespace hdeform

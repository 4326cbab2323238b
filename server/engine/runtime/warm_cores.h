// Cores kept awake through an interactive drag. Between two 20 Hz moves the machine idles
// for ≈ 40 ms; on these VMs an idle vCPU halts, and the next frame then runs 1.5–1.9× slower
// than back to back (slow wake-up, cold caches and clocks: docs/benchmarks.md "Warm cores
// through a drag"). While warm, one thread per core spins at nice 19 in 0.1 ms slices: it
// runs when the core would halt, and a waking thread takes the core within a slice.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string_view>
#include <thread>
#include <vector>

namespace hdeform {

class WarmCores {
 public:
  // threads: spinners while warm (0: never spins; the process's instance() uses one per
  // core). window: how long one extend() keeps them spinning (0: never).
  WarmCores(int threads, std::chrono::milliseconds window);
  ~WarmCores();
  WarmCores(const WarmCores&) = delete;
  WarmCores& operator=(const WarmCores&) = delete;

  // The process's instance: one spinner per core (at most 8), window 250 ms, or 0 (off) when
  // the process's cgroup has a CPU quota (spinning would spend the quota real work needs).
  static WarmCores& instance();

  // Keeps the cores warm until now + window (a later deadline already set stays). Cheap:
  // a clock read and two atomics; a futex wake only when the spinners sleep.
  void extend();
  // 0 turns warming off; the spinners go back to sleep at once. Thread-safe.
  void set_window(std::chrono::milliseconds window);
  std::chrono::milliseconds window() const {
    return std::chrono::milliseconds(window_ms_.load(std::memory_order_relaxed));
  }
  // Spinners spinning now (tests, logs).
  int spinning() const { return spinning_.load(std::memory_order_relaxed); }

 private:
  void spin_loop();
  std::atomic<std::int64_t> deadline_ns_{0};  // a steady_ns() time; the spinners stop past it
  std::atomic<std::int64_t> window_ms_;
  std::atomic<unsigned> wakes_{0};  // bumped by every extend(): what a sleeping spinner waits on
  std::atomic<int> spinning_{0};
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
};

// Whether a cgroup v2 `cpu.max` text ("max 100000", "200000 100000") sets a CPU quota;
// nullopt when the text is not that file's format.
std::optional<bool> cpu_max_has_quota(std::string_view cpu_max);

}  // namespace hdeform

// Two threads for one kernel call (the supernodal solve and factorization): a two-party
// barrier and the process's one helper thread. Both wait with a short spin, then a futex
// sleep, so a preempted partner costs no CPU on these 2-core machines.
#pragma once

#include <atomic>
#include <mutex>
#include <thread>

namespace hdeform {

// Waits until `a` differs from `old`: a short spin (the other thread is usually about to
// arrive), then a futex sleep (C++20 atomic wait), so a preempted partner costs no CPU.
template <class A, class V>
void await_change(const A& a, V old) {
  for (int i = 0; i < 4000; ++i) {
    if (a.load(std::memory_order_acquire) != old) return;
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
  while (a.load(std::memory_order_acquire) == old) a.wait(old, std::memory_order_acquire);
}

// Two-party barrier (one call's two threads).
class Barrier2 {
 public:
  void arrive_and_wait() {
    const unsigned g = gen_.load(std::memory_order_acquire);
    if (count_.fetch_add(1, std::memory_order_acq_rel) == 1) {
      count_.store(0, std::memory_order_relaxed);  // before the release: no one re-arrives yet
      gen_.fetch_add(1, std::memory_order_acq_rel);
      gen_.notify_one();
      return;
    }
    await_change(gen_, g);
  }

 private:
  std::atomic<int> count_{0};
  std::atomic<unsigned> gen_{0};
};

// The process's one helper thread for two-thread kernels (the solve, the factorization),
// started on first use. A call that finds it busy (another thread's kernel) runs alone: same
// bits, and never more than two kernel threads on the machine's two cores. Not OpenMP: its barriers spin for
// milliseconds by default (measured: a 2-thread solve 20 % slower than 1 thread when the
// other core is busy) and are invisible to TSan.
class Helper {
 public:
  static Helper& instance();
  // Runs fn(ctx, 1) on the helper and fn(ctx, 0) on the caller; false (nothing run) if the
  // helper is busy.
  bool run(void (*fn)(void*, int), void* ctx) {
    std::unique_lock<std::mutex> lock(busy_, std::try_to_lock);
    if (!lock.owns_lock()) return false;
    if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
    fn_ = fn;
    ctx_ = ctx;
    const unsigned g = go_.fetch_add(1, std::memory_order_acq_rel) + 1;
    go_.notify_one();
    fn(ctx, 0);
    await_change(done_, g - 1);
    return true;
  }
  ~Helper() {
    if (!thread_.joinable()) return;
    stop_ = true;
    go_.fetch_add(1, std::memory_order_acq_rel);
    go_.notify_one();
    thread_.join();
  }

 private:
  void loop() {
    unsigned seen = 0;
    for (;;) {
      await_change(go_, seen);
      seen = go_.load(std::memory_order_acquire);
      if (stop_) return;
      fn_(ctx_, 1);
      done_.store(seen, std::memory_order_release);
      done_.notify_one();
    }
  }
  std::mutex busy_;
  std::thread thread_;
  std::atomic<unsigned> go_{0}, done_{0};
  void (*fn_)(void*, int) = nullptr;  // written before go_'s release, read after its acquire
  void* ctx_ = nullptr;
  bool stop_ = false;
};

// fn(begin, end, part) over [0, n) in two halves: part 0 = [0, mid) on the caller, part 1 =
// [mid, n) on the helper (the halves of OpenMP's schedule(static) on two threads). Where the
// helper is busy (another caller's kernel) the caller runs both, in order: same results.
// fn must not throw (part 1 runs on the helper thread).
// Why not an OpenMP loop: on these VMs waking a sleeping OpenMP thread (OMP_WAIT_POLICY=
// PASSIVE) costs ≈ 50 µs per parallel region, and a spinning one takes a core from the
// solve's helper; the helper stays awake between a frame's back-to-back calls.
template <class Fn>
void two_halves(std::ptrdiff_t n, Fn&& fn) {
  const std::ptrdiff_t mid = (n + 1) / 2;
  auto body = [&](int part) {
    if (part == 0)
      fn(std::ptrdiff_t{0}, mid, 0);
    else
      fn(mid, n, 1);
  };
  auto run = [](void* ctx, int tid) { (*static_cast<decltype(body)*>(ctx))(tid); };
  if (!Helper::instance().run(run, &body)) {
    body(0);
    body(1);
  }
}

}  // namespace hdeform

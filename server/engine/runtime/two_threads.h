// Two threads for one kernel call (the supernodal solve and factorization, a frame's loops):
// the process's one helper thread, a two-party barrier, and claimed work for a helper that
// may join late. Waits spin briefly, then sleep on a futex, so a preempted partner costs no
// CPU on these 2-core machines.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
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

// Waits until `a` holds `want` (spin, then futex sleep, as await_change).
template <class A, class V>
void await_value(const A& a, V want) {
  for (V cur; (cur = a.load(std::memory_order_acquire)) != want;) await_change(a, cur);
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

// Items 0 … count−1 of one phase of work, each run once by whichever thread claims it first:
// the caller (tid 0) takes them from the front, the helper (tid 1) from the back, so when
// both are on time each does its half, the same half in every phase (its data stays in its
// core's caches), and a late helper leaves the rest to the caller. run() returns when every
// item is done, by either thread: the barrier of a team whose second thread may come late or
// not at all (Helper::offer).
class Claims {
 public:
  explicit Claims(int count)
      : range_(std::uint64_t{static_cast<std::uint32_t>(count)} << 32), count_(count) {}
  template <class Fn>
  void run(int tid, Fn&& fn) {
    for (int i; (i = claim(tid)) >= 0;) {
      fn(i);
      if (done_.fetch_add(1, std::memory_order_acq_rel) + 1 == count_) done_.notify_all();
    }
    await_value(done_, count_);
  }

 private:
  // The range not yet claimed, [lo, hi) = (low, high) 32 bits of range_; -1 when empty.
  int claim(int tid) {
    std::uint64_t r = range_.load(std::memory_order_relaxed);
    for (;;) {
      const auto lo = static_cast<std::uint32_t>(r), hi = static_cast<std::uint32_t>(r >> 32);
      if (lo >= hi) return -1;
      const std::uint64_t next = tid == 0 ? r + 1 : r - (std::uint64_t{1} << 32);
      if (range_.compare_exchange_weak(r, next, std::memory_order_relaxed))
        return static_cast<int>(tid == 0 ? lo : hi - 1);
    }
  }
  std::atomic<std::uint64_t> range_;
  const int count_;
  std::atomic<int> done_{0};
};

// The process's one helper thread for two-thread kernels (the solve, the factorization, a
// frame's loops), started on first use. A call that finds it busy (another thread's kernel)
// runs alone: same bits, and never more than two kernel threads on the machine's two cores.
// Not OpenMP: its barriers spin for milliseconds by default (measured: a 2-thread solve 20 %
// slower than 1 thread when the other core is busy) and are invisible to TSan.
class Helper {
 public:
  static Helper& instance();
  // How long after a caller found the helper busy its placement is left to the scheduler.
  static constexpr std::int64_t kSharedForNs = 1'000'000'000;
  // A team of two: fn(ctx, 1) on the helper and fn(ctx, 0) on the caller, both always run
  // (fn may use a Barrier2). false (nothing run) if the helper is busy.
  bool run(void (*fn)(void*, int), void* ctx) {
    const Taken taken(*this);
    if (!taken) return contended(), false;
    const unsigned g = start(fn, ctx);
    fn(ctx, 0);
    await_value(done_, g);
    return true;
  }
  // Runs fn(ctx, 0) on the caller and offers fn(ctx, 1) to the helper, which runs it only if
  // it wakes before the caller's part returns; so part 0 must finish the work alone if need
  // be (Claims). Why: on these VMs a sleeping or preempted helper takes up to milliseconds
  // to run, and a barrier would hold the caller for it. A busy helper: fn(ctx, 0) alone.
  // fn must not throw.
  void offer(void (*fn)(void*, int), void* ctx) {
    const Taken taken(*this);
    if (!taken) return contended(), fn(ctx, 0);
    const unsigned g = start(fn, ctx);
    fn(ctx, 0);
    std::uint64_t open = 2 * std::uint64_t{g};
    if (!ticket_.compare_exchange_strong(open, 0, std::memory_order_acq_rel))
      await_value(done_, g);  // the helper joined: it may still be finishing its part
  }
  // Stops and joins the thread. The process's instance() is never destroyed (threads of the
  // service may still run kernels while static objects are torn down at exit).
  ~Helper() {
    if (!thread_.joinable()) return;
    stop_.store(true, std::memory_order_relaxed);  // published by go_'s release
    go_.fetch_add(1, std::memory_order_acq_rel);
    go_.notify_one();
    thread_.join();
  }

 private:
  // The helper for one call, or nothing if another call has it. A flag, not a mutex: a call
  // on the thread that already holds the helper (a kernel inside a two-thread part, as
  // tests/engine/helper_busy.h does) must just find it busy; try_lock on an owned mutex is
  // undefined.
  class Taken {
   public:
    explicit Taken(Helper& h)
        : h_(h.busy_.exchange(true, std::memory_order_acquire) ? nullptr : &h) {}
    ~Taken() {
      if (h_) h_->busy_.store(false, std::memory_order_release);
    }
    explicit operator bool() const { return h_ != nullptr; }
    Taken(const Taken&) = delete;
    Taken& operator=(const Taken&) = delete;

   private:
    Helper* h_;
  };
  // Publishes job g = go_ + 1 with its ticket open (2g); the helper joins by turning it to
  // 2g + 1, offer() closes it with 0. Callers hold busy_.
  unsigned start(void (*fn)(void*, int), void* ctx) {
    if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
    keep_off_caller_cpu();
    fn_ = fn;
    ctx_ = ctx;
    const unsigned g = go_.load(std::memory_order_relaxed) + 1;
    ticket_.store(2 * std::uint64_t{g}, std::memory_order_release);
    go_.store(g, std::memory_order_release);
    go_.notify_one();
    return g;
  }
  void loop() {
    unsigned seen = 0;
    for (;;) {
      await_change(go_, seen);
      seen = go_.load(std::memory_order_acquire);
      if (stop_.load(std::memory_order_relaxed)) return;
      std::uint64_t open = 2 * std::uint64_t{seen};
      if (!ticket_.compare_exchange_strong(open, open + 1, std::memory_order_acq_rel))
        continue;  // closed: the caller did the work alone
      fn_(ctx_, 1);  // fn_ and ctx_ are read only after joining: the caller waits for done_
      done_.store(seen, std::memory_order_release);
      done_.notify_one();
    }
  }
  // Before each wake, when no other caller wanted the helper for kSharedForNs: the helper's
  // CPUs become the process's minus the caller's. Why: while warm cores spin no CPU is idle,
  // so the scheduler wakes the helper on its last CPU, and when that was the caller's (the
  // service's frames alternate between worker threads on both CPUs) the frame's two halves
  // shared one CPU: 1.7-1.9× the frame. With other callers (sessions under load), the mask
  // would only move the helper onto a CPU that another frame is using, which measured worse
  // (docs/benchmarks.md "The helper on the caller's CPU"); the scheduler places it then.
  // A syscall only when the caller's CPU or the mode changes.
  void keep_off_caller_cpu();
  void contended();  // a caller found the helper busy: the machine is shared
  std::atomic<std::int64_t> contended_ns_{0};  // steady clock; written only by contended()
  // The CPU the helper's mask leaves out (the last caller's), kAnyCpu or kUnset; under busy_.
  static constexpr int kAnyCpu = -1, kUnset = -2;
  int off_cpu_ = kUnset;
  std::atomic<bool> busy_{false};
  std::thread thread_;
  std::atomic<unsigned> go_{0}, done_{0};
  std::atomic<std::uint64_t> ticket_{0};
  void (*fn_)(void*, int) = nullptr;  // written before the ticket's release
  void* ctx_ = nullptr;
  // Atomic: the helper reads it after every wake-up, also one that races with ~Helper's write.
  std::atomic<bool> stop_{false};
};

// The number of chunks for_chunks splits a loop into: enough that a helper that joins late
// (or not at all) leaves the caller little idle, few enough that claiming costs nothing.
inline constexpr int kChunks = 8;

// fn(begin, end, chunk) over [0, n) in kChunks contiguous chunks, chunk c = [c·n/kChunks,
// (c+1)·n/kChunks), each run once by the caller or the helper, whichever claims it first
// (Helper::offer). Per-chunk results (a reduction: one slot per chunk, combined in chunk
// order) are the same bits whoever ran which chunk, or one thread all of them.
// fn must not throw (the helper runs chunks).
// Why not an OpenMP loop: on these VMs waking a sleeping OpenMP thread (OMP_WAIT_POLICY=
// PASSIVE) costs ≈ 50 µs per parallel region, and a spinning one takes a core from the
// solve's helper; the helper stays awake between a frame's back-to-back calls.
template <class Fn>
void for_chunks(std::ptrdiff_t n, Fn&& fn) {
  Claims chunks(kChunks);
  auto body = [&](int tid) {
    chunks.run(tid, [&](int c) { fn(c * n / kChunks, (c + 1) * n / kChunks, c); });
  };
  auto run = [](void* ctx, int tid) { (*static_cast<decltype(body)*>(ctx))(tid); };
  Helper::instance().offer(run, &body);
}

}  // namespace hdeform

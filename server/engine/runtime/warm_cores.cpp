#include "engine/runtime/warm_cores.h"
#include "engine/runtime/elapsed_ms.h"

#include <charconv>
#include <fstream>
#include <iterator>
#include <string>

#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace hdeform {

namespace {

std::string read_file(const char* path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// cgroup v2's cpu.max, else v1's cpu.cfs_quota_us (−1: none), as seen from inside the
// process's cgroup namespace (a container's own files).
bool process_has_cpu_quota() {
  if (auto v2 = cpu_max_has_quota(read_file("/sys/fs/cgroup/cpu.max"))) return *v2;
  const std::string v1 = read_file("/sys/fs/cgroup/cpu/cpu.cfs_quota_us");
  long quota = -1;
  std::from_chars(v1.data(), v1.data() + v1.size(), quota);
  return quota > 0;
}

}  // namespace

std::optional<bool> cpu_max_has_quota(std::string_view text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.remove_suffix(1);
  const auto space = text.find(' ');
  if (space == std::string_view::npos) return std::nullopt;
  const std::string_view quota = text.substr(0, space), period = text.substr(space + 1);
  long p = 0;
  auto [end, ec] = std::from_chars(period.data(), period.data() + period.size(), p);
  if (ec != std::errc() || end != period.data() + period.size() || p <= 0) return std::nullopt;
  if (quota == "max") return false;
  long q = 0;
  auto [qend, qec] = std::from_chars(quota.data(), quota.data() + quota.size(), q);
  if (qec != std::errc() || qend != quota.data() + quota.size() || q <= 0) return std::nullopt;
  return true;
}

WarmCores::WarmCores(int threads, std::chrono::milliseconds window)
    : window_ms_(window.count()) {
  threads_.reserve(static_cast<std::size_t>(threads > 0 ? threads : 0));
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { spin_loop(); });
}

WarmCores::~WarmCores() {
  stop_.store(true, std::memory_order_relaxed);
  wakes_.fetch_add(1, std::memory_order_release);
  wakes_.notify_all();
  for (auto& t : threads_) t.join();
}

WarmCores& WarmCores::instance() {
  // Never destroyed, as Helper::instance(): service threads may still extend() at exit.
  static WarmCores* const w = [] {
    const unsigned cores = std::thread::hardware_concurrency();
    const int threads = static_cast<int>(cores == 0 ? 1 : cores > 8 ? 8 : cores);
    return new WarmCores(threads, std::chrono::milliseconds(process_has_cpu_quota() ? 0 : 250));
  }();
  return *w;
}

void WarmCores::extend() {
  const std::int64_t window = window_ms_.load(std::memory_order_relaxed);
  if (window <= 0 || threads_.empty()) return;
  const std::int64_t deadline = steady_ns() + window * 1'000'000;
  std::int64_t old = deadline_ns_.load(std::memory_order_relaxed);
  while (old < deadline &&
         !deadline_ns_.compare_exchange_weak(old, deadline, std::memory_order_relaxed)) {
  }
  // Always bumped: a spinner that read the old deadline as passed sleeps on the count it
  // read before that, so this bump wakes it (no syscall when none sleeps).
  wakes_.fetch_add(1, std::memory_order_release);
  wakes_.notify_all();
}

void WarmCores::set_window(std::chrono::milliseconds window) {
  window_ms_.store(window.count(), std::memory_order_relaxed);
  if (window.count() <= 0) deadline_ns_.store(0, std::memory_order_relaxed);
}

namespace {

// This thread at nice 19 with a 0.1 ms time slice: a solver thread that wakes on its core
// takes the core within the slice (EEVDF lets the running task finish its slice, 0.75 ms or
// more by default; measured at 4 sessions of 100K, the short slice cut the p99 the spinners
// add), and under load it gets ≈ 1.5 % of a core. Raising nice and a custom slice (Linux
// ≥ 6.12; older kernels ignore it) need no privilege. Not SCHED_IDLE: measured, its paced
// frame stayed 1.5× the back-to-back one, nice 19's 1.1× (docs/benchmarks.md "Warm cores
// through a drag").
void lower_this_thread() {
  struct {  // the kernel's struct sched_attr (its header clashes with glibc's <sched.h>)
    std::uint32_t size, sched_policy;
    std::uint64_t sched_flags;
    std::int32_t sched_nice;
    std::uint32_t sched_priority;
    std::uint64_t sched_runtime, sched_deadline, sched_period;
  } attr{};
  attr.size = sizeof attr;
  attr.sched_policy = SCHED_OTHER;
  attr.sched_nice = 19;
  attr.sched_runtime = 100'000;  // ns: the slice
  if (syscall(SYS_sched_setattr, 0, &attr, 0) != 0)
    setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 19);
}

}  // namespace

void WarmCores::spin_loop() {
  lower_this_thread();
  unsigned seen = wakes_.load(std::memory_order_acquire);
  for (;;) {
    if (stop_.load(std::memory_order_relaxed)) return;
    if (steady_ns() >= deadline_ns_.load(std::memory_order_relaxed)) {
      wakes_.wait(seen, std::memory_order_acquire);
      seen = wakes_.load(std::memory_order_acquire);
      continue;
    }
    spinning_.fetch_add(1, std::memory_order_relaxed);
    while (!stop_.load(std::memory_order_relaxed) &&
           steady_ns() < deadline_ns_.load(std::memory_order_relaxed)) {
      for (int i = 0; i < 64; ++i) {
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#endif
      }
    }
    spinning_.fetch_sub(1, std::memory_order_relaxed);
  }
}

}  // namespace hdeform

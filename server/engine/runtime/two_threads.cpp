#include "engine/runtime/two_threads.h"
#include "engine/runtime/elapsed_ms.h"

#include <pthread.h>
#include <sched.h>
#include <unistd.h>

namespace hdeform {

Helper& Helper::instance() {
  // Never destroyed: at exit, threads that outlive static destruction (gRPC's, the worker
  // pool's in a process that calls exit()) may still run a kernel. The thread sleeps in
  // await_change and ends with the process.
  static Helper* const h = new Helper;
  return *h;
}

namespace {

// The CPUs the process may run on, as its main thread has them at the first call (a caller
// pinned by its creator, as tests do, must not narrow the helper's choice).
const cpu_set_t& process_cpus() {
  static const cpu_set_t cpus = [] {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(getpid(), sizeof set, &set) != 0) CPU_ZERO(&set);
    return set;
  }();
  return cpus;
}

}  // namespace

void Helper::contended() { contended_ns_.store(steady_ns(), std::memory_order_relaxed); }

void Helper::keep_off_caller_cpu() {
  const std::int64_t last = contended_ns_.load(std::memory_order_relaxed);
  int off = kAnyCpu;
  if (last == 0 || steady_ns() - last >= kSharedForNs) off = sched_getcpu();
  if (off < 0 || off >= CPU_SETSIZE) off = kAnyCpu;
  if (off == off_cpu_) return;
  cpu_set_t set = process_cpus();
  if (off != kAnyCpu) CPU_CLR(off, &set);
  if (CPU_COUNT(&set) == 0) return;  // one CPU, or the process's CPUs unknown: nowhere to go
  // A failure (a sandbox that forbids it) leaves the placement to the scheduler, as before.
  pthread_setaffinity_np(thread_.native_handle(), sizeof set, &set);
  off_cpu_ = off;
}

}  // namespace hdeform

#include "engine/runtime/run_beside.h"

#include <algorithm>
#include <mutex>
#include <thread>

namespace hdeform {

namespace {
// One mutex for four numbers: a take is once per call that starts a thread (a METIS half,
// a block build: milliseconds to seconds of work), never on a frame's path.
std::mutex budget_mutex;
BesideThreads budget{.limit = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))};
}  // namespace

void set_beside_thread_limit(int limit) {
  std::lock_guard lock(budget_mutex);
  budget.limit = std::max(0, limit);
}

BesideThreads beside_threads() {
  std::lock_guard lock(budget_mutex);
  return budget;
}

namespace detail {

bool take_beside_thread() {
  std::lock_guard lock(budget_mutex);
  if (budget.running >= budget.limit) {
    ++budget.refused;
    return false;
  }
  ++budget.running;
  ++budget.started;
  return true;
}

void return_beside_thread(bool made) {
  std::lock_guard lock(budget_mutex);
  --budget.running;
  if (!made) {
    --budget.started;
    ++budget.refused;
  }
}

}  // namespace detail

}  // namespace hdeform

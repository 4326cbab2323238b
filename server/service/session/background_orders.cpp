#include "service/session/background_orders.h"

#include "engine/deform/factor_budget.h"
#include "engine/runtime/elapsed_ms.h"
#include "engine/solve/vertex_ordering.h"

#include <spdlog/spdlog.h>

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <exception>
#include <system_error>
#include <utility>

namespace hdeform::service {

namespace {

// What the order's working memory is charged as while it runs.
struct Working : FactorBudget::Item {};

// SCHED_IDLE: the thread runs only on a core no other thread of the machine wants, so an
// order never slows a drag frame by taking its core. METIS's second thread and OpenMP's
// team inherit it (glibc's pthread_create inherits the creator's policy by default).
// True: SCHED_IDLE; else nice 19 where it can be set.
bool lower_priority() {
  sched_param param{};
  if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) == 0) return true;
  if (setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 19) != 0)
    spdlog::warn("background orders: the thread's priority could not be lowered");
  return false;
}

}  // namespace

BackgroundOrders::BackgroundOrders(const Options& options, std::shared_ptr<FactorBudget> budget)
    : options_(options), budget_(std::move(budget)) {}

BackgroundOrders::~BackgroundOrders() { join(); }

std::size_t BackgroundOrders::working_bytes(std::size_t vertices) {
  return vertices * kWorkingBytesPerVertex;
}

void BackgroundOrders::enqueue(const std::shared_ptr<const MeshRef>& mesh) {
  if (options_.from_vertices == 0 || !mesh || !mesh->prepared) return;
  const PreparedMesh& pm = *mesh->prepared;
  if (static_cast<std::size_t>(pm.n()) < options_.from_vertices ||
      (pm.has_order() && pm.has_wide_order()))
    return;
  std::lock_guard lock(mutex_);
  if (stopping_) return;
  for (const auto& queued : queue_)
    if (queued.lock() == mesh) return;  // a second session on the same mesh
  if (options_.max_queued == 0) {
    ++stats_.queue_full;
    return;
  }
  while (queue_.size() >= options_.max_queued) {
    queue_.pop_front();
    ++stats_.queue_full;
  }
  queue_.push_back(mesh);
  if (!thread_.joinable()) {
    try {
      thread_ = std::thread([this] { run(); });
    } catch (const std::system_error& e) {  // the session is made: this must not fail it
      spdlog::warn("background orders: no thread ({}); the first calls compute them", e.what());
      queue_.clear();
      return;
    }
  }
  cv_.notify_one();
}

void BackgroundOrders::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    queue_.clear();
  }
  cv_.notify_all();
}

void BackgroundOrders::join() {
  stop();  // after it no enqueue starts the thread: thread_ is read without the lock
  if (!thread_.joinable()) return;
  if (stats().busy) spdlog::info("background orders: waiting for the order in progress to end");
  thread_.join();
}

bool BackgroundOrders::stopping() const {
  std::lock_guard lock(mutex_);
  return stopping_;
}

BackgroundOrders::Stats BackgroundOrders::stats() const {
  std::lock_guard lock(mutex_);
  Stats s = stats_;
  s.queued = queue_.size();
  return s;
}

void BackgroundOrders::run() {
  const bool idle = options_.lowest_priority && lower_priority();
  std::unique_lock lock(mutex_);
  stats_.idle_priority = idle;
  for (;;) {
    cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
    if (stopping_) return;
    std::shared_ptr<const MeshRef> mesh = queue_.front().lock();
    queue_.pop_front();
    if (!mesh) {
      ++stats_.closed;
      continue;
    }
    stats_.busy = true;
    lock.unlock();
    order(*mesh);
    mesh.reset();  // possibly the last reference: a large mesh is freed outside the lock
    lock.lock();
    stats_.busy = false;
  }
}

// Runs without the lock; counts under it. The β = 0 order first: a session's first
// SetConstraints needs it, its first β > 0 the other.
void BackgroundOrders::order(const MeshRef& mesh) {
  const PreparedMesh& pm = *mesh.prepared;
  auto count = [&](std::uint64_t Stats::*field) {
    std::lock_guard lock(mutex_);
    ++(stats_.*field);
  };
  if (pm.has_order() && pm.has_wide_order()) return count(&Stats::superseded);
  const auto working = std::make_shared<const Working>();
  if (budget_ && !budget_->charge_if_room(working, working_bytes(pm.n()))) {
    spdlog::debug("mesh {}: no room in the budget for its background orders", mesh.hash);
    return count(&Stats::no_room);
  }
  for (const bool wide : {false, true}) {
    if (stopping()) return;  // a stop waits for the order in progress, no other
    if (wide ? pm.has_wide_order() : pm.has_order()) {
      count(&Stats::superseded);
      continue;
    }
    try {
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<int> order = wide ? nested_dissection(pm.L(), pm.Reg()) : nested_dissection(pm.L());
      if (!pm.adopt_order(std::move(order), wide)) {
        count(&Stats::superseded);
        continue;
      }
      spdlog::info("mesh {} ({} vertices): its β {} order computed in the background in {:.0f} ms",
                   mesh.hash, pm.n(), wide ? "> 0" : "= 0",
                   elapsed_ms(t0));
      count(&Stats::computed);
    } catch (const std::exception& e) {
      spdlog::warn("mesh {}: its background β {} order failed ({}); the first use computes it",
                   mesh.hash, wide ? "> 0" : "= 0", e.what());
      count(&Stats::failed);
    }
  }
}

}  // namespace hdeform::service

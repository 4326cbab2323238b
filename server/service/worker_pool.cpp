#include "worker_pool.h"

#include <spdlog/spdlog.h>

#include <exception>

namespace hdeform::service {

namespace {
void run_guarded(const WorkerPool::Task& task) {
  try {
    task();
  } catch (const std::exception& e) {
    spdlog::error("worker task failed: {}", e.what());
  } catch (...) {
    spdlog::error("worker task failed with an unknown exception");
  }
}
}  // namespace

WorkerPool::WorkerPool(int threads) {
  if (threads < 1) threads = 1;
  threads_.reserve(threads);
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { run(); });
}

WorkerPool::~WorkerPool() { stop(); }

void WorkerPool::submit(Task task) {
  {
    // Work submitted during shutdown still runs (reactors wait for their completions):
    // either a worker picks it up or stop() runs it after the join.
    std::lock_guard lock(mutex_);
    tasks_.push_back(std::move(task));
  }
  cv_.notify_one();
}

void WorkerPool::stop() {
  {
    std::lock_guard lock(mutex_);
    if (stopping_ && threads_.empty()) return;
    stopping_ = true;
  }
  cv_.notify_all();
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  threads_.clear();
  // Anything submitted after the threads left runs here.
  for (;;) {
    std::deque<Task> rest;
    {
      std::lock_guard lock(mutex_);
      rest.swap(tasks_);
    }
    if (rest.empty()) break;
    for (auto& task : rest) run_guarded(task);
  }
}

std::size_t WorkerPool::queued() const {
  std::lock_guard lock(mutex_);
  return tasks_.size();
}

void WorkerPool::run() {
  for (;;) {
    Task task;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
      if (tasks_.empty()) return;  // stopping and drained
      task = std::move(tasks_.front());
      tasks_.pop_front();
    }
    run_guarded(task);
  }
}

void Strand::post(WorkerPool::Task task) {
  bool start = false;
  {
    std::lock_guard lock(mutex_);
    tasks_.push_back(std::move(task));
    if (!running_) running_ = start = true;
  }
  if (start) pool_.submit([self = shared_from_this()] { self->drain(); });
}

void Strand::drain() {
  // Runs one task per pool slot so a busy session cannot starve the others.
  WorkerPool::Task task;
  {
    std::lock_guard lock(mutex_);
    task = std::move(tasks_.front());
    tasks_.pop_front();
  }
  run_guarded(task);
  bool more = false;
  {
    std::lock_guard lock(mutex_);
    if (tasks_.empty())
      running_ = false;
    else
      more = true;
  }
  if (more) pool_.submit([self = shared_from_this()] { self->drain(); });
}

}  // namespace hdeform::service

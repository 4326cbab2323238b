#include "worker_pool.h"

#include <spdlog/spdlog.h>

#include <dlfcn.h>
#include <omp.h>

#include <algorithm>
#include <exception>
#include <mutex>

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

// The engine's OpenMP loops run inside each worker: together they get the machine's cores,
// not cores × workers (oversubscribed threads only fight each other). OpenBLAS (CHOLMOD's
// BLAS) gets one thread: its pthread pool spins beside OpenMP's and costs more than it
// gives on the small supernodes of these systems (issue 10's profile).
static int limit_library_threads(int workers) {
  static std::once_flag once;
  std::call_once(once, [] {
    using SetThreads = void (*)(int);
    if (auto f = reinterpret_cast<SetThreads>(::dlsym(RTLD_DEFAULT, "openblas_set_num_threads")))
      f(1);
  });
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return std::max(1, cores / std::max(1, workers));
}

WorkerPool::WorkerPool(int threads) {
  if (threads < 1) threads = 1;
  const int omp_threads = limit_library_threads(threads);
  threads_.reserve(threads);
  for (int i = 0; i < threads; ++i)
    threads_.emplace_back([this, omp_threads] {
      omp_set_num_threads(omp_threads);  // per thread: OpenMP's nthreads-var is per task
      run();
    });
}

WorkerPool::~WorkerPool() { stop(); }

void WorkerPool::publish() { std::lock_guard lock(mutex_); }

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

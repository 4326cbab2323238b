#include "service/infra/worker_pool.h"

#include <spdlog/spdlog.h>

#include <strings.h>
#include <omp.h>

#include <algorithm>
#include <cstdlib>
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

// A frame runs on its worker and the engine's one helper thread (two_threads.h), with no
// OpenMP region; what still uses OpenMP (the operators' assembly at an open, the frame
// encodings) runs inside the workers. When OpenMP waits passively (the server sets that up:
// process_environment.h), every worker's team gets all the cores and idle teams sleep;
// with spinning waits, oversubscribed teams only fight each other, so the workers split the
// cores. (OpenBLAS gets one thread from the factorization itself: one_blas_thread.h.)
static bool openmp_waits_passively() {
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  return policy != nullptr && ::strcasecmp(policy, "passive") == 0;
}

static int openmp_threads_per_worker(int workers) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int plan = openmp_waits_passively() ? cores : std::max(1, cores / std::max(1, workers));
  return std::min(plan, omp_get_max_threads());  // never above a user's OMP_NUM_THREADS
}

WorkerPool::WorkerPool(int threads) {
  if (threads < 1) threads = 1;
  const int omp_threads = openmp_threads_per_worker(threads);
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

namespace {
thread_local bool t_on_worker = false;
}  // namespace

bool WorkerPool::on_worker() { return t_on_worker; }

void WorkerPool::run() {
  t_on_worker = true;
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

std::size_t Strand::queued() const {
  std::lock_guard lock(mutex_);
  return tasks_.size();
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

// A small fixed-size thread pool for the expensive work (parsing, preparing, factorizing,
// solving) so gRPC reactions never block, plus a Strand that runs one session's tasks
// in submission order, one at a time, on that pool.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace hdeform::service {

class WorkerPool {
 public:
  using Task = std::function<void()>;

  explicit WorkerPool(int threads);
  ~WorkerPool();  // runs the queued tasks, then joins
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  // Queues a task. Exceptions escaping a task are logged and swallowed.
  void submit(Task task);
  // Everything the caller wrote before this call is visible to every task that starts
  // after it: a release on the queue's mutex, which a worker takes before each task. The
  // owner calls it once it is fully built, so no worker can see a member before its
  // initialization even when the task came in through a library TSan cannot see into.
  void publish();
  // Stops accepting work, drains the queue and joins the threads.
  void stop();
  int size() const { return static_cast<int>(threads_.size()); }
  // True on a thread of any WorkerPool: where blocking work (a session's restore) may run.
  static bool on_worker();
  std::size_t queued() const;

 private:
  void run();

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Task> tasks_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

// Serial executor on top of a WorkerPool: tasks posted to one strand never overlap and run
// in the order they were posted; different strands run in parallel.
class Strand : public std::enable_shared_from_this<Strand> {
 public:
  explicit Strand(WorkerPool& pool) : pool_(pool) {}
  void post(WorkerPool::Task task);
  std::size_t queued() const;  // posted, not started

 private:
  void drain();

  WorkerPool& pool_;
  mutable std::mutex mutex_;
  std::deque<WorkerPool::Task> tasks_;
  bool running_ = false;
};

}  // namespace hdeform::service

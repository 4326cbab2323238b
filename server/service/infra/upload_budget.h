// Bounds on uploads in flight (CreateSession streams, ImportSession's mesh bytes — every
// request that carries a mesh): the bytes all unfinished uploads
// hold together, and how long one may go without sending. A watchdog thread cancels
// stalled uploads, so a client that opens an upload and goes quiet holds nothing for long.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace hdeform::service {

class UploadBudget {
 public:
  // One upload's account. The reactor calls touch() on each message and detach() in OnDone
  // (after which the watchdog never touches its context again).
  class Ticket {
   public:
    void touch();
    // Reserve `bytes` more for this upload; false when the server-wide budget is spent.
    bool charge(std::size_t bytes);
    bool stalled() const { return stalled_.load(); }
    // The client finished sending: from now on the server is working (parsing, preparing),
    // which is not a stall, so the watchdog leaves this upload alone.
    void received_all() { received_all_ = true; }
    void detach();  // releases the bytes; the context is not used afterwards
    ~Ticket();

   private:
    friend class UploadBudget;
    Ticket(UploadBudget& budget, grpc::CallbackServerContext* ctx);
    UploadBudget& budget_;
    std::mutex mutex_;  // guards ctx_
    grpc::CallbackServerContext* ctx_;
    std::atomic<std::int64_t> last_ns_;
    std::size_t charged_ = 0;
    std::atomic<bool> stalled_{false};
    std::atomic<bool> received_all_{false};
  };

  UploadBudget(std::size_t max_bytes, std::chrono::milliseconds stall_timeout);
  ~UploadBudget();  // stops the watchdog
  std::shared_ptr<Ticket> open(grpc::CallbackServerContext* ctx);
  std::size_t bytes_in_flight() const { return bytes_.load(); }
  std::size_t max_bytes() const { return max_bytes_; }
  // RESOURCE_EXHAUSTED naming --max-upload-inflight-mb: what a charge() refused answers.
  grpc::Status exhausted() const;
  std::chrono::milliseconds stall_timeout() const { return stall_timeout_; }

 private:
  void watch();

  const std::size_t max_bytes_;
  const std::chrono::milliseconds stall_timeout_;
  std::atomic<std::size_t> bytes_{0};
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::vector<std::weak_ptr<Ticket>> tickets_;
  std::thread watchdog_;
};

}  // namespace hdeform::service

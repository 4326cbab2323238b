// The door's gRPC calls whose OnDone has not run. stop() cancels every one and waits for the
// registry to empty before the channel (and then the server) goes: gRPC 1.51's in-process
// transport can take a stream off its list while the server still has a write pending, and
// then Server::Shutdown's own cancel-all never reaches it and waits forever. A client-side
// TryCancel reaches the stream through the call itself.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <memory>
#include <mutex>
#include <unordered_map>

namespace hdeform::gateway {

class GrpcCall;

class LiveCalls {
 public:
  // A call about to start; once close_and_cancel() has run it is cancelled at once (a
  // TryCancel before StartCall cancels the call as it starts).
  void add(const std::shared_ptr<GrpcCall>& call);
  // From OnDone: the call is no longer cancelled by stop().
  void remove(const GrpcCall* call);
  // Cancels every call, now and any added later. TryCancel runs outside the lock: gRPC may
  // run a call's OnDone inline, and OnDone calls remove().
  void close_and_cancel();
  // True once every call has ended; false if `limit` passed first.
  bool wait_empty(std::chrono::milliseconds limit);
  std::size_t size();

 private:
  std::mutex mu_;
  std::condition_variable emptied_;
  std::unordered_map<const GrpcCall*, std::weak_ptr<GrpcCall>> calls_;
  bool closed_ = false;
};

}  // namespace hdeform::gateway

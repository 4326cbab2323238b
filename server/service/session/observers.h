// Who watches a session and which streams it must end: the WatchSession sinks events are
// broadcast to, the Deform streams a token rotation or deletion revokes, and the counts the
// limits and the idle sweeper read. Its own lock, taken after Session's (never the other way)
// and never held while calling out: a slow sink never stalls a solve or a describe().
#pragma once

#include "hdeform/v1/deform.pb.h"
#include "service/access/access.h"

#include <grpcpp/support/status.h>

#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

// An open stream as its session sees it, with the tokens it was authorized with: it ends
// (revoke) as soon as they stop granting what it needs — RotateTokens, or the session's
// deletion for a Deform stream. Empty token_hashes: the operator's token (never revoked).
class AuthorizedStream {
 public:
  virtual ~AuthorizedStream() = default;
  virtual void revoke(const grpc::Status& why) = 0;  // never blocks
  std::vector<TokenHash> token_hashes;
  Access needed = Access::kView;
};

// A WatchSession stream as the session sees it. push() never blocks.
class EventSink : public AuthorizedStream {
 public:
  virtual void push(std::shared_ptr<const pb::SessionEvent> event) = 0;
  virtual void close() = 0;  // the session is gone (after a `deleted` event)
};

class Observers {
 public:
  // False, and nothing added, once close() took the streams.
  bool add_watcher(std::shared_ptr<EventSink> sink);
  bool remove_watcher(const EventSink* sink);  // whether it was there
  // A Deform stream, held weakly (it unregisters by going away).
  void add_stream(std::weak_ptr<AuthorizedStream> stream);
  int watchers() const;
  // To every watcher but `except`; the pushes run outside the lock.
  void broadcast(const std::shared_ptr<const pb::SessionEvent>& event,
                 const EventSink* except = nullptr) const;

  struct Open {
    std::vector<std::shared_ptr<EventSink>> watchers;
    std::vector<std::shared_ptr<AuthorizedStream>> deform;
  };
  // Takes out every stream (watchers and Deform) `lost` is true of; the caller revokes them.
  std::vector<std::shared_ptr<AuthorizedStream>> take_if(
      const std::function<bool(const AuthorizedStream&)>& lost);
  // Takes out every stream and refuses new watchers from now on (the session is gone).
  Open close();
  // Ends every open stream with `why`; the session stays usable (the server is stopping).
  void end_all(const grpc::Status& why);

  // MESHOPT_DELTA watchers (each encodes every frame for itself): false, and nothing taken,
  // when `limit` are already watching so.
  bool acquire_delta_watcher(std::size_t limit);
  void release_delta_watcher() { delta_watchers_.fetch_sub(1); }
  int delta_watchers() const { return delta_watchers_.load(); }
  // Open Deform streams (they keep a session from idling out).
  void stream_opened() { ++streams_; }
  void stream_closed() { --streams_; }
  bool busy() const { return streams_.load() > 0 || watchers() > 0; }

 private:
  mutable std::mutex mutex_;
  bool closed_ = false;
  std::vector<std::shared_ptr<EventSink>> watchers_;
  std::vector<std::weak_ptr<AuthorizedStream>> deform_;
  std::atomic<int> streams_{0};
  std::atomic<int> delta_watchers_{0};
};

}  // namespace hdeform::service

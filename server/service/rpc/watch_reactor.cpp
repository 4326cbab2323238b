#include "service/rpc/reactors.h"

#include "service/rpc/deform_service.h"
#include "service/frames/frame_delta.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <deque>
#include <mutex>

namespace hdeform::service {

namespace {

// WatchSession: the session's state and frames. A slow reader never has more than one
// frame (the newest) and one state (the newest) waiting.
class WatchReactor final : public grpc::ServerWriteReactor<v1::SessionEvent> {
  static constexpr long kMaxPendingSteps = 32;

 public:
  // `client_id`: the watcher joined the session's presence under it (empty: anonymous).
  // `authorize` fills the sink's tokens (DeformService::bind_stream) before it is added.
  WatchReactor(std::shared_ptr<Session> session, const v1::FrameFormat& format,
               std::string client_id, Roster::Claim claim, WorkerPool& pool,
               const std::function<void(AuthorizedStream&)>& authorize)
      : session_(std::move(session)),
        format_(format),
        client_id_(std::move(client_id)),
        claim_(claim),
        pool_(pool) {
    sink_ = std::make_shared<Sink>(this);
    authorize(*sink_);
    session_->add_watcher(sink_);
  }

  // The session not resident: `start` finds (restores) it and admits the watcher on the pool,
  // then the stream starts as above; a failure ends it with start's status.
  WatchReactor(WatchStarter start, const v1::FrameFormat& format, WorkerPool& pool,
               std::function<void(AuthorizedStream&)> authorize)
      : format_(format), pool_(pool) {
    starting_ = true;  // the pool task owns this until it is done
    pool_.submit([this, start = std::move(start), authorize = std::move(authorize)] {
      WatchStart w;
      const grpc::Status status = guarded([&] { w = start(); }, "WatchSession");
      if (status.ok()) {
        session_ = std::move(w.session);
        client_id_ = std::move(w.client_id);
        claim_ = w.claim;
        sink_ = std::make_shared<Sink>(this);
        authorize(*sink_);
        session_->add_watcher(sink_);  // without mutex_: it may push the join state
      }
      std::unique_lock lock(mutex_);
      starting_ = false;
      if (done_) {  // the client left meanwhile: undo what OnDone could not
        lock.unlock();
        if (session_) detach();
        delete this;
        return;
      }
      if (!status.ok()) finish_locked(status);
    });
  }

  void OnWriteDone(bool ok) override {
    std::lock_guard lock(mutex_);
    writing_ = false;
    current_.reset();
    if (!ok) {
      finish_locked({grpc::StatusCode::CANCELLED, "watcher went away"});
      return;
    }
    next_locked();
  }

  void OnCancel() override {
    std::lock_guard lock(mutex_);
    finish_locked({grpc::StatusCode::CANCELLED, "watch cancelled"});
  }

  void OnDone() override {
    {
      std::lock_guard lock(mutex_);
      if (starting_) {  // the start task detaches and deletes this when it ends
        done_ = true;
        return;
      }
    }
    if (session_) detach();
    {
      std::lock_guard lock(mutex_);
      done_ = true;
      if (encoding_) return;  // the encode in progress deletes this when it ends
    }
    delete this;
  }

 private:
  // Off the session: no more events, presence left (its grabs end with it), its delta slot.
  void detach() {
    {
      std::lock_guard lock(sink_->mutex);
      sink_->reactor = nullptr;
    }
    session_->remove_watcher(sink_.get());
    if (!client_id_.empty()) session_->leave(client_id_, claim_);
    if (format_.encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA)
      session_->observers().release_delta_watcher();
  }

  struct Sink final : EventSink {
    explicit Sink(WatchReactor* r) : reactor(r) {}
    void push(std::shared_ptr<const v1::SessionEvent> event) override {
      std::lock_guard lock(mutex);
      if (reactor) reactor->enqueue(std::move(event));
    }
    void close() override {
      std::lock_guard lock(mutex);
      if (reactor) reactor->end();
    }
    void revoke(const grpc::Status& why) override {
      std::lock_guard lock(mutex);
      if (reactor) reactor->revoked(why);
    }
    std::mutex mutex;
    WatchReactor* reactor;
  };

  void revoked(const grpc::Status& why) {
    std::lock_guard lock(mutex_);
    finish_locked(why);  // what waits is dropped: the client may no longer see it
  }

  void enqueue(std::shared_ptr<const v1::SessionEvent> event) {
    std::lock_guard lock(mutex_);
    if (finished_ || closing_) return;
    // Latest wins: a newer frame replaces a waiting frame, a newer state a waiting state, a
    // newer presence a waiting presence, a newer timeline a waiting timeline.
    const auto kind = event->event_case();
    if (kind == v1::SessionEvent::kFrame || kind == v1::SessionEvent::kState ||
        kind == v1::SessionEvent::kPresence || kind == v1::SessionEvent::kTimeline) {
      for (auto it = pending_.begin(); it != pending_.end(); ++it)
        if ((*it)->event_case() == kind) {
          pending_.erase(it);
          ++skipped_;
          break;
        }
    }
    // History steps all count, but a stalled watcher keeps only the newest few (ListHistory
    // has them all): its memory stays bounded.
    if (kind == v1::SessionEvent::kStep &&
        std::count_if(pending_.begin(), pending_.end(), [](const auto& e) {
          return e->event_case() == v1::SessionEvent::kStep;
        }) >= kMaxPendingSteps) {
      for (auto it = pending_.begin(); it != pending_.end(); ++it)
        if ((*it)->event_case() == v1::SessionEvent::kStep) {
          pending_.erase(it);
          ++skipped_;
          break;
        }
    }
    pending_.push_back(std::move(event));
    if (!writing_) next_locked();
  }

  void end() {
    std::lock_guard lock(mutex_);
    closing_ = true;
    if (!writing_) next_locked();
  }

  void next_locked() {
    if (finished_) return;
    if (pending_.empty()) {
      if (closing_) finish_locked(grpc::Status::OK);
      return;
    }
    auto event = std::move(pending_.front());
    pending_.pop_front();
    writing_ = true;
    if (!event->has_frame() || encoding_for(event->frame(), format_) == v1::FRAME_ENCODING_FLOAT32) {
      if (event->has_frame()) delta_.reset();  // the client's state is no longer ours
      start_write_locked(std::move(event));
      return;
    }
    // Encoded here, not at broadcast: only frames that are written cost an encoding, and
    // the session's watchers share one encode per encoding (MESHOPT_DELTA is this stream's
    // own: a delta to what it wrote). On the pool, not inline: this may run on the session's
    // strand (a broadcast), whose next solve must not wait for N watchers' encodes.
    ++encoding_;
    pool_.submit([this, event = std::move(event)]() mutable { encode_and_write(std::move(event)); });
  }

  // One at a time (writing_ stays set until the write is done), so delta_ needs no lock.
  void encode_and_write(std::shared_ptr<const v1::SessionEvent> event) {
    grpc::Status failed;
    try {
      if (format_.encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA) {
        auto out = std::make_shared<v1::SessionEvent>();
        delta_.encode(event->frame(), out->mutable_frame());
        event = std::move(out);
      } else {
        event = session_->encoded_frames().get(std::move(event), format_);
      }
    } catch (const std::exception& e) {
      failed = grpc::Status(grpc::StatusCode::INTERNAL, std::string("frame encoding failed: ") + e.what());
    }
    std::unique_lock lock(mutex_);
    --encoding_;
    if (done_) {
      lock.unlock();
      delete this;
      return;
    }
    if (!failed.ok()) finish_locked(failed);
    if (finished_) return;
    start_write_locked(std::move(event));
  }

  void start_write_locked(std::shared_ptr<const v1::SessionEvent> event) {
    current_ = std::move(event);
    StartWrite(current_.get());
  }

  void finish_locked(const grpc::Status& status) {
    if (finished_) return;
    finished_ = true;
    pending_.clear();
    Finish(status);
  }

  std::shared_ptr<Session> session_;
  const v1::FrameFormat format_;
  std::string client_id_;  // set once, before any event (the constructor or the start task)
  Roster::Claim claim_ = 0;
  WorkerPool& pool_;
  FrameDeltaEncoder delta_;
  std::shared_ptr<Sink> sink_;
  std::mutex mutex_;
  std::deque<std::shared_ptr<const v1::SessionEvent>> pending_;
  std::shared_ptr<const v1::SessionEvent> current_;
  bool writing_ = false, closing_ = false, finished_ = false, done_ = false, starting_ = false;
  int encoding_ = 0;  // 0 or 1: an encode on the pool, which then owns this
  std::uint64_t skipped_ = 0;
};

}  // namespace

grpc::ServerWriteReactor<v1::SessionEvent>* new_watch_reactor(
    std::shared_ptr<Session> session, const v1::FrameFormat& format, std::string client_id,
    Roster::Claim claim, WorkerPool& pool,
    const std::function<void(AuthorizedStream&)>& authorize) {
  return new WatchReactor(std::move(session), format, std::move(client_id), claim, pool,
                          authorize);
}

grpc::ServerWriteReactor<v1::SessionEvent>* new_deferred_watch_reactor(
    WatchStarter start, const v1::FrameFormat& format, WorkerPool& pool,
    std::function<void(AuthorizedStream&)> authorize) {
  return new WatchReactor(std::move(start), format, pool, std::move(authorize));
}

}  // namespace hdeform::service

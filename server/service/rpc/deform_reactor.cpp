#include "service/rpc/reactors.h"

#include "service/rpc/deform_service.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/handle_update.h"

#include <spdlog/spdlog.h>

#include <mutex>
#include <optional>

namespace hdeform::service {

namespace {

// Deform: handle updates in, frames out. Reads never stop: while a solve runs, only the
// newest update waits (latest wins); while a frame is being written, only the newest frame
// waits (a slow reader skips frames). The reactor outlives OnDone until its last solve
// has come back from the pool.
class DeformReactor final : public grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame> {
 public:
  DeformReactor(DeformService* svc, grpc::CallbackServerContext* ctx) : svc_(svc), ctx_(ctx) {
    StartRead(&in_);
  }

  void OnReadDone(bool ok) override {
    std::unique_lock lock(mutex_);
    if (!ok) {
      reads_done_ = true;
      maybe_finish_locked();
      return;
    }
    ++received_;
    if (!session_) {
      if (in_.name().empty()) {
        finish_locked({grpc::StatusCode::INVALID_ARGUMENT,
                       "the first DeformRequest must name the session"});
        return;
      }
      if (!svc_->sessions().resident(in_.name())) {
        // Finding it restores it (parse, factorize) or reads the store: on the pool, never on
        // gRPC's thread. The first message waits in in_ (no read is started meanwhile).
        ++inflight_;
        svc_->pool().submit([this, name = in_.name()] {
          std::shared_ptr<Session> found;
          const auto status = guarded(
              [&] { found = svc_->session_for(*ctx_, name, Access::kEdit, "Deform"); }, "Deform");
          std::unique_lock lock(mutex_);
          if (!returned(lock) || finished_) return;
          if (!status.ok()) {
            finish_locked(status);
            return;
          }
          opened_locked(std::move(found));
          take_locked();
        });
        return;
      }
      std::shared_ptr<Session> found;
      const auto status = guarded(
          [&] { found = svc_->session_for(*ctx_, in_.name(), Access::kEdit, "Deform"); },
          "Deform");
      if (!status.ok()) {
        finish_locked(status);
        return;
      }
      opened_locked(std::move(found));
    }
    take_locked();
  }


  void OnWriteDone(bool ok) override {
    std::unique_lock lock(mutex_);
    writing_ = false;
    current_.reset();
    if (!ok) {
      finish_locked({grpc::StatusCode::CANCELLED, "Deform: the client went away"});
      return;
    }
    if (pending_out_) {
      write_locked(std::move(pending_out_));
      pending_out_.reset();
    } else {
      maybe_finish_locked();
    }
  }

  void OnCancel() override {
    std::unique_lock lock(mutex_);
    finish_locked({grpc::StatusCode::CANCELLED, "Deform cancelled"});
  }

  void OnDone() override {
    if (auth_) {
      std::lock_guard lock(auth_->mutex);
      auth_->reactor = nullptr;
    }
    std::unique_lock lock(mutex_);
    done_ = true;
    if (session_) {
      session_->observers().stream_closed();
      session_->touch();
      spdlog::debug("{}: Deform stream ended: {} updates, {} solves, {} frames skipped",
                    session_->name(), received_, solves_, skipped_frames_);
    }
    if (inflight_ == 0) {
      lock.unlock();
      delete this;
    }
  }

 private:
  // The stream's session, found and authorized: registered for revocation and counted.
  void opened_locked(std::shared_ptr<Session> session) {
    session_ = std::move(session);
    session_->observers().stream_opened();
    session_->touch();
    auth_ = std::make_shared<Revocation>(this);
    svc_->bind_stream(*ctx_, *auth_, Access::kEdit);
    session_->observers().add_stream(auth_);
  }

  // The message in in_ (the session is open): coalesced into the pending update, a solve
  // started when none runs, and the next read.
  void take_locked() {
    if (finished_) return;
    if (in_.has_format()) {
      const auto status = guarded([&] { check_frame_format(in_.format(), "Deform"); }, "Deform");
      if (!status.ok()) {
        finish_locked(status);
        return;
      }
      format_ = in_.format();
    }
    // Latest wins, but a partial update keeps the moves of the one it replaces.
    if (pending_) {
      ++coalesced_;
      merge_deform_requests(*pending_, std::move(in_));
    } else {
      pending_ = std::move(in_);
    }
    in_.Clear();
    if (!solving_) start_solve_locked();
    StartRead(&in_);
  }

  void start_solve_locked() {
    solving_ = true;
    ++inflight_;
    ++solves_;
    // The update is taken when the solve starts, not when it is queued: under load the
    // strand's queue wait can be long, and newer updates arriving meanwhile must win.
    session_->post([this] {
      std::shared_ptr<v1::DeformRequest> request;
      v1::FrameFormat format;
      {
        std::lock_guard lock(mutex_);
        format = format_;
        if (pending_) {
          request = std::make_shared<v1::DeformRequest>(std::move(*pending_));
          pending_.reset();
        }
      }
      if (!request) {  // the stream finished while this waited
        solved({grpc::StatusCode::CANCELLED, "Deform ended"}, nullptr);
        return;
      }
      std::shared_ptr<const v1::Frame> frame;
      const auto status = guarded(
          [&] {
            Session::Update u;
            u.sequence = request->sequence();
            u.transforms = &request->transforms();
            u.keep_transforms_if_empty = true;
            u.energies = request->energies();
            u.dragging = request->dragging();
            u.beta = request->has_beta() ? &request->beta() : nullptr;
            u.handles = &request->handles();
            u.client_id = request->client_id();
            u.float64 = format.encoding() == v1::FRAME_ENCODING_FLOAT64;
            frame = session_->update(u);
            // Stored as the store promises (Session::StoreGate): a β change before its frame
            // goes out, handle moves as SessionStore::moved() says.
            svc_->sessions().moved(*session_);
            frame = encode_frame(std::move(frame), format);
          },
          "Deform");
      solved(status, std::move(frame));
    });
  }

  // A pool task of this stream came back (lock held): false when the call is over, and then
  // the last task back deletes the reactor (lock released).
  bool returned(std::unique_lock<std::mutex>& lock) {
    --inflight_;
    if (!done_) return true;
    if (inflight_ == 0) {
      lock.unlock();
      delete this;
    }
    return false;
  }

  void solved(const grpc::Status& status, std::shared_ptr<const v1::Frame> frame) {
    std::unique_lock lock(mutex_);
    solving_ = false;
    if (!returned(lock) || finished_) return;
    if (!status.ok()) {
      finish_locked(status);
      return;
    }
    if (writing_) {
      if (pending_out_) ++skipped_frames_;
      pending_out_ = std::move(frame);
    } else {
      write_locked(std::move(frame));
    }
    if (pending_)
      start_solve_locked();
    else
      maybe_finish_locked();
  }

  void write_locked(std::shared_ptr<const v1::Frame> frame) {
    current_ = std::move(frame);
    writing_ = true;
    StartWrite(current_.get());
  }

  void maybe_finish_locked() {
    if (reads_done_ && !solving_ && !pending_ && !writing_ && !pending_out_)
      finish_locked(grpc::Status::OK);
  }

  void finish_locked(const grpc::Status& status) {
    if (finished_) return;
    finished_ = true;
    pending_.reset();
    pending_out_.reset();
    Finish(status);
  }

  // The session's handle on this stream: ends it when its token is rotated away or the
  // session is deleted. Outlives the reactor (the session holds it weakly).
  struct Revocation final : AuthorizedStream {
    explicit Revocation(DeformReactor* r) : reactor(r) {}
    void revoke(const grpc::Status& why) override {
      std::lock_guard lock(mutex);
      if (!reactor) return;
      std::lock_guard reactor_lock(reactor->mutex_);
      reactor->finish_locked(why);
    }
    std::mutex mutex;
    DeformReactor* reactor;
  };

  DeformService* svc_;
  grpc::CallbackServerContext* ctx_;
  std::shared_ptr<Revocation> auth_;
  std::mutex mutex_;
  v1::DeformRequest in_;
  std::optional<v1::DeformRequest> pending_;
  v1::FrameFormat format_;  // the latest a message set
  std::shared_ptr<const v1::Frame> current_, pending_out_;
  std::shared_ptr<Session> session_;
  bool solving_ = false, writing_ = false, reads_done_ = false, finished_ = false, done_ = false;
  int inflight_ = 0;
  std::uint64_t received_ = 0, coalesced_ = 0, solves_ = 0, skipped_frames_ = 0;
};

}  // namespace

grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame>* new_deform_reactor(
    DeformService* svc, grpc::CallbackServerContext* ctx) {
  return new DeformReactor(svc, ctx);
}

}  // namespace hdeform::service

#include "service/rpc/deform_service.h"

#include "service/frames/frame_delta.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/release_memory.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/handle_update.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <deque>
#include <mutex>
#include <optional>

namespace hdeform::service {

namespace {

Limits limits_from(const ServerOptions& o) {
  Limits l;
  l.max_sessions = o.max_sessions;
  l.max_vertices = o.max_vertices;
  l.max_upload_bytes = o.max_upload_bytes;
  l.session_ttl = std::chrono::duration_cast<std::chrono::milliseconds>(o.session_ttl);
  l.request = o.request;
  return l;
}

constexpr std::size_t kMeshChunkBytes = 1u << 20;

// ---------------------------------------------------------------------------------------
// CreateSession: header, then upload chunks. Bounded: the byte limit per upload (as chunks
// arrive, and the declared total_bytes as an upper bound), the server-wide budget of bytes
// in flight, and a stall timeout (UploadBudget). A cancelled upload is never loaded.
class CreateSessionReactor final : public grpc::ServerReadReactor<v1::CreateSessionRequest> {
 public:
  CreateSessionReactor(DeformService* svc, grpc::CallbackServerContext* ctx,
                       v1::Session* response)
      : svc_(svc), ctx_(ctx), response_(response), ticket_(svc->uploads().open(ctx)) {
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    ticket_->touch();
    if (!ok) {
      if (ticket_->stalled()) {
        Finish({grpc::StatusCode::DEADLINE_EXCEEDED,
                "upload stalled: no data for " +
                    std::to_string(svc_->uploads().stall_timeout().count()) +
                    " ms (--upload-stall-timeout)"});
      } else if (ctx_->IsCancelled()) {
        Finish({grpc::StatusCode::CANCELLED, "upload cancelled by the client"});
      } else {
        ticket_->received_all();
        finish_upload();
      }
      return;
    }
    if (!have_header_) {
      if (!request_.has_header()) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "the first CreateSessionRequest must carry the header"});
        return;
      }
      header_ = request_.header();
      have_header_ = true;
      const auto status = guarded([&] { check_header(); }, "CreateSession");
      if (!status.ok()) {
        Finish(status);
        return;
      }
    } else {
      if (!request_.has_chunk()) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "only chunks may follow the CreateSession header"});
        return;
      }
      if (header_.has_library_mesh()) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "a library mesh takes no upload chunks"});
        return;
      }
      const std::size_t n = request_.chunk().size();
      received_ += n;
      const auto limit = svc_->sessions().limits().max_upload_bytes;
      if (received_ > limit) {
        spdlog::warn("CreateSession: upload '{}' exceeds {} bytes; rejected", header_.filename(),
                     limit);
        Finish({grpc::StatusCode::RESOURCE_EXHAUSTED,
                "upload exceeds the limit of " + std::to_string(limit) +
                    " bytes (--max-upload-mb)"});
        return;
      }
      const auto declared = static_cast<std::size_t>(header_.total_bytes());
      if (declared > 0 && received_ > declared) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "upload sent more than its declared total_bytes (" + std::to_string(declared) +
                    ")"});
        return;
      }
      // Declared uploads were charged in full at the header; others pay as they go.
      if (declared == 0 && !ticket_->charge(n)) {
        Finish(over_budget());
        return;
      }
      data_->append(request_.chunk());
    }
    request_.Clear();
    StartRead(&request_);
  }

  void OnDone() override {
    ticket_->detach();
    delete this;
  }

 private:
  grpc::Status over_budget() const {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            "the server is receiving too many uploads at once (" +
                std::to_string(svc_->uploads().max_bytes()) +
                " bytes in flight, --max-upload-inflight-mb); retry later"};
  }

  void check_header() {
    const auto& limits = svc_->sessions().limits();
    switch (header_.source_case()) {
      case v1::CreateSessionHeader::kLibraryMesh:
        if (header_.library_mesh().empty()) fail(grpc::StatusCode::INVALID_ARGUMENT,
                                                 "library_mesh is empty");
        break;
      case v1::CreateSessionHeader::kFilename:
        if (header_.filename().empty())
          fail(grpc::StatusCode::INVALID_ARGUMENT, "an upload needs a filename (its format)");
        break;
      default:
        fail(grpc::StatusCode::INVALID_ARGUMENT,
             "CreateSessionHeader needs library_mesh or filename");
    }
    if (header_.total_bytes() < 0)
      fail(grpc::StatusCode::INVALID_ARGUMENT, "total_bytes must not be negative");
    if (static_cast<std::uint64_t>(header_.total_bytes()) > limits.max_upload_bytes)
      fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
           "upload of " + std::to_string(header_.total_bytes()) + " bytes exceeds the limit of " +
               std::to_string(limits.max_upload_bytes) + " bytes (--max-upload-mb)");
    svc_->sessions().check_id(header_.session_id());  // fail fast, before an upload
    svc_->sessions().check_capacity();
    if (header_.total_bytes() > 0) {
      const auto declared = static_cast<std::size_t>(header_.total_bytes());
      if (!ticket_->charge(declared)) throw ServiceError(over_budget().error_code(),
                                                         over_budget().error_message());
      data_->reserve(declared);  // accounted above: an upper bound, enforced per chunk
    }
  }

  void finish_upload() {
    if (!have_header_) {
      Finish({grpc::StatusCode::INVALID_ARGUMENT, "CreateSession needs a header"});
      return;
    }
    std::shared_ptr<const std::string> bytes = std::move(data_);
    svc_->pool().submit([this, bytes] {
      const auto status = guarded(
          [&] {
            svc_->sessions().check_capacity();
            std::shared_ptr<const MeshRef> mesh =
                header_.has_library_mesh() ? svc_->load_library_mesh(header_.library_mesh())
                                           : svc_->load_upload(bytes, header_.filename());
            // The client left while its mesh was parsed: create nothing nobody will own.
            if (ctx_->IsCancelled())
              fail(grpc::StatusCode::CANCELLED, "upload cancelled by the client");
            IssuedTokens tokens;
            auto session =
                svc_->sessions().create(std::move(mesh), header_.session_id(), {}, &tokens);
            *response_ = session->describe();
            response_->set_edit_token(tokens.edit);
            response_->set_view_token(tokens.view);
          },
          "CreateSession");
      Finish(status);
    });
  }

  DeformService* svc_;
  grpc::CallbackServerContext* ctx_;
  v1::Session* response_;
  std::shared_ptr<UploadBudget::Ticket> ticket_;
  v1::CreateSessionRequest request_;
  v1::CreateSessionHeader header_;
  bool have_header_ = false;
  std::size_t received_ = 0;
  std::shared_ptr<std::string> data_ = std::make_shared<std::string>();
};

// ---------------------------------------------------------------------------------------
// A server-streaming call that ends at once with `status`.
template <class Message>
grpc::ServerWriteReactor<Message>* failed_stream(grpc::Status status) {
  class Fail final : public grpc::ServerWriteReactor<Message> {
   public:
    explicit Fail(grpc::Status s) { this->Finish(std::move(s)); }
    void OnDone() override { delete this; }
  };
  return new Fail(std::move(status));
}

// A file streamed in ≤ 1 MiB chunks once it is produced (GetMesh, ExportAnimation).
class ChunkWriter : public grpc::ServerWriteReactor<v1::MeshChunk> {
 public:
  void OnWriteDone(bool ok) override {
    std::lock_guard lock(mutex_);
    if (!ok) {
      Finish({grpc::StatusCode::CANCELLED, "the client went away"});
      return;
    }
    next_locked();
  }

  void OnDone() override { delete this; }

 protected:
  // Starts streaming `data` (once), or ends the call with `status` when it is not OK.
  void produced(const grpc::Status& status, std::string data) {
    if (!status.ok()) {
      Finish(status);
      return;
    }
    std::lock_guard lock(mutex_);
    data_ = std::move(data);
    next_locked();
  }

 private:
  void next_locked() {
    if (offset_ >= data_.size() && offset_ > 0) {
      Finish(grpc::Status::OK);
      return;
    }
    chunk_.Clear();
    if (offset_ == 0) chunk_.set_total_bytes(static_cast<std::int64_t>(data_.size()));
    const std::size_t n = std::min(kMeshChunkBytes, data_.size() - offset_);
    chunk_.set_data(data_.substr(offset_, n));
    offset_ += n;
    if (data_.empty()) offset_ = 1;  // an empty file is one empty chunk
    StartWrite(&chunk_);
  }

  std::mutex mutex_;
  std::string data_;
  std::size_t offset_ = 0;
  v1::MeshChunk chunk_;
};

// GetMesh: the file is produced on the session's strand, then streamed.
class MeshWriter final : public ChunkWriter {
 public:
  MeshWriter(std::shared_ptr<Session> session, const v1::GetMeshRequest& request)
      : session_(std::move(session)) {
    session_->post([this, request] {
      std::string data;
      const auto status = guarded([&] { data = session_->mesh_file(request); }, "GetMesh");
      produced(status, std::move(data));
    });
  }

 private:
  std::shared_ptr<Session> session_;
};

// ExportAnimation: one pool task per sampled frame, like a Sweep (never the session's
// strand, never a worker for the whole export); stops at the next frame when the client
// leaves or its deadline passes, the session is deleted or the server stops. Counted with
// the Sweeps under --max-sweeps.
class AnimationWriter final : public ChunkWriter {
 public:
  AnimationWriter(DeformService* svc, grpc::CallbackServerContext* ctx,
                  std::shared_ptr<Session> session, Session::AnimationPlan plan)
      : svc_(svc), ctx_(ctx), session_(std::move(session)), plan_(std::move(plan)) {
    svc_->pool().submit([this] { step(); });
  }

 private:
  void step() {
    std::string data;
    bool done = false;
    const auto status = guarded(
        [&] {
          if (ctx_->IsCancelled()) throw Cancelled("ExportAnimation cancelled by the client");
          if (std::chrono::system_clock::now() > ctx_->deadline())
            fail(grpc::StatusCode::DEADLINE_EXCEEDED,
                 "ExportAnimation deadline exceeded after " + std::to_string(plan_.next) +
                     " of " + std::to_string(plan_.times.size()) + " frames");
          if (svc_->stopping()) fail(grpc::StatusCode::UNAVAILABLE, "the server is stopping");
          if (session_->closed()) fail(grpc::StatusCode::NOT_FOUND, session_->name() + " was deleted");
          session_->animation_frame(plan_);
          if (plan_.next == plan_.times.size()) {
            data = session_->animation_finish(plan_);
            done = true;
          }
        },
        "ExportAnimation");
    if (status.ok() && !done) {
      svc_->pool().submit([this] { step(); });
      return;
    }
    plan_ = {};  // the frames' memory goes before the bytes are streamed
    --svc_->running_sweeps();
    release_freed_memory();  // a finished sweep must not leave its peak resident
    produced(status, std::move(data));
  }

  DeformService* svc_;
  grpc::CallbackServerContext* ctx_;
  std::shared_ptr<Session> session_;
  Session::AnimationPlan plan_;
};

// ---------------------------------------------------------------------------------------
// WatchSession: the session's state and frames. A slow reader never has more than one
// frame (the newest) and one state (the newest) waiting.
class WatchReactor final : public grpc::ServerWriteReactor<v1::SessionEvent> {
  static constexpr long kMaxPendingSteps = 32;

 public:
  // `client_id`: the watcher joined the session's presence under it (empty: anonymous).
  // `authorize` fills the sink's tokens (DeformService::bind_stream) before it is added.
  WatchReactor(std::shared_ptr<Session> session, const v1::FrameFormat& format,
               std::string client_id, WorkerPool& pool,
               const std::function<void(AuthorizedStream&)>& authorize)
      : session_(std::move(session)),
        format_(format),
        client_id_(std::move(client_id)),
        pool_(pool) {
    sink_ = std::make_shared<Sink>(this);
    authorize(*sink_);
    session_->add_watcher(sink_);
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
      std::lock_guard lock(sink_->mutex);
      sink_->reactor = nullptr;
    }
    session_->remove_watcher(sink_.get());
    if (!client_id_.empty()) session_->leave(client_id_);  // its grabs end with it
    if (format_.encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA) session_->release_delta_watcher();
    {
      std::lock_guard lock(mutex_);
      done_ = true;
      if (encoding_) return;  // the encode in progress deletes this when it ends
    }
    delete this;
  }

 private:
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
  const std::string client_id_;
  WorkerPool& pool_;
  FrameDeltaEncoder delta_;
  std::shared_ptr<Sink> sink_;
  std::mutex mutex_;
  std::deque<std::shared_ptr<const v1::SessionEvent>> pending_;
  std::shared_ptr<const v1::SessionEvent> current_;
  bool writing_ = false, closing_ = false, finished_ = false, done_ = false;
  int encoding_ = 0;  // 0 or 1: an encode on the pool, which then owns this
  std::uint64_t skipped_ = 0;
};

// ---------------------------------------------------------------------------------------
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
      const auto status = guarded(
          [&] { session_ = svc_->session_for(*ctx_, in_.name(), Access::kEdit, "Deform"); },
          "Deform");
      if (!status.ok()) {
        session_.reset();
        finish_locked(status);
        return;
      }
      session_->stream_opened();
      auth_ = std::make_shared<Revocation>(this);
      svc_->bind_stream(*ctx_, *auth_, Access::kEdit);
      session_->add_stream(auth_);
    }
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
      session_->stream_closed();
      spdlog::debug("{}: Deform stream ended: {} updates, {} solves, {} frames skipped",
                    session_->name(), received_, solves_, skipped_frames_);
    }
    if (inflight_ == 0) {
      lock.unlock();
      delete this;
    }
  }

 private:
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
            frame = session_->update(u);
            // Handle moves are saved as SessionStore::moved() says; a β change is an
            // accepted change like SetBeta: durable before its frame goes out.
            if (u.beta) svc_->sessions().save(*session_);
            else svc_->sessions().moved(*session_);
            frame = encode_frame(std::move(frame), format);
          },
          "Deform");
      solved(status, std::move(frame));
    });
  }

  void solved(const grpc::Status& status, std::shared_ptr<const v1::Frame> frame) {
    std::unique_lock lock(mutex_);
    --inflight_;
    solving_ = false;
    if (done_) {
      if (inflight_ == 0) {
        lock.unlock();
        delete this;
      }
      return;
    }
    if (finished_) return;
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

// ---------------------------------------------------------------------------------------

DeformService::DeformService(const ServerOptions& options)
    : options_(options),
      uploads_(options.max_upload_inflight_bytes, options.upload_stall_timeout),
      pool_(std::make_unique<WorkerPool>(options.workers)),
      cache_(options.cache_bytes),
      library_(options.mesh_dir.empty() ? default_mesh_dir() : options.mesh_dir),
      store_(limits_from(options), *pool_, cache_) {
  if (!options.admin_token.empty()) admin_hash_ = hash_token(options.admin_token);
  pool_->publish();  // the workers started before the members after pool_ were built
  open_state();
  pool_->publish();
  store_.start_sweeper();
  spdlog::info("mesh library: {} ({} meshes)", library_.dir().empty() ? "(none)" : library_.dir(),
               library_.list().size());
}

DeformService::~DeformService() {
  begin_shutdown();
  stop_workers();
  close_sessions();
}

void DeformService::begin_shutdown() {
  stopping_ = true;  // long loops (parsing, sweeps, automatic β) stop at their next check
  store_.end_streams();
}

void DeformService::close_sessions() { store_.shutdown(); }  // after begin_shutdown
void DeformService::stop_workers() { pool_->stop(); }

std::shared_ptr<const MeshRef> DeformService::load_library_mesh(const std::string& name) {
  auto entry = library_.find(name);
  if (!entry) fail(grpc::StatusCode::NOT_FOUND, "no mesh '" + name + "' in the library");
  auto bytes = std::make_shared<const std::string>(read_file(entry->path));
  return load_mesh(bytes, entry->path, entry->name, cache_, read_limits());
}

std::shared_ptr<const MeshRef> DeformService::load_upload(std::shared_ptr<const std::string> bytes,
                                                          const std::string& filename) {
  if (bytes->size() > options_.max_upload_bytes)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         "upload exceeds the limit of " + std::to_string(options_.max_upload_bytes) + " bytes");
  return load_mesh(std::move(bytes), filename, "", cache_, read_limits());
}

void DeformService::open_state() {
  if (!options_.state_dir.empty() && !options_.state_redis.empty())
    throw StateError("give --state-dir or --state-redis, not both");
  if (options_.state_dir.empty() && options_.state_redis.empty()) return;
  Persistence p;
  if (!options_.state_redis.empty()) {
    state_ = open_redis_state(options_.state_redis);
    p.save_every_move = true;
    p.revalidate = std::chrono::milliseconds(1000);
  } else {
    state_ = open_sqlite_state(options_.state_dir);
    p.purge_meshes = true;  // this server is the folder's only user (its lock)
  }
  p.backend = state_;
  p.load_mesh = [this](const v1::Snapshot& snap, const std::string& key) {
    return load_stored_mesh(snap, key);
  };
  spdlog::info("session state: {}", state_->describe());
  store_.attach(std::move(p));
}

std::shared_ptr<const MeshRef> DeformService::load_stored_mesh(const v1::Snapshot& snap,
                                                               const std::string& key) {
  std::shared_ptr<const MeshRef> mesh;
  if (!snap.library_mesh().empty()) {
    mesh = load_library_mesh(snap.library_mesh());
  } else {
    auto bytes = state_->get_mesh(key);
    if (!bytes) throw StateError("its mesh " + key + " is missing from " + state_->describe());
    mesh = load_mesh(std::make_shared<const std::string>(std::move(*bytes)), snap.filename(), "",
                     cache_, read_limits());
  }
  if (!snap.mesh_hash().empty() && snap.mesh_hash() != mesh->hash)
    fail(grpc::StatusCode::FAILED_PRECONDITION,
         "its mesh '" + mesh->display_name() + "' has changed since the session was stored");
  return mesh;
}

bool DeformService::is_admin(const std::vector<TokenHash>& token_hashes) const {
  if (!admin_hash_) return false;
  bool admin = false;
  for (const auto& h : token_hashes) admin |= same_hash(h, *admin_hash_);
  return admin;
}

void DeformService::authorize(const grpc::ServerContextBase& ctx, const Session& session,
                              Access needed, const char* op) const {
  const auto hashes = presented_token_hashes(ctx);
  const std::string what = std::string(op) + " on " + session.name() + " needs the session's " +
                           access_name(needed) + " token";
  if (hashes.empty())
    fail(grpc::StatusCode::UNAUTHENTICATED,
         what + ": send the metadata 'authorization: Bearer TOKEN' (CreateSession returned "
                "the edit and view tokens)");
  if (is_admin(hashes)) return;
  const Access got = session.grant(hashes);
  if (static_cast<int>(got) >= static_cast<int>(needed)) return;
  fail(grpc::StatusCode::PERMISSION_DENIED,
       got == Access::kView ? what + "; the token presented is its view token (read-only)"
                            : what + "; the token presented is not one of this session's");
}

void DeformService::bind_stream(const grpc::ServerContextBase& ctx, AuthorizedStream& stream,
                                Access needed) const {
  auto hashes = presented_token_hashes(ctx);
  stream.needed = needed;
  stream.token_hashes = is_admin(hashes) ? std::vector<TokenHash>{} : std::move(hashes);
}

bool DeformService::can_edit(const grpc::ServerContextBase& ctx, const Session& session) const {
  const auto hashes = presented_token_hashes(ctx);
  return is_admin(hashes) || session.grant(hashes) == Access::kEdit;
}

std::shared_ptr<Session> DeformService::session_for(const grpc::ServerContextBase& ctx,
                                                    const std::string& name, Access needed,
                                                    const char* op) {
  auto session = store_.find(name);
  if (!session) fail(grpc::StatusCode::NOT_FOUND, "no session '" + name + "'");
  authorize(ctx, *session, needed, op);
  return session;
}

ReadLimits DeformService::read_limits() const {
  ReadLimits limits;
  limits.max_vertices = options_.max_vertices;
  limits.cancel = &stopping_;  // a parse in progress stops when the server does
  return limits;
}

grpc::ServerUnaryReactor* DeformService::finish_inline(grpc::CallbackServerContext* ctx,
                                                       const char* op, const Work& fn) {
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(guarded(fn, op));
  return reactor;
}

void DeformService::admit_to_pool() const {
  const std::size_t waiting = pool_->queued();
  if (waiting >= options_.request.max_queued_calls)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         "the server has " + std::to_string(waiting) +
             " calls waiting for a solver thread, the limit (--max-queued-calls); retry later");
}

grpc::ServerUnaryReactor* DeformService::finish_on_pool(grpc::CallbackServerContext* ctx,
                                                        const char* op, Work fn) {
  auto* reactor = ctx->DefaultReactor();
  const auto status = guarded([this] { admit_to_pool(); }, op);
  if (!status.ok()) {
    reactor->Finish(status);
    return reactor;
  }
  pool_->submit([reactor, op, fn = std::move(fn)] { reactor->Finish(guarded(fn, op)); });
  return reactor;
}

grpc::ServerUnaryReactor* DeformService::finish_on_session(grpc::CallbackServerContext* ctx,
                                                           const char* op,
                                                           const std::string& name,
                                                           Access needed,
                                                           std::function<void(Session&)> fn,
                                                           std::function<void(Session&)> admit) {
  auto* reactor = ctx->DefaultReactor();
  const auto status = guarded(
      [&] {
        auto session = session_for(*ctx, name, needed, op);
        auto task = [reactor, op, session, fn = std::move(fn)] {
          reactor->Finish(guarded(
              [&] {
                // Deleted while this call waited on the strand: it must not act on a ghost.
                if (session->closed())
                  fail(grpc::StatusCode::NOT_FOUND, session->name() + " was deleted");
                fn(*session);
              },
              op));
        };
        admit_to_pool();
        session->admit_and_post(
            [&] {
              if (admit) admit(*session);
            },
            std::move(task), options_.request.max_session_queue);
      },
      op);
  if (!status.ok()) reactor->Finish(status);
  return reactor;
}

grpc::ServerUnaryReactor* DeformService::finish_change(grpc::CallbackServerContext* ctx,
                                                       const char* op, const std::string& name,
                                                       const std::string& request_id,
                                                       google::protobuf::Message* response,
                                                       std::function<void(Session&)> fn) {
  auto admit = [op, &request_id](Session&) { RequestLog::check_id(request_id, op); };
  auto change = [this, op, request_id, response, fn = std::move(fn)](Session& s) {
    grpc::Status first;
    if (s.requests().replay(op, request_id, response, &first)) {
      if (!first.ok()) throw ServiceError(first.error_code(), first.error_message());
      return;
    }
    fn(s);  // throws when nothing was applied: a retry may try again
    try {
      store_.save(s);
    } catch (const ServiceError& e) {
      s.requests().remember(op, request_id, *response, e.status());
      throw;
    }
    s.requests().remember(op, request_id, *response, grpc::Status::OK);
  };
  return finish_on_session(ctx, op, name, Access::kEdit, std::move(change), std::move(admit));
}

grpc::ServerReadReactor<v1::CreateSessionRequest>* DeformService::CreateSession(
    grpc::CallbackServerContext* ctx, v1::Session* response) {
  return new CreateSessionReactor(this, ctx, response);
}

grpc::ServerUnaryReactor* DeformService::GetSession(grpc::CallbackServerContext* ctx,
                                                    const v1::GetSessionRequest* request,
                                                    v1::Session* response) {
  return finish_inline(ctx, "GetSession", [&] {
    *response = session_for(*ctx, request->name(), Access::kView, "GetSession")->describe();
  });
}

grpc::ServerUnaryReactor* DeformService::ListSessions(grpc::CallbackServerContext* ctx,
                                                      const v1::ListSessionsRequest*,
                                                      v1::ListSessionsResponse* response) {
  return finish_inline(ctx, "ListSessions", [&] {
    const auto hashes = presented_token_hashes(*ctx);
    const bool all = is_admin(hashes);
    if (hashes.empty()) return;  // no token opens no session
    for (auto& s : store_.list())
      if (all || s->grant(hashes) != Access::kNone) *response->add_sessions() = s->describe();
    for (auto& e : store_.list_stored())
      if (all || e.tokens.grant(hashes) != Access::kNone) *response->add_sessions() = e.described;
  });
}

grpc::ServerUnaryReactor* DeformService::DeleteSession(grpc::CallbackServerContext* ctx,
                                                       const v1::DeleteSessionRequest* request,
                                                       v1::DeleteSessionResponse*) {
  return finish_inline(ctx, "DeleteSession", [&] {
    session_for(*ctx, request->name(), Access::kEdit, "DeleteSession");
    if (!store_.remove(request->name()))
      fail(grpc::StatusCode::NOT_FOUND, "no session '" + request->name() + "'");
  });
}

grpc::ServerUnaryReactor* DeformService::ListMeshes(grpc::CallbackServerContext* ctx,
                                                    const v1::ListMeshesRequest*,
                                                    v1::ListMeshesResponse* response) {
  return finish_on_pool(ctx, "ListMeshes", [this, response] {
    for (const auto& e : library_.list()) {
      auto* m = response->add_meshes();
      m->set_name(e.name);
      m->set_path(e.relative_path);  // never the server's absolute paths
      m->set_has_benchmark(e.has_benchmark);
    }
  });
}

grpc::ServerUnaryReactor* DeformService::SetConstraints(grpc::CallbackServerContext* ctx,
                                                        const v1::SetConstraintsRequest* request,
                                                        v1::Session* response) {
  return finish_change(ctx, "SetConstraints", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.set_constraints(
                             request->constraints(), request->expected_version(),
                             request->expected_config_version(), request->client_id(),
                             request->discard_timeline());
                       });
}

grpc::ServerUnaryReactor* DeformService::SetBeta(grpc::CallbackServerContext* ctx,
                                                 const v1::SetBetaRequest* request,
                                                 v1::Session* response) {
  return finish_change(ctx, "SetBeta", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.set_beta(request->beta(), request->expected_version(),
                                                request->expected_config_version(),
                                                request->client_id());
                       });
}

grpc::ServerUnaryReactor* DeformService::UpdateHandles(grpc::CallbackServerContext* ctx,
                                                       const v1::UpdateHandlesRequest* request,
                                                       v1::Frame* response) {
  // A coalescing update takes its ticket on arrival (bounded per session), so that when its
  // turn on the strand comes it knows whether a newer one is waiting.
  auto ticket = std::make_shared<std::unique_ptr<Session::CoalesceTicket>>();
  auto admit = [this, request, ticket](Session& s) {
    check_frame_format(request->format(), "UpdateHandles");
    if (request->coalesce()) *ticket = s.coalesce_ticket(options_.request.max_pending_updates);
  };
  return finish_on_session(
      ctx, "UpdateHandles", request->name(), Access::kEdit,
      [this, request, response, ticket](Session& s) {
        Session::Update u;
        u.sequence = request->sequence();
        u.transforms = &request->transforms();
        u.energies = request->energies();
        u.dragging = request->dragging();
        u.expected_version = request->expected_version();
        u.handles = &request->handles();
        u.client_id = request->client_id();
        u.sequenced = true;
        u.coalesce = request->coalesce();
        if (*ticket && (*ticket)->superseded()) {
          *response = s.supersede(u);
          store_.moved(s);
          return;
        }
        auto frame = s.update(u);
        store_.moved(s);  // a drag: saved coalesced (SQLite) or at once (Redis)
        if (frame->superseded()) return response->Swap(frame.get());  // stale: nothing solved
        if (!encode_frame_to(*frame, request->format(), request->omit_buffers(), response))
          response->Swap(frame.get());
      },
      admit);
}

grpc::ServerWriteReactor<v1::MeshChunk>* DeformService::GetMesh(
    grpc::CallbackServerContext* ctx, const v1::GetMeshRequest* request) {
  std::shared_ptr<Session> session;
  const auto status = guarded(
      [&] { session = session_for(*ctx, request->name(), Access::kView, "GetMesh"); }, "GetMesh");
  if (!status.ok()) {
    return failed_stream<v1::MeshChunk>(status);
  }
  return new MeshWriter(std::move(session), *request);
}

// Sweep: one pool task per β, each queued behind whatever else waits, so a long sweep
// never holds the session's strand (edits go on) nor a worker for its whole length.
// Stops at the next β when the client leaves or its deadline passes, the session is
// deleted or the server stops. At most --max-sweeps run at once.
namespace {
struct SweepJob {
  DeformService* svc;
  grpc::CallbackServerContext* ctx;
  grpc::ServerUnaryReactor* reactor;
  v1::SweepResponse* response;
  std::shared_ptr<Session> session;
  Session::SweepPlan plan;
  std::size_t next = 0;
};

void sweep_step(const std::shared_ptr<SweepJob>& job) {
  auto finish = [&](const grpc::Status& status) {
    --job->svc->running_sweeps();
    release_freed_memory();  // a finished sweep must not leave its peak resident
    job->reactor->Finish(status);
  };
  const auto status = guarded(
      [&] {
        if (job->ctx->IsCancelled()) throw Cancelled("Sweep cancelled by the client");
        if (std::chrono::system_clock::now() > job->ctx->deadline())
          fail(grpc::StatusCode::DEADLINE_EXCEEDED,
               "Sweep deadline exceeded after " + std::to_string(job->next) + " of " +
                   std::to_string(job->plan.betas.size()) + " betas");
        if (job->svc->stopping()) fail(grpc::StatusCode::UNAVAILABLE, "the server is stopping");
        if (job->session->closed())
          fail(grpc::StatusCode::NOT_FOUND, job->session->name() + " was deleted");
        job->session->sweep_row(job->plan, job->plan.betas[job->next],
                                job->response->add_rows());
        ++job->next;
      },
      "Sweep");
  if (!status.ok()) return finish(status);
  if (job->next == job->plan.betas.size()) return finish(grpc::Status::OK);
  job->svc->pool().submit([job] { sweep_step(job); });
}
}  // namespace

grpc::ServerUnaryReactor* DeformService::Sweep(grpc::CallbackServerContext* ctx,
                                               const v1::SweepRequest* request,
                                               v1::SweepResponse* response) {
  auto* reactor = ctx->DefaultReactor();
  auto job = std::make_shared<SweepJob>();
  job->svc = this;
  job->ctx = ctx;
  job->reactor = reactor;
  job->response = response;
  const auto status = guarded(
      [&] {
        job->session = session_for(*ctx, request->name(), Access::kEdit, "Sweep");
        job->plan = job->session->sweep_plan(*request);
        if (++running_sweeps_ > options_.request.max_concurrent_sweeps) {
          --running_sweeps_;
          fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
               "too many sweeps running (" +
                   std::to_string(options_.request.max_concurrent_sweeps) +
                   ", --max-sweeps); retry later");
        }
      },
      "Sweep");
  if (!status.ok()) {
    reactor->Finish(status);
    return reactor;
  }
  pool_->submit([job] { sweep_step(job); });
  return reactor;
}

grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame>* DeformService::Deform(
    grpc::CallbackServerContext* ctx) {
  return new DeformReactor(this, ctx);
}

grpc::ServerWriteReactor<v1::SessionEvent>* DeformService::WatchSession(
    grpc::CallbackServerContext* ctx, const v1::WatchSessionRequest* request) {
  std::shared_ptr<Session> session;
  const auto status = guarded(
      [&] {
        session = session_for(*ctx, request->name(), Access::kView, "WatchSession");
        check_frame_format(request->format(), "WatchSession", /*in_order_stream=*/true);
        if (request->has_client()) Roster::check_participant(request->client(), "WatchSession");
      },
      "WatchSession");
  if (!status.ok()) {
    return failed_stream<v1::SessionEvent>(status);
  }
  // Each watcher's memory is bounded (one pending frame, one state); their number is too.
  if (static_cast<std::size_t>(session->observers()) >= options_.request.max_watchers) {
    return failed_stream<v1::SessionEvent>({grpc::StatusCode::RESOURCE_EXHAUSTED,
                     session->name() + " has " + std::to_string(session->observers()) +
                         " watchers, the limit (--max-watchers)"});
  }
  // MESHOPT_DELTA costs an encode per frame and 8 bytes per vertex per watcher: fewer of them.
  const bool delta = request->format().encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA;
  if (delta && !session->acquire_delta_watcher(options_.request.max_delta_watchers)) {
    return failed_stream<v1::SessionEvent>(
        {grpc::StatusCode::RESOURCE_EXHAUSTED,
         session->name() + " has " + std::to_string(session->delta_watchers()) +
             " MESHOPT_DELTA watchers, the limit (--max-delta-watchers); ask MESHOPT, whose "
             "encode all watchers share"});
  }
  std::string client_id;
  if (request->has_client()) {
    const auto joined = guarded(
        [&] { session->join(request->client(), can_edit(*ctx, *session)); }, "WatchSession");
    if (!joined.ok()) {
      if (delta) session->release_delta_watcher();
      return failed_stream<v1::SessionEvent>(joined);
    }
    client_id = request->client().client_id();
  }
  return new WatchReactor(std::move(session), request->format(), std::move(client_id), *pool_,
                          [&](AuthorizedStream& a) { bind_stream(*ctx, a, Access::kView); });
}

grpc::ServerUnaryReactor* DeformService::ExportSession(grpc::CallbackServerContext* ctx,
                                                       const v1::ExportSessionRequest* request,
                                                       v1::Snapshot* response) {
  return finish_on_session(ctx, "ExportSession", request->name(), Access::kEdit,
                           [request, response](Session& s) {
                             *response = s.export_snapshot(request->include_mesh());
                           });
}

grpc::ServerUnaryReactor* DeformService::ImportSession(grpc::CallbackServerContext* ctx,
                                                       const v1::ImportSessionRequest* request,
                                                       v1::Session* response) {
  // The caller's tokens are read now: the context's metadata is not to be used from the pool
  // after the call could have ended.
  auto hashes = presented_token_hashes(*ctx);
  return finish_on_pool(ctx, "ImportSession", [this, request, response,
                                               hashes = std::move(hashes)] {
    const auto& snap = request->snapshot();
    store_.check_id(request->session_id());
    store_.check_capacity();
    std::shared_ptr<const MeshRef> mesh;
    if (!snap.mesh_bytes().empty()) {
      const std::string filename =
          !snap.filename().empty() ? snap.filename()
                                   : (!snap.library_mesh().empty() ? snap.library_mesh() : "");
      if (filename.empty())
        fail(grpc::StatusCode::INVALID_ARGUMENT, "snapshot mesh_bytes need a filename");
      auto bytes = std::make_shared<const std::string>(snap.mesh_bytes());
      mesh = snap.library_mesh().empty()
                 ? load_upload(bytes, filename)
                 : load_mesh(bytes, filename, snap.library_mesh(), cache_, read_limits());
    } else if (!snap.library_mesh().empty()) {
      mesh = load_library_mesh(snap.library_mesh());
    } else if (!snap.mesh_hash().empty()) {
      // A hash alone must not open someone else's upload: it takes the edit token of a
      // session on that mesh.
      mesh = store_.find_mesh(snap.mesh_hash(), hashes, is_admin(hashes));
      if (!mesh)
        fail(grpc::StatusCode::NOT_FOUND,
             "mesh " + snap.mesh_hash() +
                 " is not on this server under the tokens presented: import by mesh_hash "
                 "alone needs the edit token of a live session on that mesh; otherwise export "
                 "the snapshot with include_mesh");
    } else {
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           "snapshot names no mesh (mesh_bytes, library_mesh or mesh_hash)");
    }
    if (!snap.mesh_hash().empty() && snap.mesh_hash() != mesh->hash)
      fail(grpc::StatusCode::INVALID_ARGUMENT, "snapshot mesh hash " + snap.mesh_hash() +
                                                   " does not match the mesh's hash " +
                                                   mesh->hash);
    IssuedTokens tokens;
    auto session = store_.create(
        mesh, request->session_id(), [&snap](Session& s) { s.restore(snap); }, &tokens);
    *response = session->describe();
    response->set_edit_token(tokens.edit);
    response->set_view_token(tokens.view);
  });
}

// History and snapshots: on the session's strand, ordered with the changes they revert.
grpc::ServerUnaryReactor* DeformService::Undo(grpc::CallbackServerContext* ctx,
                                              const v1::UndoRequest* request,
                                              v1::Session* response) {
  return finish_change(ctx, "Undo", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.undo(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::Redo(grpc::CallbackServerContext* ctx,
                                              const v1::UndoRequest* request,
                                              v1::Session* response) {
  return finish_change(ctx, "Redo", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.redo(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::ListHistory(grpc::CallbackServerContext* ctx,
                                                     const v1::ListHistoryRequest* request,
                                                     v1::ListHistoryResponse* response) {
  return finish_inline(ctx, "ListHistory", [&] {
    *response =
        session_for(*ctx, request->name(), Access::kView, "ListHistory")->list_history(*request);
  });
}

grpc::ServerUnaryReactor* DeformService::SaveSnapshot(grpc::CallbackServerContext* ctx,
                                                      const v1::SaveSnapshotRequest* request,
                                                      v1::NamedSnapshot* response) {
  return finish_change(ctx, "SaveSnapshot", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.save_snapshot(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::ListSnapshots(grpc::CallbackServerContext* ctx,
                                                       const v1::ListSnapshotsRequest* request,
                                                       v1::ListSnapshotsResponse* response) {
  return finish_inline(ctx, "ListSnapshots", [&] {
    *response = session_for(*ctx, request->name(), Access::kView, "ListSnapshots")
                    ->list_snapshots();
  });
}

grpc::ServerUnaryReactor* DeformService::RestoreSnapshot(
    grpc::CallbackServerContext* ctx, const v1::RestoreSnapshotRequest* request,
    v1::Session* response) {
  return finish_change(ctx, "RestoreSnapshot", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.restore_snapshot(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::DeleteSnapshot(grpc::CallbackServerContext* ctx,
                                                        const v1::DeleteSnapshotRequest* request,
                                                        v1::DeleteSnapshotResponse* response) {
  return finish_change(ctx, "DeleteSnapshot", request->name(), request->request_id(), response,
                       [this, request](Session& s) {
                         s.delete_snapshot(request->snapshot(), request->client_id());
                       });
}

// O(n) copy of a column the constraint set keeps: on the pool, not on a gRPC thread.
grpc::ServerUnaryReactor* DeformService::GetHandleWeights(
    grpc::CallbackServerContext* ctx, const v1::GetHandleWeightsRequest* request,
    v1::HandleWeights* response) {
  std::shared_ptr<Session> session;
  const auto status = guarded(
      [&] { session = session_for(*ctx, request->name(), Access::kView, "GetHandleWeights"); },
      "GetHandleWeights");
  if (!status.ok()) {
    auto* reactor = ctx->DefaultReactor();
    reactor->Finish(status);
    return reactor;
  }
  return finish_on_pool(ctx, "GetHandleWeights", [session, request, response] {
    *response = session->handle_weights(request->handle());
  });
}

// Timeline: set on the strand (ordered with SetConstraints, which clears it); read anywhere.
grpc::ServerUnaryReactor* DeformService::SetTimeline(grpc::CallbackServerContext* ctx,
                                                     const v1::SetTimelineRequest* request,
                                                     v1::Timeline* response) {
  return finish_change(ctx, "SetTimeline", request->name(), request->request_id(), response,
                       [this, request, response](Session& s) {
                         *response = s.set_timeline(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::GetTimeline(grpc::CallbackServerContext* ctx,
                                                     const v1::GetTimelineRequest* request,
                                                     v1::Timeline* response) {
  return finish_inline(ctx, "GetTimeline", [&] {
    *response = session_for(*ctx, request->name(), Access::kView, "GetTimeline")->timeline();
  });
}

grpc::ServerUnaryReactor* DeformService::PoseAt(grpc::CallbackServerContext* ctx,
                                                const v1::PoseAtRequest* request,
                                                v1::Keyframe* response) {
  return finish_inline(ctx, "PoseAt", [&] {
    *response =
        session_for(*ctx, request->name(), Access::kView, "PoseAt")->pose_at(request->time_s());
  });
}

grpc::ServerWriteReactor<v1::MeshChunk>* DeformService::ExportAnimation(
    grpc::CallbackServerContext* ctx, const v1::ExportAnimationRequest* request) {
  std::shared_ptr<Session> session;
  Session::AnimationPlan plan;
  const auto status = guarded(
      [&] {
        session = session_for(*ctx, request->name(), Access::kEdit, "ExportAnimation");
        plan = session->animation_plan(*request);
        if (++running_sweeps_ > options_.request.max_concurrent_sweeps) {
          --running_sweeps_;
          fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
               "too many sweeps and animation exports running (" +
                   std::to_string(options_.request.max_concurrent_sweeps) +
                   ", --max-sweeps); retry later");
        }
      },
      "ExportAnimation");
  if (!status.ok()) {
    return failed_stream<v1::MeshChunk>(status);
  }
  return new AnimationWriter(this, ctx, std::move(session), std::move(plan));
}

// Grabs run on the session's strand: they are ordered with SetConstraints, which renumbers
// the handles and ends every grab.
grpc::ServerUnaryReactor* DeformService::GrabHandles(grpc::CallbackServerContext* ctx,
                                                     const v1::GrabHandlesRequest* request,
                                                     v1::GrabHandlesResponse* response) {
  return finish_on_session(ctx, "GrabHandles", request->name(), Access::kEdit,
                           [request, response](Session& s) {
                             *response = s.grab(*request, true);
                           });
}

grpc::ServerUnaryReactor* DeformService::ReleaseHandles(grpc::CallbackServerContext* ctx,
                                                        const v1::ReleaseHandlesRequest* request,
                                                        v1::GrabHandlesResponse* response) {
  return finish_on_session(ctx, "ReleaseHandles", request->name(), Access::kEdit,
                           [request, response](Session& s) {
                             *response = s.release(*request);
                           });
}

grpc::ServerUnaryReactor* DeformService::RotateTokens(grpc::CallbackServerContext* ctx,
                                                      const v1::RotateTokensRequest* request,
                                                      v1::Session* response) {
  return finish_change(ctx, "RotateTokens", request->name(), "", response,
                       [this, response](Session& s) {
                         const IssuedTokens tokens = s.rotate_tokens();
                         *response = s.describe();
                         response->set_edit_token(tokens.edit);
                         response->set_view_token(tokens.view);
                         spdlog::info("{}: tokens rotated", s.name());
                       });
}

}  // namespace hdeform::service

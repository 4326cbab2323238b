#include "service/rpc/reactors.h"

#include "service/rpc/deform_service.h"
#include "service/infra/release_memory.h"
#include "service/infra/service_error.h"

#include <algorithm>
#include <mutex>

namespace hdeform::service {

namespace {

constexpr std::size_t kMeshChunkBytes = 1u << 20;

// A file streamed in ≤ 1 MiB chunks once it is produced (GetMesh, ExportAnimation, ExportRig).
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
  // `report`: ExportRig's, on the first chunk.
  void produced(const grpc::Status& status, std::string data, v1::RigReport report = {}) {
    if (!status.ok()) {
      Finish(status);
      return;
    }
    std::lock_guard lock(mutex_);
    data_ = std::move(data);
    report_ = std::move(report);
    next_locked();
  }

 private:
  void next_locked() {
    if (offset_ >= data_.size() && offset_ > 0) {
      Finish(grpc::Status::OK);
      return;
    }
    chunk_.Clear();
    if (offset_ == 0) {
      chunk_.set_total_bytes(static_cast<std::int64_t>(data_.size()));
      if (report_.joints() > 0) chunk_.mutable_rig_report()->Swap(&report_);
    }
    const std::size_t n = std::min(kMeshChunkBytes, data_.size() - offset_);
    chunk_.set_data(data_.substr(offset_, n));
    offset_ += n;
    if (data_.empty()) offset_ = 1;  // an empty file is one empty chunk
    StartWrite(&chunk_);
  }

  std::mutex mutex_;
  std::string data_;
  v1::RigReport report_;
  std::size_t offset_ = 0;
  v1::MeshChunk chunk_;
};

// GetMesh: the file is produced on the session's strand, then streamed. Without a session,
// `lookup` finds it first on the pool (it may restore it).
class MeshWriter final : public ChunkWriter {
 public:
  MeshWriter(DeformService* svc, std::shared_ptr<Session> session, SessionLookup lookup,
             const v1::GetMeshRequest& request)
      : session_(std::move(session)) {
    if (session_) {
      start(request);
      return;
    }
    svc->pool().submit([this, lookup = std::move(lookup), request] {
      const auto status = guarded([&] { session_ = lookup(); }, "GetMesh");
      if (!status.ok()) return produced(status, {});
      start(request);
    });
  }

 private:
  void start(const v1::GetMeshRequest& request) {
    session_->post([this, request] {
      std::string data;
      const auto status = guarded([&] { data = session_->mesh_file(request); }, "GetMesh");
      produced(status, std::move(data));
    });
  }

  std::shared_ptr<Session> session_;
};

// ExportAnimation: one pool task per sampled frame, like a Sweep (never the session's
// strand, never a worker for the whole export); stops at the next frame when the client
// leaves or its deadline passes, the session is deleted or the server stops. Counted with
// the Sweeps under --max-sweeps.
class AnimationWriter final : public ChunkWriter {
 public:
  // Without a session, the first step finds it with `lookup` (it may restore it) and plans
  // the export from `request`.
  AnimationWriter(DeformService* svc, grpc::CallbackServerContext* ctx,
                  std::shared_ptr<Session> session, AnimationPlan plan,
                  SessionLookup lookup, const v1::ExportAnimationRequest& request)
      : svc_(svc), ctx_(ctx), session_(std::move(session)), plan_(std::move(plan)),
        lookup_(std::move(lookup)), request_(request) {
    svc_->pool().submit([this] { step(); });
  }

 private:
  void step() {
    std::string data;
    bool done = false;
    const auto status = guarded(
        [&] {
          if (!session_) {
            session_ = lookup_();
            plan_ = plan_animation(session_->pose(), session_->limits(), request_);
          }
          if (ctx_->IsCancelled()) throw Cancelled("ExportAnimation cancelled by the client");
          if (std::chrono::system_clock::now() > ctx_->deadline())
            fail(grpc::StatusCode::DEADLINE_EXCEEDED,
                 "ExportAnimation deadline exceeded after " + std::to_string(plan_.next) +
                     " of " + std::to_string(plan_.times.size()) + " frames");
          if (svc_->stopping()) fail(grpc::StatusCode::UNAVAILABLE, "the server is stopping");
          if (session_->closed()) fail(grpc::StatusCode::NOT_FOUND, session_->name() + " was deleted");
          animation_frame(plan_);
          if (plan_.next == plan_.times.size()) {
            data = animation_finish(plan_);
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
  AnimationPlan plan_;
  SessionLookup lookup_;
  v1::ExportAnimationRequest request_;
};

// ExportRig: one pool task (the current pose and each key are one solve each, a timeline
// has at most 256 keys) that stops before the next solve when the client leaves or its
// deadline passes, the session is deleted or the server stops. Counted with the Sweeps.
class RigWriter final : public ChunkWriter {
 public:
  RigWriter(DeformService* svc, grpc::CallbackServerContext* ctx, SessionLookup lookup,
            v1::ExportRigRequest request)
      : svc_(svc), ctx_(ctx), lookup_(std::move(lookup)), request_(std::move(request)) {
    svc_->pool().submit([this] { run(); });
  }

 private:
  void run() {
    RigExport rig;
    const auto status = guarded(
        [&] {
          session_ = lookup_();  // here, on the pool: it may restore the session
          rig = export_rig(session_->pose(), session_->limits(), request_, [this] {
            if (ctx_->IsCancelled()) throw Cancelled("ExportRig cancelled by the client");
            if (std::chrono::system_clock::now() > ctx_->deadline())
              fail(grpc::StatusCode::DEADLINE_EXCEEDED, "ExportRig deadline exceeded");
            if (svc_->stopping()) fail(grpc::StatusCode::UNAVAILABLE, "the server is stopping");
            if (session_->closed())
              fail(grpc::StatusCode::NOT_FOUND, session_->name() + " was deleted");
          });
        },
        "ExportRig");
    --svc_->running_sweeps();
    release_freed_memory();
    produced(status, std::move(rig.glb), std::move(rig.report));
  }

  DeformService* svc_;
  grpc::CallbackServerContext* ctx_;
  SessionLookup lookup_;
  std::shared_ptr<Session> session_;
  v1::ExportRigRequest request_;
};

}  // namespace

grpc::ServerWriteReactor<v1::MeshChunk>* new_rig_writer(DeformService* svc,
                                                        grpc::CallbackServerContext* ctx,
                                                        SessionLookup lookup,
                                                        const v1::ExportRigRequest& request) {
  return new RigWriter(svc, ctx, std::move(lookup), request);
}

grpc::ServerWriteReactor<v1::MeshChunk>* new_mesh_writer(DeformService* svc,
                                                         std::shared_ptr<Session> session,
                                                         SessionLookup lookup,
                                                         const v1::GetMeshRequest& request) {
  return new MeshWriter(svc, std::move(session), std::move(lookup), request);
}

grpc::ServerWriteReactor<v1::MeshChunk>* new_animation_writer(
    DeformService* svc, grpc::CallbackServerContext* ctx, std::shared_ptr<Session> session,
    AnimationPlan plan, SessionLookup lookup, const v1::ExportAnimationRequest& request) {
  return new AnimationWriter(svc, ctx, std::move(session), std::move(plan), std::move(lookup),
                             request);
}

}  // namespace hdeform::service

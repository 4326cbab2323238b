// Reads: mesh files, history and snapshot lists, weights, the timeline and its exports.
// None changes the session; heavy ones run on the pool.
#include "service/rpc/deform_service.h"

#include "service/rpc/failed_stream.h"
#include "service/rpc/reactors.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

namespace hdeform::service {

std::function<std::shared_ptr<Session>()> DeformService::lookup(grpc::CallbackServerContext* ctx, const std::string& name,
                                   Access needed, const char* op) {
  return [this, ctx, name, needed, op] { return session_for(*ctx, name, needed, op); };
}

grpc::ServerWriteReactor<v1::MeshChunk>* DeformService::GetMesh(
    grpc::CallbackServerContext* ctx, const v1::GetMeshRequest* request) {
  std::shared_ptr<Session> session;
  const auto status = guarded(
      [&] {
        if (store_.resident(request->name()))
          session = session_for(*ctx, request->name(), Access::kView, "GetMesh");
        else
          admit_to_pool();  // found (and restored) on the pool
      },
      "GetMesh");
  if (!status.ok()) {
    return failed_stream<v1::MeshChunk>(status);
  }
  return new_mesh_writer(this, std::move(session),
                         lookup(ctx, request->name(), Access::kView, "GetMesh"), *request);
}

grpc::ServerUnaryReactor* DeformService::ListHistory(grpc::CallbackServerContext* ctx,
                                                     const v1::ListHistoryRequest* request,
                                                     v1::ListHistoryResponse* response) {
  return finish_with_session(ctx, "ListHistory", request->name(), [this, ctx, request, response] {
    *response =
        session_for(*ctx, request->name(), Access::kView, "ListHistory")->list_history(*request);
  });
}

grpc::ServerUnaryReactor* DeformService::ListSnapshots(grpc::CallbackServerContext* ctx,
                                                       const v1::ListSnapshotsRequest* request,
                                                       v1::ListSnapshotsResponse* response) {
  return finish_with_session(ctx, "ListSnapshots", request->name(), [this, ctx, request, response] {
    *response = session_for(*ctx, request->name(), Access::kView, "ListSnapshots")
                    ->list_snapshots();
  });
}

// O(n) copy of a column the constraint set keeps: on the pool, not on a gRPC thread.
grpc::ServerUnaryReactor* DeformService::GetHandleWeights(
    grpc::CallbackServerContext* ctx, const v1::GetHandleWeightsRequest* request,
    v1::HandleWeights* response) {
  return finish_on_pool(ctx, "GetHandleWeights", [this, ctx, request, response] {
    *response = session_for(*ctx, request->name(), Access::kView, "GetHandleWeights")
                    ->handle_weights(request->handle());
  });
}

grpc::ServerUnaryReactor* DeformService::GetTimeline(grpc::CallbackServerContext* ctx,
                                                     const v1::GetTimelineRequest* request,
                                                     v1::Timeline* response) {
  return finish_with_session(ctx, "GetTimeline", request->name(), [this, ctx, request, response] {
    *response = session_for(*ctx, request->name(), Access::kView, "GetTimeline")->timeline();
  });
}

grpc::ServerUnaryReactor* DeformService::PoseAt(grpc::CallbackServerContext* ctx,
                                                const v1::PoseAtRequest* request,
                                                v1::Keyframe* response) {
  return finish_with_session(ctx, "PoseAt", request->name(), [this, ctx, request, response] {
    *response =
        session_for(*ctx, request->name(), Access::kView, "PoseAt")->pose_at(request->time_s());
  });
}

grpc::ServerWriteReactor<v1::MeshChunk>* DeformService::ExportAnimation(
    grpc::CallbackServerContext* ctx, const v1::ExportAnimationRequest* request) {
  std::shared_ptr<Session> session;
  AnimationPlan plan;
  const auto status = guarded(
      [&] {
        // Not resident: the writer's first pool task finds (restores) it and plans.
        if (store_.resident(request->name())) {
          session = session_for(*ctx, request->name(), Access::kEdit, "ExportAnimation");
          plan = plan_animation(session->pose(), session->limits(), *request);
        }
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
  return new_animation_writer(this, ctx, std::move(session), std::move(plan),
                              lookup(ctx, request->name(), Access::kEdit, "ExportAnimation"),
                              *request);
}

grpc::ServerWriteReactor<v1::MeshChunk>* DeformService::ExportRig(
    grpc::CallbackServerContext* ctx, const v1::ExportRigRequest* request) {
  std::shared_ptr<Session> found;  // authorized before admission when that needs no work
  const auto status = guarded(
      [&] {
        if (store_.resident(request->name()))
          found = session_for(*ctx, request->name(), Access::kEdit, "ExportRig");
        if (++running_sweeps_ > options_.request.max_concurrent_sweeps) {
          --running_sweeps_;
          fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
               "too many sweeps and exports running (" +
                   std::to_string(options_.request.max_concurrent_sweeps) +
                   ", --max-sweeps); retry later");
        }
      },
      "ExportRig");
  if (!status.ok()) return failed_stream<v1::MeshChunk>(status);
  // Not resident: the session is found on the pool (it may be restored there).
  SessionLookup find = found ? SessionLookup([found] { return found; })
                             : lookup(ctx, request->name(), Access::kEdit, "ExportRig");
  return new_rig_writer(this, ctx, std::move(find), *request);
}

}  // namespace hdeform::service

// The streaming calls' reactors, one file each (DeformService creates them): the upload
// of CreateSession, the Deform and WatchSession streams, and the chunked file writers of
// GetMesh, ExportAnimation and ExportRig. Each deletes itself when its call is done.
#pragma once

#include "hdeform/v1/deform.grpc.pb.h"
#include "service/session/animation_plan.h"
#include "service/session/rig_export.h"
#include "service/session/session.h"

#include <grpcpp/grpcpp.h>

#include <functional>
#include <memory>
#include <string>

namespace hdeform::service {

class DeformService;

grpc::ServerReadReactor<v1::CreateSessionRequest>* new_create_session_reactor(
    DeformService* svc, grpc::CallbackServerContext* ctx, v1::Session* response);
grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame>* new_deform_reactor(
    DeformService* svc, grpc::CallbackServerContext* ctx);
// `client_id`: the watcher joined the session's presence under it with `claim` (empty:
// anonymous); `authorize` fills the sink's tokens before it is added.
grpc::ServerWriteReactor<v1::SessionEvent>* new_watch_reactor(
    std::shared_ptr<Session> session, const v1::FrameFormat& format, std::string client_id,
    Roster::Claim claim, WorkerPool& pool,
    const std::function<void(AuthorizedStream&)>& authorize);
// A watcher admitted to its session (DeformService::start_watch): the session, and the
// presence it joined under (client_id empty: anonymous).
struct WatchStart {
  std::shared_ptr<Session> session;
  std::string client_id;
  Roster::Claim claim = 0;
};
using WatchStarter = std::function<WatchStart()>;
// WatchSession for a session not resident: `start` runs on the pool (it may restore it).
grpc::ServerWriteReactor<v1::SessionEvent>* new_deferred_watch_reactor(
    WatchStarter start, const v1::FrameFormat& format, WorkerPool& pool,
    std::function<void(AuthorizedStream&)> authorize);

// The session a streaming call is for, found on the pool when it is not resident (a lookup
// may restore it: never on gRPC's threads). Throws as DeformService::session_for.
using SessionLookup = std::function<std::shared_ptr<Session>()>;
// GetMesh: the file is produced on the session's strand, then streamed. `session` null:
// `lookup` finds it on the pool first.
grpc::ServerWriteReactor<v1::MeshChunk>* new_mesh_writer(DeformService* svc,
                                                         std::shared_ptr<Session> session,
                                                         SessionLookup lookup,
                                                         const v1::GetMeshRequest& request);
// ExportAnimation: one pool task per sample, then the GLB streamed. `session` null: the first
// task finds it with `lookup` and plans `request` (admission to --max-sweeps came first).
grpc::ServerWriteReactor<v1::MeshChunk>* new_animation_writer(
    DeformService* svc, grpc::CallbackServerContext* ctx, std::shared_ptr<Session> session,
    AnimationPlan plan, SessionLookup lookup, const v1::ExportAnimationRequest& request);
// ExportRig: the session found and the rig built on the pool (its report on the first
// chunk), then streamed.
grpc::ServerWriteReactor<v1::MeshChunk>* new_rig_writer(DeformService* svc,
                                                        grpc::CallbackServerContext* ctx,
                                                        SessionLookup lookup,
                                                        const v1::ExportRigRequest& request);

}  // namespace hdeform::service

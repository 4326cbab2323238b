// The handlers of changes: each builds its command and hands it to finish_change (or,
// for moves, finish_on_session), the one path of a change.
#include "service/rpc/deform_service.h"

#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

namespace hdeform::service {

grpc::ServerUnaryReactor* DeformService::SetConstraints(grpc::CallbackServerContext* ctx,
                                                        const v1::SetConstraintsRequest* request,
                                                        v1::Session* response) {
  return finish_change(ctx, "SetConstraints", request->name(), request->request_id(), response,
                       [request, response](Session& s) {
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
                       [request, response](Session& s) {
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
        u.float64 = request->format().encoding() == v1::FRAME_ENCODING_FLOAT64 &&
                    !request->omit_buffers();
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

// History and snapshots: on the session's strand, ordered with the changes they revert.
grpc::ServerUnaryReactor* DeformService::Undo(grpc::CallbackServerContext* ctx,
                                              const v1::UndoRequest* request,
                                              v1::Session* response) {
  return finish_change(ctx, "Undo", request->name(), request->request_id(), response,
                       [request, response](Session& s) {
                         *response = s.undo(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::Redo(grpc::CallbackServerContext* ctx,
                                              const v1::UndoRequest* request,
                                              v1::Session* response) {
  return finish_change(ctx, "Redo", request->name(), request->request_id(), response,
                       [request, response](Session& s) {
                         *response = s.redo(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::SaveSnapshot(grpc::CallbackServerContext* ctx,
                                                      const v1::SaveSnapshotRequest* request,
                                                      v1::NamedSnapshot* response) {
  return finish_change(ctx, "SaveSnapshot", request->name(), request->request_id(), response,
                       [request, response](Session& s) {
                         *response = s.save_snapshot(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::RestoreSnapshot(
    grpc::CallbackServerContext* ctx, const v1::RestoreSnapshotRequest* request,
    v1::Session* response) {
  return finish_change(ctx, "RestoreSnapshot", request->name(), request->request_id(), response,
                       [request, response](Session& s) {
                         *response = s.restore_snapshot(*request);
                       });
}

grpc::ServerUnaryReactor* DeformService::DeleteSnapshot(grpc::CallbackServerContext* ctx,
                                                        const v1::DeleteSnapshotRequest* request,
                                                        v1::DeleteSnapshotResponse* response) {
  return finish_change(ctx, "DeleteSnapshot", request->name(), request->request_id(), response,
                       [request](Session& s) {
                         s.delete_snapshot(request->snapshot(), request->client_id());
                       });
}

// Timeline: set on the strand (ordered with SetConstraints, which clears it); read anywhere.
grpc::ServerUnaryReactor* DeformService::SetTimeline(grpc::CallbackServerContext* ctx,
                                                     const v1::SetTimelineRequest* request,
                                                     v1::Timeline* response) {
  return finish_change(ctx, "SetTimeline", request->name(), request->request_id(), response,
                       [request, response](Session& s) {
                         *response = s.set_timeline(*request);
                       });
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

}  // namespace hdeform::service

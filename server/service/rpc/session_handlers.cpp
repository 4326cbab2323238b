// Sessions as a whole: create, read, list, delete, export, import, rotate tokens; meshes.
#include "service/rpc/deform_service.h"

#include "service/rpc/reactors.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

grpc::ServerReadReactor<v1::CreateSessionRequest>* DeformService::CreateSession(
    grpc::CallbackServerContext* ctx, v1::Session* response) {
  return new_create_session_reactor(this, ctx, response);
}

grpc::ServerUnaryReactor* DeformService::GetSession(grpc::CallbackServerContext* ctx,
                                                    const v1::GetSessionRequest* request,
                                                    v1::Session* response) {
  return finish_with_session(ctx, "GetSession", request->name(), [this, ctx, request, response] {
    *response = session_for(*ctx, request->name(), Access::kView, "GetSession")->describe();
  });
}

grpc::ServerUnaryReactor* DeformService::ListSessions(grpc::CallbackServerContext* ctx,
                                                      const v1::ListSessionsRequest*,
                                                      v1::ListSessionsResponse* response) {
  // On the pool: the caller's stored records not in memory are read (through the token index).
  return finish_on_pool(ctx, "ListSessions", [this, ctx, response] {
    const auto hashes = presented_token_hashes(*ctx);
    const bool all = is_admin(hashes);
    if (hashes.empty()) return;  // no token opens no session
    for (auto& s : store_.list())
      if (all || s->grant(hashes) != Access::kNone) *response->add_sessions() = s->describe();
    for (auto& e : store_.list_stored(hashes, all)) *response->add_sessions() = e.described;
  });
}

grpc::ServerUnaryReactor* DeformService::DeleteSession(grpc::CallbackServerContext* ctx,
                                                       const v1::DeleteSessionRequest* request,
                                                       v1::DeleteSessionResponse*) {
  return finish_with_session(ctx, "DeleteSession", request->name(), [this, ctx, request] {
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
  // Mesh bytes in a snapshot are an upload: charged to the one in-flight budget before any
  // work — twice, the request and the copy the mesh keeps — until the import ends.
  auto ticket = uploads_.open(ctx);
  ticket->received_all();  // unary: nothing more will arrive, so it cannot stall
  if (const auto& bytes = request->snapshot().mesh_bytes(); !bytes.empty()) {
    if (!ticket->charge(2 * bytes.size())) {
      auto* reactor = ctx->DefaultReactor();
      reactor->Finish(uploads_.exhausted());
      return reactor;
    }
  }
  return finish_on_pool(ctx, "ImportSession", [this, request, response,
                                               hashes = std::move(hashes),
                                               ticket = std::move(ticket)] {
    const struct Release {
      UploadBudget::Ticket& t;
      ~Release() { t.detach(); }
    } release{*ticket};
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
                 ? load_upload(bytes, filename, snap.has_repair() ? &snap.repair() : nullptr)
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
    if (mesh->repair) describe_repair(*mesh, response->mutable_repair());
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
                         store_.save(s);
                       });
}


}  // namespace hdeform::service

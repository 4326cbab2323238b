// The hdeform.v1.Deformation service on gRPC's callback API. Reactions never block:
// parsing, preparing, factorizing and solving run on the worker pool, one session's work
// serialized on that session's strand.
#pragma once

#include "hdeform/v1/deform.grpc.pb.h"
#include "service/infra/cache.h"
#include "service/infra/upload_budget.h"
#include "service/infra/worker_pool.h"
#include "service/rpc/reactors.h"
#include "service/rpc/server.h"
#include "service/session/mesh_library.h"
#include "service/session/session_store.h"

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

namespace hdeform::service {

// CreateSessionHeader.repair / Snapshot.repair as engine options; null: no repair. Throws
// ServiceError INVALID_ARGUMENT for a tolerance outside [0, 0.01].
std::optional<RepairOptions> repair_options(const v1::MeshRepair* repair);

class DeformService final : public v1::Deformation::CallbackService {
 public:
  explicit DeformService(const ServerOptions& options);
  ~DeformService() override;

  // A clean stop, in this order (Server::shutdown): begin_shutdown ends every open stream
  // (UNAVAILABLE) and stops long loops; grpc::Server::Shutdown stops accepting and drains the
  // calls in flight; stop_workers drains the pool; close_sessions flushes the durable state
  // and closes the sessions. So every change that was answered is stored.
  void begin_shutdown();
  // Flushes the durable state, closes every session, stops the TTL sweeper.
  void close_sessions();
  // Drains and joins the worker pool (after the gRPC server has shut down).
  void stop_workers();

  SessionStore& sessions() { return store_; }
  UploadBudget& uploads() { return uploads_; }
  std::atomic<std::size_t>& running_sweeps() { return running_sweeps_; }
  // True once shutdown began: long work polls it (cooperative cancellation).
  bool stopping() const { return stopping_.load(); }
  Cache& cache() { return cache_; }
  WorkerPool& pool() { return *pool_; }
  const MeshLibrary& library() const { return library_; }
  const ServerOptions& options() const { return options_; }

  grpc::ServerReadReactor<v1::CreateSessionRequest>* CreateSession(
      grpc::CallbackServerContext* ctx, v1::Session* response) override;
  grpc::ServerUnaryReactor* GetSession(grpc::CallbackServerContext* ctx,
                                       const v1::GetSessionRequest* request,
                                       v1::Session* response) override;
  grpc::ServerUnaryReactor* ListSessions(grpc::CallbackServerContext* ctx,
                                         const v1::ListSessionsRequest* request,
                                         v1::ListSessionsResponse* response) override;
  grpc::ServerUnaryReactor* DeleteSession(grpc::CallbackServerContext* ctx,
                                          const v1::DeleteSessionRequest* request,
                                          v1::DeleteSessionResponse* response) override;
  grpc::ServerUnaryReactor* ListMeshes(grpc::CallbackServerContext* ctx,
                                       const v1::ListMeshesRequest* request,
                                       v1::ListMeshesResponse* response) override;
  grpc::ServerUnaryReactor* SetConstraints(grpc::CallbackServerContext* ctx,
                                           const v1::SetConstraintsRequest* request,
                                           v1::Session* response) override;
  grpc::ServerUnaryReactor* SetBeta(grpc::CallbackServerContext* ctx,
                                    const v1::SetBetaRequest* request,
                                    v1::Session* response) override;
  grpc::ServerUnaryReactor* UpdateHandles(grpc::CallbackServerContext* ctx,
                                          const v1::UpdateHandlesRequest* request,
                                          v1::Frame* response) override;
  grpc::ServerWriteReactor<v1::MeshChunk>* GetMesh(grpc::CallbackServerContext* ctx,
                                                   const v1::GetMeshRequest* request) override;
  grpc::ServerUnaryReactor* Sweep(grpc::CallbackServerContext* ctx,
                                  const v1::SweepRequest* request,
                                  v1::SweepResponse* response) override;
  grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame>* Deform(
      grpc::CallbackServerContext* ctx) override;
  grpc::ServerWriteReactor<v1::SessionEvent>* WatchSession(
      grpc::CallbackServerContext* ctx, const v1::WatchSessionRequest* request) override;
  grpc::ServerUnaryReactor* ExportSession(grpc::CallbackServerContext* ctx,
                                          const v1::ExportSessionRequest* request,
                                          v1::Snapshot* response) override;
  grpc::ServerUnaryReactor* ImportSession(grpc::CallbackServerContext* ctx,
                                          const v1::ImportSessionRequest* request,
                                          v1::Session* response) override;
  grpc::ServerUnaryReactor* GrabHandles(grpc::CallbackServerContext* ctx,
                                        const v1::GrabHandlesRequest* request,
                                        v1::GrabHandlesResponse* response) override;
  grpc::ServerUnaryReactor* ReleaseHandles(grpc::CallbackServerContext* ctx,
                                           const v1::ReleaseHandlesRequest* request,
                                           v1::GrabHandlesResponse* response) override;
  grpc::ServerUnaryReactor* Undo(grpc::CallbackServerContext* ctx, const v1::UndoRequest* request,
                                 v1::Session* response) override;
  grpc::ServerUnaryReactor* Redo(grpc::CallbackServerContext* ctx, const v1::UndoRequest* request,
                                 v1::Session* response) override;
  grpc::ServerUnaryReactor* ListHistory(grpc::CallbackServerContext* ctx,
                                        const v1::ListHistoryRequest* request,
                                        v1::ListHistoryResponse* response) override;
  grpc::ServerUnaryReactor* SaveSnapshot(grpc::CallbackServerContext* ctx,
                                         const v1::SaveSnapshotRequest* request,
                                         v1::NamedSnapshot* response) override;
  grpc::ServerUnaryReactor* ListSnapshots(grpc::CallbackServerContext* ctx,
                                          const v1::ListSnapshotsRequest* request,
                                          v1::ListSnapshotsResponse* response) override;
  grpc::ServerUnaryReactor* RestoreSnapshot(grpc::CallbackServerContext* ctx,
                                            const v1::RestoreSnapshotRequest* request,
                                            v1::Session* response) override;
  grpc::ServerUnaryReactor* DeleteSnapshot(grpc::CallbackServerContext* ctx,
                                           const v1::DeleteSnapshotRequest* request,
                                           v1::DeleteSnapshotResponse* response) override;
  grpc::ServerUnaryReactor* GetHandleWeights(grpc::CallbackServerContext* ctx,
                                             const v1::GetHandleWeightsRequest* request,
                                             v1::HandleWeights* response) override;
  grpc::ServerUnaryReactor* SetTimeline(grpc::CallbackServerContext* ctx,
                                        const v1::SetTimelineRequest* request,
                                        v1::Timeline* response) override;
  grpc::ServerUnaryReactor* GetTimeline(grpc::CallbackServerContext* ctx,
                                        const v1::GetTimelineRequest* request,
                                        v1::Timeline* response) override;
  grpc::ServerUnaryReactor* PoseAt(grpc::CallbackServerContext* ctx,
                                   const v1::PoseAtRequest* request,
                                   v1::Keyframe* response) override;
  grpc::ServerWriteReactor<v1::MeshChunk>* ExportAnimation(
      grpc::CallbackServerContext* ctx, const v1::ExportAnimationRequest* request) override;
  grpc::ServerWriteReactor<v1::MeshChunk>* ExportRig(
      grpc::CallbackServerContext* ctx, const v1::ExportRigRequest* request) override;
  grpc::ServerUnaryReactor* RotateTokens(grpc::CallbackServerContext* ctx,
                                         const v1::RotateTokensRequest* request,
                                         v1::Session* response) override;

  // Capability check (access.h): throws ServiceError UNAUTHENTICATED (no token) or
  // PERMISSION_DENIED unless the call's tokens grant `needed` on `session`.
  // Whether the call presented the session's edit token (or the operator token).
  bool can_edit(const grpc::ServerContextBase& ctx, const Session& session) const;
  void authorize(const grpc::ServerContextBase& ctx, const Session& session, Access needed,
                 const char* op) const;
  // Fails (UNAUTHENTICATED without tokens, else PERMISSION_DENIED) unless `granted` ≥ `needed`.
  static void refuse_unless(const std::vector<TokenHash>& hashes, const std::string& name,
                            Access granted, Access needed, const char* op);
  // The presented tokens include the operator token.
  bool is_admin(const std::vector<TokenHash>& token_hashes) const;
  // A stream's authorization for `needed` on `session` (AuthorizedStream): the session
  // tokens it presented, none when it presented the operator token (never revoked).
  void bind_stream(const grpc::ServerContextBase& ctx, AuthorizedStream& stream,
                   Access needed) const;
  // The named session (restored from durable state if needed), authorized for `needed`.
  std::shared_ptr<Session> session_for(const grpc::ServerContextBase& ctx,
                                       const std::string& name, Access needed, const char* op);
  // `session` once the call's tokens allow `needed` (else throws as session_for).
  std::shared_ptr<Session> authorized(const grpc::ServerContextBase& ctx,
                                      std::shared_ptr<Session> session, Access needed,
                                      const char* op);

  // Blocking helpers used by the reactors (run on the pool).
  std::shared_ptr<const MeshRef> load_library_mesh(
      const std::string& name, PrepareOrder order = PrepareOrder::on_first_use);
  // How a CreateSession prepares a new mesh (ServerOptions::order_on_open).
  PrepareOrder open_order() const {
    return options_.order_on_open ? PrepareOrder::with_operators : PrepareOrder::on_first_use;
  }
  // `repair` (optional): CreateSessionHeader.repair / Snapshot.repair.
  std::shared_ptr<const MeshRef> load_upload(std::shared_ptr<const std::string> bytes,
                                             const std::string& filename,
                                             const v1::MeshRepair* repair = nullptr,
                                             PrepareOrder order = PrepareOrder::on_first_use);

 private:
  using Work = std::function<void()>;
  // Mesh parsing bounds: --max-vertices while parsing, stopped by shutdown.
  ReadLimits read_limits() const;
  // Finish a unary call with fn's outcome: on the pool, inline or on the pool (a lookup), or
  // on a session's strand (NOT_FOUND when the session does not exist). `admit` runs at arrival, before the
  // call waits for the strand (cheap checks and per-session admission).
  grpc::ServerUnaryReactor* finish_on_pool(grpc::CallbackServerContext* ctx, const char* op,
                                           Work fn);
  // fn (which looks up session `name`) inline when the lookup does no work
  // (SessionStore::resident), else on the pool: a restore or a revalidation never runs on
  // gRPC's callback threads. fn may run after the handler returned: it captures by value.
  // A WatchSession's session found, checked and joined (limits, delta slot, presence);
  // throws ServiceError with what refused it.
  WatchStart start_watch(grpc::CallbackServerContext* ctx, const v1::WatchSessionRequest& request);
  // session_for(ctx, name, needed, op) as a callable for a streaming call's pool task.
  std::function<std::shared_ptr<Session>()> lookup(grpc::CallbackServerContext* ctx,
                                                   const std::string& name, Access needed,
                                                   const char* op);
  grpc::ServerUnaryReactor* finish_with_session(grpc::CallbackServerContext* ctx, const char* op,
                                                const std::string& name, Work fn);
  grpc::ServerUnaryReactor* finish_on_session(grpc::CallbackServerContext* ctx, const char* op,
                                              const std::string& name, Access needed,
                                              std::function<void(Session&)> fn,
                                              std::function<void(Session&)> admit = {});
  // A change of the session (docs/architecture.md "One path for a change"): authorized for
  // editing, admitted to the strand, applied by `fn` (a Session method that runs
  // Session::execute), then persisted — answered only after the store took it. A repeated
  // `request_id` gets the first answer (into `response`) and applies nothing.
  grpc::ServerUnaryReactor* finish_change(grpc::CallbackServerContext* ctx, const char* op,
                                          const std::string& name, const std::string& request_id,
                                          google::protobuf::Message* response,
                                          std::function<void(Session&)> fn);
  // RESOURCE_EXHAUSTED naming --max-queued-calls when that many wait for a solver thread.
  void admit_to_pool() const;
  // Durable state from the options (none, SQLite folder, Redis); throws StateError.
  void open_state();
  std::shared_ptr<const MeshRef> load_stored_mesh(const v1::Snapshot& snapshot,
                                                  const std::string& mesh_key,
                                                  PrepareOrder order);

  ServerOptions options_;
  // Everything the workers read is built before pool_ starts them (declaration order is
  // construction order): a worker thread must never see a member before its initialization.
  std::atomic<std::size_t> running_sweeps_{0};
  std::atomic<bool> stopping_{false};
  UploadBudget uploads_;
  std::unique_ptr<WorkerPool> pool_;
  Cache cache_;
  MeshLibrary library_;
  SessionStore store_;
  std::optional<TokenHash> admin_hash_;
  std::shared_ptr<StateBackend> state_;
};

}  // namespace hdeform::service

#include "service/rpc/deform_service.h"

#include "service/rpc/failed_stream.h"
#include "service/rpc/reactors.h"

#include "service/frames/frame_encoding.h"
#include "service/infra/release_memory.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <mutex>

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

std::optional<RepairOptions> repair_options(const v1::MeshRepair* repair) {
  if (!repair) return std::nullopt;
  const double t = repair->merge_tolerance();
  // Bounded: a large tolerance would merge whole regions (and the grid would have few cells).
  if (!std::isfinite(t) || t < 0 || t > 0.01)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "repair.merge_tolerance must be between 0 and 0.01 (a fraction of the bounding-box "
         "diagonal), got " + fmt::format("{}", t));
  return RepairOptions{t};
}

std::shared_ptr<const MeshRef> DeformService::load_library_mesh(const std::string& name) {
  auto entry = library_.find(name);
  if (!entry) fail(grpc::StatusCode::NOT_FOUND, "no mesh '" + name + "' in the library");
  auto bytes = std::make_shared<const std::string>(read_file(entry->path));
  return load_mesh(bytes, entry->path, entry->name, cache_, read_limits());
}

std::shared_ptr<const MeshRef> DeformService::load_upload(std::shared_ptr<const std::string> bytes,
                                                          const std::string& filename,
                                                          const v1::MeshRepair* repair) {
  if (bytes->size() > options_.max_upload_bytes)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         "upload exceeds the limit of " + std::to_string(options_.max_upload_bytes) + " bytes");
  return load_mesh(std::move(bytes), filename, "", cache_, read_limits(), repair_options(repair));
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
                     cache_, read_limits(),
                     repair_options(snap.has_repair() ? &snap.repair() : nullptr));
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
  if (is_admin(hashes)) return;
  refuse_unless(hashes, session.name(), session.grant(hashes), needed, op);
}

// The answer depends only on the name asked for and what the tokens grant, so an unknown id
// answers exactly as an existing one whose tokens the caller lacks (no existence oracle).
void DeformService::refuse_unless(const std::vector<TokenHash>& hashes, const std::string& name,
                                  Access granted, Access needed, const char* op) {
  if (static_cast<int>(granted) >= static_cast<int>(needed)) return;
  const std::string what =
      std::string(op) + " on " + name + " needs the session's " + access_name(needed) + " token";
  if (hashes.empty())
    fail(grpc::StatusCode::UNAUTHENTICATED,
         what + ": send the metadata 'authorization: Bearer TOKEN' (CreateSession returned "
                "the edit and view tokens)");
  fail(grpc::StatusCode::PERMISSION_DENIED,
       granted == Access::kView
           ? what + "; the token presented is its view token (read-only)"
           : what + "; the token presented opens no session of that name (a deleted or "
                    "expired session's tokens open nothing)");
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
  if (!session) {
    const auto hashes = presented_token_hashes(ctx);
    // Only the operator learns that an id does not exist; anyone else gets the refusal an
    // existing session would give them.
    if (!is_admin(hashes)) {
      refuse_unless(hashes, "sessions/" + SessionStore::id_of(name), Access::kNone, needed, op);
    }
    fail(grpc::StatusCode::NOT_FOUND, "no session '" + name + "'");
  }
  return authorized(ctx, std::move(session), needed, op);
}

std::shared_ptr<Session> DeformService::authorized(const grpc::ServerContextBase& ctx,
                                                   std::shared_ptr<Session> session,
                                                   Access needed, const char* op) {
  authorize(ctx, *session, needed, op);
  return session;
}

ReadLimits DeformService::read_limits() const {
  ReadLimits limits;
  limits.max_vertices = options_.max_vertices;
  limits.cancel = &stopping_;  // a parse in progress stops when the server does
  return limits;
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

grpc::ServerUnaryReactor* DeformService::finish_with_session(grpc::CallbackServerContext* ctx,
                                                             const char* op,
                                                             const std::string& name, Work fn) {
  if (!store_.resident(name)) return finish_on_pool(ctx, op, std::move(fn));
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(guarded(fn, op));
  return reactor;
}

grpc::ServerUnaryReactor* DeformService::finish_on_session(grpc::CallbackServerContext* ctx,
                                                           const char* op,
                                                           const std::string& name,
                                                           Access needed,
                                                           std::function<void(Session&)> fn,
                                                           std::function<void(Session&)> admit) {
  auto* reactor = ctx->DefaultReactor();
  // Looks the session up, admits the call and posts it to the strand; here when the lookup
  // does no work, else from the pool (a restore parses and factorizes).
  auto enter = [this, reactor, ctx, op, name, needed, fn = std::move(fn),
                admit = std::move(admit)](std::shared_ptr<Session> found) mutable {
    const auto status = guarded(
        [&] {
          auto session = found ? authorized(*ctx, std::move(found), needed, op)
                               : session_for(*ctx, name, needed, op);
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
          if (!WorkerPool::on_worker()) admit_to_pool();
          session->admit_and_post(
              [&] {
                if (admit) admit(*session);
              },
              std::move(task), options_.request.max_session_queue);
        },
        op);
    if (!status.ok()) reactor->Finish(status);
  };
  bool resident = false;
  if (auto found = store_.find_resident(name, &resident); found || resident) {
    enter(std::move(found));
    return reactor;
  }
  const auto admitted = guarded([this] { admit_to_pool(); }, op);
  if (!admitted.ok()) {
    reactor->Finish(admitted);
    return reactor;
  }
  pool_->submit([enter = std::move(enter)]() mutable { enter(nullptr); });
  return reactor;
}

grpc::ServerUnaryReactor* DeformService::finish_change(grpc::CallbackServerContext* ctx,
                                                       const char* op, const std::string& name,
                                                       const std::string& request_id,
                                                       google::protobuf::Message* response,
                                                       std::function<void(Session&)> fn) {
  auto admit = [op, request_id](Session&) { RequestLog::check_id(request_id, op); };
  auto change = [this, op, request_id, response, fn = std::move(fn)](Session& s) {
    grpc::Status first;
    if (s.requests().replay(op, request_id, response, &first)) {
      if (!first.ok()) throw ServiceError(first.error_code(), first.error_message());
      return;
    }
    try {
      fn(s);  // stores the change (Session::StoreGate); throws when nothing was applied
    } catch (const ServiceError& e) {
      // Applied but not stored (a token rotation): a retry must not apply it again.
      if (e.status().error_code() == grpc::StatusCode::DATA_LOSS)
        s.requests().remember(op, request_id, *response, e.status());
      throw;
    }
    s.requests().remember(op, request_id, *response, grpc::Status::OK);
  };
  return finish_on_session(ctx, op, name, Access::kEdit, std::move(change), std::move(admit));
}

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
  // Looks the session up, plans and admits; here when the lookup does no work, else from the
  // pool (a restore parses and factorizes).
  auto enter = [this, ctx, request, reactor, job] {
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
      return;
    }
    pool_->submit([job] { sweep_step(job); });
  };
  if (store_.resident(request->name())) {
    enter();
    return reactor;
  }
  const auto admitted = guarded([this] { admit_to_pool(); }, "Sweep");
  if (!admitted.ok()) {
    reactor->Finish(admitted);
    return reactor;
  }
  pool_->submit(std::move(enter));
  return reactor;
}

grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame>* DeformService::Deform(
    grpc::CallbackServerContext* ctx) {
  return new_deform_reactor(this, ctx);
}

WatchStart DeformService::start_watch(grpc::CallbackServerContext* ctx,
                                     const v1::WatchSessionRequest& request) {
  WatchStart w;
  w.session = session_for(*ctx, request.name(), Access::kView, "WatchSession");
  check_frame_format(request.format(), "WatchSession", /*in_order_stream=*/true);
  if (request.has_client()) Roster::check_participant(request.client(), "WatchSession");
  Session& session = *w.session;
  // Each watcher's memory is bounded (one pending frame, one state); their number is too.
  if (static_cast<std::size_t>(session.observers()) >= options_.request.max_watchers)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         session.name() + " has " + std::to_string(session.observers()) +
             " watchers, the limit (--max-watchers)");
  // MESHOPT_DELTA costs an encode per frame and 8 bytes per vertex per watcher: fewer of them.
  const bool delta = request.format().encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA;
  if (delta && !session.acquire_delta_watcher(options_.request.max_delta_watchers))
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         session.name() + " has " + std::to_string(session.delta_watchers()) +
             " MESHOPT_DELTA watchers, the limit (--max-delta-watchers); ask MESHOPT, whose "
             "encode all watchers share");
  if (request.has_client()) {
    try {
      w.claim = session.join(request.client(), can_edit(*ctx, session));
    } catch (...) {
      if (delta) session.release_delta_watcher();
      throw;
    }
    w.client_id = request.client().client_id();
  }
  return w;
}

grpc::ServerWriteReactor<v1::SessionEvent>* DeformService::WatchSession(
    grpc::CallbackServerContext* ctx, const v1::WatchSessionRequest* request) {
  auto authorize = [this, ctx](AuthorizedStream& a) { bind_stream(*ctx, a, Access::kView); };
  if (!store_.resident(request->name())) {
    // Finding it restores it (parse, factorize) or reads the store: on the pool.
    const auto admitted = guarded([this] { admit_to_pool(); }, "WatchSession");
    if (!admitted.ok()) return failed_stream<v1::SessionEvent>(admitted);
    return new_deferred_watch_reactor([this, ctx, request] { return start_watch(ctx, *request); },
                                      request->format(), *pool_, authorize);
  }
  WatchStart w;
  const auto status = guarded([&] { w = start_watch(ctx, *request); }, "WatchSession");
  if (!status.ok()) return failed_stream<v1::SessionEvent>(status);
  return new_watch_reactor(std::move(w.session), request->format(), std::move(w.client_id),
                           w.claim, *pool_, authorize);
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

grpc::ServerUnaryReactor* DeformService::ListHistory(grpc::CallbackServerContext* ctx,
                                                     const v1::ListHistoryRequest* request,
                                                     v1::ListHistoryResponse* response) {
  return finish_with_session(ctx, "ListHistory", request->name(), [this, ctx, request, response] {
    *response =
        session_for(*ctx, request->name(), Access::kView, "ListHistory")->list_history(*request);
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

grpc::ServerUnaryReactor* DeformService::ListSnapshots(grpc::CallbackServerContext* ctx,
                                                       const v1::ListSnapshotsRequest* request,
                                                       v1::ListSnapshotsResponse* response) {
  return finish_with_session(ctx, "ListSnapshots", request->name(), [this, ctx, request, response] {
    *response = session_for(*ctx, request->name(), Access::kView, "ListSnapshots")
                    ->list_snapshots();
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

// O(n) copy of a column the constraint set keeps: on the pool, not on a gRPC thread.
grpc::ServerUnaryReactor* DeformService::GetHandleWeights(
    grpc::CallbackServerContext* ctx, const v1::GetHandleWeightsRequest* request,
    v1::HandleWeights* response) {
  return finish_on_pool(ctx, "GetHandleWeights", [this, ctx, request, response] {
    *response = session_for(*ctx, request->name(), Access::kView, "GetHandleWeights")
                    ->handle_weights(request->handle());
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
  Session::AnimationPlan plan;
  const auto status = guarded(
      [&] {
        // Not resident: the writer's first pool task finds (restores) it and plans.
        if (store_.resident(request->name())) {
          session = session_for(*ctx, request->name(), Access::kEdit, "ExportAnimation");
          plan = session->animation_plan(*request);
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
                         store_.save(s);
                       });
}

}  // namespace hdeform::service

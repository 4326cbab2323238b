// The service's shared machinery: loading meshes, authorization, and the finish_* entry
// points every handler goes through (finish_change is the one path of a change). The
// handlers are in *_handlers.cpp by what they do; the streaming reactors in *_reactor.cpp.
#include "service/rpc/deform_service.h"

#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

namespace {

Limits limits_from(const ServerOptions& o) {
  Limits l;
  l.max_sessions = o.max_sessions;
  l.max_vertices = o.max_vertices;
  l.max_upload_bytes = o.max_upload_bytes;
  l.session_ttl = std::chrono::duration_cast<std::chrono::milliseconds>(o.session_ttl);
  l.request = o.request;
  l.background_order_from = o.background_order_from;
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

std::shared_ptr<const MeshRef> DeformService::load_library_mesh(const std::string& name,
                                                                PrepareOrder order) {
  auto entry = library_.find(name);
  if (!entry) fail(grpc::StatusCode::NOT_FOUND, "no mesh '" + name + "' in the library");
  auto bytes = std::make_shared<const std::string>(read_file(entry->path));
  return load_mesh(bytes, entry->path, entry->name, cache_, read_limits(), {}, order);
}

std::shared_ptr<const MeshRef> DeformService::load_upload(std::shared_ptr<const std::string> bytes,
                                                          const std::string& filename,
                                                          const v1::MeshRepair* repair,
                                                          PrepareOrder order) {
  if (bytes->size() > options_.max_upload_bytes)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         "upload exceeds the limit of " + std::to_string(options_.max_upload_bytes) + " bytes");
  return load_mesh(std::move(bytes), filename, "", cache_, read_limits(), repair_options(repair),
                   order);
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
  p.load_mesh = [this](const v1::Snapshot& snap, const std::string& key, PrepareOrder order) {
    return load_stored_mesh(snap, key, order);
  };
  spdlog::info("session state: {}", state_->describe());
  store_.attach(std::move(p));
}

std::shared_ptr<const MeshRef> DeformService::load_stored_mesh(const v1::Snapshot& snap,
                                                               const std::string& key,
                                                               PrepareOrder order) {
  std::shared_ptr<const MeshRef> mesh;
  if (!snap.library_mesh().empty()) {
    mesh = load_library_mesh(snap.library_mesh(), order);
  } else {
    auto bytes = state_->get_mesh(key);
    if (!bytes) throw StateError("its mesh " + key + " is missing from " + state_->describe());
    mesh = load_mesh(std::make_shared<const std::string>(std::move(*bytes)), snap.filename(), "",
                     cache_, read_limits(),
                     repair_options(snap.has_repair() ? &snap.repair() : nullptr), order);
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

}  // namespace hdeform::service

#include "service/session/session_store.h"

#include "engine/runtime/elapsed_ms.h"
#include "service/infra/release_memory.h"
#include "service/infra/service_error.h"
#include "service/infra/worker_pool.h"
#include "service/session/session_record.h"
#include "service/state/state_keys.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdint>
#include <optional>

namespace hdeform::service {

SessionStore::SessionStore(const Limits& limits, WorkerPool& pool, Cache& cache)
    : limits_(limits),
      pool_(pool),
      cache_(cache),
      background_({.from_vertices = limits.background_order_from}, cache.factor_budget()) {}

SessionStore::~SessionStore() { shutdown(); }

std::string SessionStore::id_of(const std::string& name) {
  static const std::string kPrefix = "sessions/";
  if (name.rfind(kPrefix, 0) == 0) return name.substr(kPrefix.size());
  return name;
}

void SessionStore::check_capacity() const {
  std::lock_guard lock(mutex_);
  if (sessions_.size() >= limits_.max_sessions)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         "session limit reached (" + std::to_string(limits_.max_sessions) +
             " sessions); delete one or wait for idle sessions to expire");
}

namespace {
using Clock = std::chrono::steady_clock;

void check_id_format(const std::string& id) {
  if (id.size() > 64)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "session_id must be 1 to 64 characters of [A-Za-z0-9_-], got " +
             std::to_string(id.size()) + " characters");
  for (char c : id)
    if (!is_session_id_char(c))
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           "session_id '" + id + "' may only contain [A-Za-z0-9_-] (at most 64 characters)");
}
}  // namespace

void SessionStore::check_id(const std::string& id) const {
  if (id.empty()) return;
  check_id_format(id);
  {
    std::lock_guard lock(mutex_);
    if (sessions_.count(id))
      fail(grpc::StatusCode::ALREADY_EXISTS, "session sessions/" + id + " already exists");
  }
  if (durable()) {
    bool stored = false;
    try {
      stored = persistence_.backend->get_session(id).has_value();
    } catch (const StateError& e) {
      fail(grpc::StatusCode::UNAVAILABLE, std::string("session state: ") + e.what());
    }
    if (stored)
      fail(grpc::StatusCode::ALREADY_EXISTS, "session sessions/" + id + " already exists");
  }
}

std::shared_ptr<Session> SessionStore::create(std::shared_ptr<const MeshRef> mesh,
                                              const std::string& requested,
                                              const std::function<void(Session&)>& init,
                                              IssuedTokens* tokens) {
  if (!requested.empty()) check_id_format(requested);
  auto check_locked = [&] {
    if (!requested.empty() && sessions_.count(requested))
      fail(grpc::StatusCode::ALREADY_EXISTS, "session sessions/" + requested + " already exists");
    if (sessions_.size() >= limits_.max_sessions)
      fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
           "session limit reached (" + std::to_string(limits_.max_sessions) + " sessions)");
  };
  std::string id = requested;
  {
    std::lock_guard lock(mutex_);
    check_locked();
    while (id.empty() || sessions_.count(id)) id = random_hex64();
  }
  if (orderings_) orderings_->prime(*mesh);
  auto s = std::make_shared<Session>(id, std::move(mesh), pool_, cache_, limits_.request);
  // Initialised before anyone can reach it (ImportSession's restore): no strand needed,
  // and a failed restore leaves nothing behind. The store step is installed after it: the
  // record below is the session's first, and the restore's own changes must not write one.
  if (init) init(*s);
  gate(*s);
  const IssuedTokens issued = s->rotate_tokens();
  if (tokens) *tokens = issued;
  if (durable()) {
    // Stored before it is published: an id another replica (or a stored session not in
    // memory) owns is refused here, atomically in the backend.
    auto& p = s->persisted();
    std::lock_guard plock(p.mutex);
    try {
      if (s->mesh().library_name.empty() && s->mesh().file_bytes) {
        p.store_generation = persistence_.backend->generation();
        p.mesh_key = persistence_.backend->put_mesh(*s->mesh().file_bytes);
      }
      std::int64_t version = 0;
      const auto record = make_record(*s, p.mesh_key, unix_ms_now(), &version);
      if (!persistence_.backend->create_session(id, record.SerializeAsString(),
                                                 index_hashes(record)))
        fail(grpc::StatusCode::ALREADY_EXISTS, "session sessions/" + id + " already exists");
      p.saved_version = version;
      p.saved_ms = unix_ms_now();
    } catch (const StateError& e) {
      fail(grpc::StatusCode::UNAVAILABLE, std::string("session state could not be saved: ") +
                                              e.what());
    }
  }
  try {
    std::lock_guard lock(mutex_);
    check_locked();  // the id or the last slot may have been taken meanwhile
    if (sessions_.count(id)) fail(grpc::StatusCode::ABORTED, "session id collision; retry");
    sessions_.emplace(id, s);
  } catch (...) {
    if (durable()) {
      try {
        persistence_.backend->delete_session(id);
      } catch (const StateError& e) {
        spdlog::error("{}: {}", s->name(), e.what());
      }
    }
    throw;
  }
  spdlog::info("{}: created on mesh {} ({}, {} vertices)", s->name(), s->mesh_name(),
               s->mesh().hash, s->mesh().layout->vertex_count());
  background_.enqueue(s->mesh_ref());
  return s;
}

std::shared_ptr<Session> SessionStore::find(const std::string& name) const {
  const std::string id = id_of(name);
  std::shared_ptr<Session> s;
  {
    std::lock_guard lock(mutex_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) s = it->second;
  }
  if (s) {
    s->touch();
    if (persistence_.revalidate.count() == 0 || still_current(*s)) return s;
    drop(s);  // served elsewhere since (or deleted there): the store's copy wins
  }
  if (!durable() || id.empty() || id.size() > 64) return nullptr;
  return restore(id);
}

bool SessionStore::resident(const std::string& name) const {
  bool resident = false;
  find_resident(name, &resident);
  return resident;
}

std::shared_ptr<Session> SessionStore::find_resident(const std::string& name,
                                                     bool* resident) const {
  const std::string id = id_of(name);
  std::shared_ptr<Session> s;
  {
    std::lock_guard lock(mutex_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) s = it->second;
  }
  if (!s) {
    if (resident) *resident = !durable() || id.empty() || id.size() > 64;
    return nullptr;
  }
  if (persistence_.revalidate.count() > 0 &&
      unix_ms_now() - s->persisted().checked_ms.load() >= persistence_.revalidate.count()) {
    if (resident) *resident = false;  // find() compares it with the store first
    return nullptr;
  }
  if (resident) *resident = true;
  s->touch();
  return s;
}

bool SessionStore::still_current(Session& s) const {
  auto& p = s.persisted();
  const std::int64_t now = unix_ms_now();
  if (now - p.checked_ms.load() < persistence_.revalidate.count()) return true;
  p.checked_ms = now;
  try {
    auto bytes = persistence_.backend->get_session(s.id());
    if (!bytes) {
      std::lock_guard lock(p.mutex);
      if (persistence_.backend->generation() == p.store_generation) {
        spdlog::info("{}: deleted elsewhere; dropping this copy", s.name());
        return false;
      }
      // Not deleted: the store lost everything (Redis restarted empty). This copy is the
      // session now: it is written again, mesh and all.
      spdlog::warn("{}: missing from {} after it was emptied; writing it again", s.name(),
                   persistence_.backend->describe());
      save_locked(s, p);
      return true;
    }
    const auto record = parse_record(s.id(), *bytes);
    std::lock_guard lock(p.mutex);
    if (record.version() > p.saved_version && record.version() > s.version()) {
      spdlog::info("{}: version {} in {} is newer than this copy's {}; restoring it", s.name(),
                   record.version(), persistence_.backend->describe(), s.version());
      return false;
    }
  } catch (const StateError& e) {
    spdlog::warn("{}: cannot compare with the stored state: {}", s.name(), e.what());
  }
  return true;
}

void SessionStore::forget(Session& s, bool expired) {
  if (durable()) {
    std::lock_guard plock(s.persisted().mutex);  // no save of it may follow the delete
    const std::int64_t saved = s.persisted().saved_version;
    s.persisted().saved_version = INT64_MAX;
    try {
      if (!expired) {
        persistence_.backend->delete_session(s.id());
      } else if (const auto bytes = persistence_.backend->get_session(s.id())) {
        // Idle here is not idle everywhere: a record another replica wrote since (a newer
        // version) is that replica's to expire. The delete is conditional on the very bytes
        // read, so a write landing in between is kept too.
        const std::int64_t stored = parse_record(s.id(), *bytes).version();
        if (stored > saved || !persistence_.backend->delete_session_if(s.id(), *bytes))
          spdlog::info("{}: expired here; its stored state is newer (another replica), kept",
                       s.name());
      }
    } catch (const std::exception& e) {
      spdlog::error("{}: deleting its stored state: {}", s.name(), e.what());
    }
  }
  s.close();
}

void SessionStore::drop(const std::shared_ptr<Session>& s) const {
  {
    std::lock_guard lock(mutex_);
    auto it = sessions_.find(s->id());
    if (it == sessions_.end() || it->second != s) return;
    sessions_.erase(it);
  }
  std::lock_guard plock(s->persisted().mutex);
  s->persisted().saved_version = INT64_MAX;  // this copy never writes again
  s->close();
}

std::shared_ptr<Session> SessionStore::restore(const std::string& id) const {
  if (!WorkerPool::on_worker()) {
    ++restores_off_pool_;
    spdlog::warn("sessions/{}: restored on a thread outside the worker pool", id);
  }
  std::shared_ptr<std::mutex> mine;
  {
    std::lock_guard lock(mutex_);
    auto& m = restoring_[id];
    if (!m) m = std::make_shared<std::mutex>();
    mine = m;
  }
  // The map entry goes with its last user, on every path out.
  struct Release {
    const SessionStore& store;
    const std::string& id;
    std::shared_ptr<std::mutex>& mine;
    ~Release() {
      std::lock_guard lock(store.mutex_);
      const auto it = store.restoring_.find(id);
      if (it != store.restoring_.end() && it->second == mine && mine.use_count() == 2)
        store.restoring_.erase(it);
    }
  } release{*this, id, mine};
  std::lock_guard restoring(*mine);
  {
    std::lock_guard lock(mutex_);  // restored by another caller meanwhile?
    auto it = sessions_.find(id);
    if (it != sessions_.end()) return it->second;
    // The cap before any work (the record, the mesh, the factorizations).
    if (sessions_.size() >= limits_.max_sessions)
      fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
           "session limit reached (" + std::to_string(limits_.max_sessions) +
               " sessions in memory): sessions/" + id + " cannot be restored now");
  }
  const auto t0 = std::chrono::steady_clock::now();
  hdeform::state::StoredSession record;
  try {
    auto bytes = persistence_.backend->get_session(id);
    if (!bytes) return nullptr;
    record = parse_record(id, *bytes);
  } catch (const StateError& e) {
    spdlog::error("restoring sessions/{}: {}", id, e.what());
    fail(grpc::StatusCode::UNAVAILABLE, std::string("session state: ") + e.what());
  }
  std::shared_ptr<Session> s;
  // Where a restore's time goes (the log line below): the mesh (parse and operators, unless
  // another session holds it), then the constraint set (orders, analysis, factorization).
  double record_ms = 0, mesh_ms = 0, constraints_ms = 0;
  try {
    auto t = Clock::now();
    record_ms = elapsed_ms(t0, t);
    // A restore with constraints factors at once: without a stored order, its mesh is
    // ordered beside its operators (PrepareOrder), not after them.
    const auto& snap = record.snapshot();
    std::optional<std::string> stored_orders;
    if (orderings_) stored_orders = orderings_->read(snap.mesh_hash());
    auto mesh = persistence_.load_mesh(
        snap, record.mesh_key(),
        snapshot_has_constraints(snap) && !stored_orders ? PrepareOrder::with_operators
                                                         : PrepareOrder::on_first_use);
    if (orderings_) orderings_->prime(*mesh, stored_orders);
    s = std::make_shared<Session>(id, std::move(mesh), pool_, cache_, limits_.request);
    mesh_ms = elapsed_ms(t, Clock::now());
    t = Clock::now();
    // Re-applying the stored state is not a change to store: the gate comes after it (with
    // it, the restore's SetConstraints would write a record without the mesh key, at the
    // wrong version, over the one it restores).
    s->restore(record.snapshot());
    constraints_ms = elapsed_ms(t, Clock::now());
    s->adopt_snapshots(record.snapshots());
    gate(*s);
  } catch (const StateError& e) {
    spdlog::error("restoring sessions/{}: {}", id, e.what());
    fail(grpc::StatusCode::UNAVAILABLE, "sessions/" + id + " cannot be restored: " + e.what());
  } catch (const ServiceError& e) {
    spdlog::error("restoring sessions/{}: {}", id, e.what());
    fail(grpc::StatusCode::FAILED_PRECONDITION,
         "sessions/" + id + " cannot be restored from its stored state: " + e.what());
  } catch (const std::exception& e) {
    spdlog::error("restoring sessions/{}: {}", id, e.what());
    fail(grpc::StatusCode::FAILED_PRECONDITION,
         "sessions/" + id + " cannot be restored from its stored state: " + e.what());
  }
  s->adopt(record.version(), tokens_of(record), record.create_time_unix_ms(),
           record.update_time_unix_ms());
  std::optional<std::string> history;
  try {
    history = persistence_.backend->get_history(id);
  } catch (const StateError& e) {
    // The session itself is whole: it opens with a new history, and Undo says why.
    spdlog::warn("restoring sessions/{}: its history: {}", id, e.what());
  }
  s->adopt_history(history);
  {
    auto& p = s->persisted();
    std::lock_guard plock(p.mutex);
    p.saved_history = s->history_revision();
    p.mesh_key = record.mesh_key();
    p.store_generation = persistence_.backend->generation();
    p.saved_version = record.version();
    p.saved_ms = unix_ms_now();
  }
  {
    std::lock_guard lock(mutex_);
    if (sessions_.size() >= limits_.max_sessions)
      fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
           "session limit reached (" + std::to_string(limits_.max_sessions) +
               " sessions in memory): sessions/" + id + " cannot be restored now");
    sessions_.emplace(id, s);
  }
  background_.enqueue(s->mesh_ref());
  spdlog::info("{}: restored from {} at version {} ({:.0f} ms: record {:.0f}, mesh {:.0f}, "
               "constraints {:.0f})",
               s->name(), persistence_.backend->describe(), record.version(),
               elapsed_ms(t0, Clock::now()), record_ms, mesh_ms, constraints_ms);
  return s;
}

std::shared_ptr<Session> SessionStore::get(const std::string& name) const {
  auto s = find(name);
  if (!s) fail(grpc::StatusCode::NOT_FOUND, "no session '" + name + "'");
  return s;
}

bool SessionStore::remove(const std::string& name) {
  std::shared_ptr<Session> s;
  {
    std::lock_guard lock(mutex_);
    auto it = sessions_.find(id_of(name));
    if (it == sessions_.end()) return false;
    s = std::move(it->second);
    sessions_.erase(it);
  }
  forget(*s);
  spdlog::info("{}: deleted", s->name());
  s.reset();
  release_freed_memory();  // a no-op while a stream still holds the session
  return true;
}

std::vector<std::shared_ptr<Session>> SessionStore::list() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<Session>> out;
  out.reserve(sessions_.size());
  for (auto& [id, s] : sessions_) out.push_back(s);
  return out;
}

std::size_t SessionStore::size() const {
  std::lock_guard lock(mutex_);
  return sessions_.size();
}

std::shared_ptr<const MeshRef> SessionStore::find_mesh(const std::string& hash,
                                                       const std::vector<TokenHash>& token_hashes,
                                                       bool any) const {
  std::lock_guard lock(mutex_);
  for (auto& [id, s] : sessions_)
    if (s->mesh().hash == hash && (any || s->grant(token_hashes) == Access::kEdit))
      return s->mesh_ref();
  return nullptr;
}

std::size_t SessionStore::expire_idle() {
  const auto now = std::chrono::steady_clock::now();
  if (durable() && now - last_purge_ > std::chrono::minutes(10)) {
    last_purge_ = now;  // stored sessions nobody restored expire too (meshes: at start only)
    try {
      purge_stored(false);
    } catch (const StateError& e) {
      spdlog::error("session state: {}", e.what());
    }
  }
  std::vector<std::shared_ptr<Session>> expired;
  {
    std::lock_guard lock(mutex_);
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      auto& s = it->second;
      if (s->observers().busy()) {
        s->touch();
        ++it;
      } else if (now - s->last_used() > limits_.session_ttl) {
        expired.push_back(std::move(s));
        it = sessions_.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (auto& s : expired) {
    spdlog::info("{}: expired after {} ms idle", s->name(), limits_.session_ttl.count());
    forget(*s, true);
  }
  const std::size_t n = expired.size();
  expired.clear();
  if (n > 0) release_freed_memory();
  return n;
}

void SessionStore::start_sweeper() {
  if (durable() && !flusher_.joinable()) {
    flusher_ = std::thread([this] {
      std::unique_lock lock(sweeper_mutex_);
      while (!stopping_) {
        sweeper_cv_.wait_for(lock, persistence_.flush_period, [this] { return stopping_; });
        if (stopping_) break;
        lock.unlock();
        flush();
        lock.lock();
      }
    });
  }
  if (sweeper_.joinable()) return;
  const auto period = std::clamp<std::chrono::milliseconds>(
      limits_.session_ttl / 4, std::chrono::milliseconds(50), std::chrono::milliseconds(1'000));
  sweeper_ = std::thread([this, period] {
    std::unique_lock lock(sweeper_mutex_);
    while (!stopping_) {
      sweeper_cv_.wait_for(lock, period, [this] { return stopping_; });
      if (stopping_) break;
      lock.unlock();
      try {
        expire_idle();
        // Handle grabs of clients that stopped renewing end within a second of their lease.
        for (auto& s : list()) s->expire_leases();
      } catch (const std::exception& e) {
        spdlog::error("session sweeper: {}", e.what());
      }
      lock.lock();
    }
  });
}

void SessionStore::end_streams() {
  const grpc::Status stopping(grpc::StatusCode::UNAVAILABLE,
                              "hdeform-server is shutting down; reconnect to resume the session");
  for (auto& s : list()) s->observers().end_all(stopping);
}

void SessionStore::shutdown() {
  background_.stop();  // no further order; the one in progress runs on past the flush
  {
    std::lock_guard lock(sweeper_mutex_);
    stopping_ = true;
  }
  sweeper_cv_.notify_all();
  if (sweeper_.joinable()) sweeper_.join();
  if (flusher_.joinable()) flusher_.join();
  if (durable()) flush(true);  // the last moves of a drag (and steps) survive a clean stop
  std::map<std::string, std::shared_ptr<Session>> all;
  {
    std::lock_guard lock(mutex_);
    all.swap(sessions_);
  }
  for (auto& [id, s] : all) s->close();
  // Last: the sessions are stored by now, so a stop killed while METIS ends (up to seconds
  // at 1M vertices) loses nothing but that order.
  background_.join();
}

std::vector<SessionStore::StoredEntry> SessionStore::list_stored(
    const std::vector<TokenHash>& presented, bool all) const {
  std::vector<StoredEntry> out;
  if (!durable() || (!all && presented.empty())) return out;
  std::vector<std::string> ids;
  try {
    // A token holder's sessions from the index: no one else's record is read for them.
    ids = all ? persistence_.backend->list_sessions()
              : persistence_.backend->sessions_for(index_hashes(presented));
  } catch (const StateError& e) {
    fail(grpc::StatusCode::UNAVAILABLE, std::string("session state: ") + e.what());
  }
  for (const auto& id : ids) {
    {
      std::lock_guard lock(mutex_);
      if (sessions_.count(id)) continue;  // listed from memory
    }
    try {
      auto bytes = persistence_.backend->get_session(id);
      if (!bytes) continue;  // deleted meanwhile
      const auto record = parse_record(id, *bytes);
      // The record decides: an index entry may be older than a rotation elsewhere.
      const SessionTokens tokens = tokens_of(record);
      if (!all && tokens.grant(presented) == Access::kNone) continue;
      out.push_back({record.described(), tokens});
    } catch (const StateError& e) {
      spdlog::warn("listing stored sessions: {}", e.what());
    }
  }
  return out;
}

void SessionStore::attach(Persistence persistence) {
  persistence_ = std::move(persistence);
  if (!durable()) return;
  orderings_ = std::make_unique<OrderingStore>(*persistence_.backend);
  purge_stored(persistence_.purge_meshes);
}

// Expired records go; records that cannot be read are reported and kept (never
// overwritten: an operator may want them back).
void SessionStore::purge_stored(bool meshes_too) {
  const auto ids = persistence_.backend->list_sessions();
  const std::int64_t now = unix_ms_now();
  std::size_t kept = 0, expired = 0, unreadable = 0;
  std::vector<std::string> mesh_keys, mesh_hashes;
  for (const auto& id : ids) {
    std::optional<std::string> bytes = persistence_.backend->get_session(id);
    if (!bytes) continue;
    try {
      const auto record = parse_record(id, *bytes);
      if (now - record.last_used_unix_ms() > limits_.session_ttl.count()) {
        persistence_.backend->delete_session(id);
        ++expired;
        continue;
      }
      if (!record.mesh_key().empty()) mesh_keys.push_back(record.mesh_key());
      mesh_hashes.push_back(record.snapshot().mesh_hash());
      // At start: a record stored before the token index existed gets its entries.
      if (meshes_too) {
        const auto hashes = index_hashes(record);
        const auto indexed = persistence_.backend->sessions_for({hashes[0]});
        if (std::find(indexed.begin(), indexed.end(), id) == indexed.end())
          persistence_.backend->index_session(id, hashes);
      }
      ++kept;
    } catch (const StateError& e) {
      spdlog::error("{} (left as it is)", e.what());
      ++unreadable;
    }
  }
  std::size_t meshes = 0;
  // An unreadable record may refer to any mesh: then no mesh is dropped.
  if (meshes_too && unreadable == 0) {
    meshes = persistence_.backend->purge_meshes(mesh_keys);
    persistence_.backend->purge_derived(mesh_hashes);
  }
  if (meshes_too)
    spdlog::info("session state {}: {} stored sessions (restored on first use), {} expired, {} "
                 "unreadable, {} unused meshes dropped",
                 persistence_.backend->describe(), kept, expired, unreadable, meshes);
  else if (expired > 0)
    spdlog::info("session state: {} stored sessions expired", expired);
}

void SessionStore::save_locked(Session& s, Session::Persisted& p,
                               const Session::PendingPose* pending) const {
  p.dirty = false;
  std::int64_t version = 0;
  const std::int64_t now = unix_ms_now();
  const auto last_used =
      now - std::chrono::duration_cast<std::chrono::milliseconds>(
                std::chrono::steady_clock::now() - s.last_used())
                .count();
  const auto record = make_record(s, p.mesh_key, last_used, &version, pending);
  if (version < p.saved_version) return;  // deleted (INT64_MAX), or a newer one is stored
  persistence_.backend->put_session(s.id(), record.SerializeAsString(), index_hashes(record));
  // A store that may have lost data since the mesh was written (Redis restarted empty; the
  // write above may be what found out) gets it again: a record without its mesh could never
  // be restored by another replica.
  if (const auto g = persistence_.backend->generation();
      !p.mesh_key.empty() && g != p.store_generation && s.mesh().file_bytes) {
    if (!persistence_.backend->has_mesh(p.mesh_key)) {
      persistence_.backend->put_mesh(*s.mesh().file_bytes);
      spdlog::warn("{}: its mesh was missing from {}; written again", s.name(),
                   persistence_.backend->describe());
    }
    p.store_generation = g;
    p.saved_history = s.history_revision() - 1;  // lost with the rest: the flusher rewrites it
  }
  p.saved_version = version;
  p.saved_ms = now;
}

void SessionStore::save(Session& s) const {
  if (!durable()) return;
  auto& p = s.persisted();
  std::lock_guard lock(p.mutex);
  try {
    save_locked(s, p);
  } catch (const StateError& e) {
    p.dirty = true;  // the flusher tries again
    spdlog::error("{}: {}", s.name(), e.what());
    // Not UNAVAILABLE: clients retry that, and this change is applied already.
    fail(grpc::StatusCode::DATA_LOSS,
         "the change was applied but is not stored yet (" + std::string(e.what()) +
             "): the server stores it once the store answers again, and it is lost only if "
             "the server stops before; do not send it again");
  }
}

void SessionStore::moved(Session& s) const {
  if (!durable() || persistence_.save_every_move) return;
  s.persisted().dirty = true;
}

void SessionStore::gate(Session& session) const {
  if (!durable()) return;
  session.set_store_gate([this](Session& s, const Session::PendingPose* pose) {
    // A drag's moves are coalesced (flush_period) unless every move must be durable, or it
    // changes β (an accepted change like SetBeta). Decided before the lock: a flusher's
    // write holds it, and a coalesced move must not wait for that.
    if (pose && !persistence_.save_every_move && !pose->beta_changed) return std::unique_lock<std::mutex>{};
    auto& p = s.persisted();
    std::unique_lock lock(p.mutex);
    try {
      save_locked(s, p, pose);
    } catch (const StateError& e) {
      p.dirty = true;  // the flusher writes what the session holds over what may have landed
      spdlog::error("{}: a change was refused: {}", s.name(), e.what());
      fail(grpc::StatusCode::UNAVAILABLE,
           std::string(pose ? "the move" : "the change") +
               " was not applied: the session store did not acknowledge it (" + e.what() +
               "); the session is unchanged, send it again");
    }
    return lock;
  });
}

void SessionStore::flush(bool final) {
  if (!durable()) return;
  const std::int64_t now = unix_ms_now();
  const auto sessions = list();
  std::vector<std::shared_ptr<const MeshRef>> meshes;
  for (const auto& s : sessions) meshes.push_back(s->mesh_ref());
  orderings_->keep(meshes);
  for (auto& s : sessions) {
    auto& p = s->persisted();
    std::lock_guard lock(p.mutex);
    // A session in use has its record refreshed now and then: its idle clock is what
    // expires it where it is not in memory (after a restart, on another replica).
    const bool refresh =
        now - p.saved_ms > persistence_.refresh_period.count() &&
        std::chrono::steady_clock::now() - s->last_used() < persistence_.refresh_period;
    const bool history = s->history_revision() != p.saved_history &&
                         (final || now - p.saved_history_ms >= kHistoryPeriod.count());
    if (!p.dirty && !refresh && !history) continue;
    try {
      if (p.dirty || refresh) save_locked(*s, p);
      if (history) save_history_locked(*s, p);
    } catch (const StateError& e) {
      p.dirty = true;
      spdlog::error("{}: saving its state: {}", s->name(), e.what());
    }
  }
}

void SessionStore::save_history_locked(Session& s, Session::Persisted& p) const {
  if (p.saved_version == INT64_MAX) return;  // deleted: nothing of it is written again
  std::uint64_t revision = 0;
  const std::string bytes = s.history_bytes(&revision);
  // Written after its record (the store keeps a history only beside one): false means the
  // record is not there yet, and the next flush tries again.
  if (persistence_.backend->put_history(s.id(), bytes)) {
    p.saved_history = revision;
    p.saved_history_ms = unix_ms_now();
  }
}

}  // namespace hdeform::service

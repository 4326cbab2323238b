// The registry of live sessions: limits, lookup by name, idle-TTL expiry, and (optionally)
// their durable copy in a StateBackend (docs/deployment.md "State"): a session not in memory
// is restored from its record on first use (after a restart, or on another replica).
#pragma once

#include "service/infra/request_limits.h"
#include "service/session/background_orders.h"
#include "service/session/session.h"
#include "service/session/ordering_store.h"
#include "service/state/state_backend.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace hdeform::service {

struct Limits {
  std::size_t max_sessions = 64;
  std::size_t max_vertices = 2'000'000;
  std::size_t max_upload_bytes = 256u << 20;
  std::chrono::milliseconds session_ttl{std::chrono::hours(1)};
  RequestLimits request;
  // A new mesh's β > 0 order, computed in the background from this many vertices on
  // (background_orders.h; --background-order-from); 0 = never.
  std::size_t background_order_from = 20000;
};

// Durable state for a SessionStore.
struct Persistence {
  std::shared_ptr<StateBackend> backend;
  // The mesh of a stored session: by library name, or the upload stored under mesh_key;
  // a PreparedMesh built for it orders its β = 0 system as `order` says (load_mesh).
  std::function<std::shared_ptr<const MeshRef>(
      const pb::Snapshot& snapshot, const std::string& mesh_key, PrepareOrder order)>
      load_mesh;
  // Handle moves are saved at most this late (a drag's last moves lost on kill -9)...
  std::chrono::milliseconds flush_period{100};
  // ... or each before its frame is answered (Redis: a write costs ~0.1 ms, and a replica
  // taking over must find the pose the client last saw).
  bool save_every_move = false;
  // A used session's record is refreshed this often (its idle clock, for expiry elsewhere).
  std::chrono::milliseconds refresh_period{30'000};
  // Drop stored meshes no record refers to (one server per store: SQLite, not Redis).
  bool purge_meshes = false;
  // Shared stores (Redis): another replica may have served a session meanwhile. A session
  // in memory is checked against its record at most this often; 0 = never (one owner).
  std::chrono::milliseconds revalidate{0};
};

class SessionStore {
 public:
  SessionStore(const Limits& limits, WorkerPool& pool, Cache& cache);
  ~SessionStore();

  const Limits& limits() const { return limits_; }
  BackgroundOrders::Stats background_orders() const { return background_.stats(); }
  // RESOURCE_EXHAUSTED when no session can be added.
  void check_capacity() const;
  // `id` (the {id} of sessions/{id}): empty → the server picks one; else it must be
  // [A-Za-z0-9_-]{1,64} (INVALID_ARGUMENT) and free (ALREADY_EXISTS).
  // `init` (optional) runs on the new session before it is published: on a throw the
  // session is never reachable.
  // The new session gets fresh capability tokens (`tokens`, optional, receives them) and,
  // with durable state, is stored (with its uploaded mesh) before it is published.
  std::shared_ptr<Session> create(std::shared_ptr<const MeshRef> mesh, const std::string& id = "",
                                  const std::function<void(Session&)>& init = {},
                                  IssuedTokens* tokens = nullptr);
  // Early checks of a client-chosen id (format, and not taken right now); "" passes.
  void check_id(const std::string& id) const;
  // "sessions/{id}" or "{id}"; nullptr when unknown. With durable state a session that is
  // stored but not in memory is restored first (ServiceError UNAVAILABLE / FAILED_PRECONDITION
  // when its record or mesh cannot be read: the record is left as it is).
  std::shared_ptr<Session> find(const std::string& name) const;
  // Whether find(name) would do no I/O and no work: the session is in memory and needs no
  // revalidation against the store now. When false, callers on gRPC's threads move the
  // lookup to the worker pool (a restore parses and factorizes; a revalidation reads the
  // store). Unknown names are "resident" only without durable state (nothing to read).
  bool resident(const std::string& name) const;
  // The session when find() would return it without work (in memory, no revalidation due);
  // else null, and *resident (optional) says whether find() would do no work anyway (an id
  // that cannot be stored). One map lookup where resident() + find() would take two.
  std::shared_ptr<Session> find_resident(const std::string& name, bool* resident = nullptr) const;
  // Restores that ran on a thread outside the worker pool (should stay 0; each is logged).
  std::size_t restores_off_pool() const { return restores_off_pool_.load(); }
  std::shared_ptr<Session> get(const std::string& name) const;  // NOT_FOUND
  // Deletes the session and its durable record.
  bool remove(const std::string& name);
  std::vector<std::shared_ptr<Session>> list() const;
  // Stored sessions not in memory, as their records describe them (durable state only),
  // with their token hashes. Unreadable records are skipped (and logged).
  struct StoredEntry {
    pb::Session described;
    SessionTokens tokens;
  };
  // Stored sessions not in memory that `presented` opens (every one when `all`: the
  // operator), read through the state's token index.
  std::vector<StoredEntry> list_stored(const std::vector<TokenHash>& presented, bool all) const;
  std::size_t size() const;
  // A mesh a live session uses, by content hash, provided `token_hashes` hold the edit
  // token of a session on it (or `any`: the operator).
  std::shared_ptr<const MeshRef> find_mesh(const std::string& hash,
                                           const std::vector<TokenHash>& token_hashes,
                                           bool any) const;

  // ---- durable state ----
  // Before start_sweeper(): reads the stored ids and purges expired records (and, when
  // asked, unreferenced meshes). Sessions are restored lazily, on first use.
  void attach(Persistence persistence);
  bool durable() const { return persistence_.backend != nullptr; }
  // Writes the session's record now, for a change outside the commit path (token rotation;
  // every other change is stored by the session's StoreGate before it is answered). Throws
  // ServiceError DATA_LOSS when the store fails: the change is applied, and the flusher
  // stores it once the store answers again.
  void save(Session& session) const;
  // The session's handles moved: saved within flush_period. Never throws: a failed save is
  // logged and retried by the flusher. With save_every_move each move was written before it
  // was applied (StoreGate: a move the store does not acknowledge is refused and changes
  // nothing), so this has nothing left to do.
  void moved(Session& session) const;
  // Writes every dirty session's record (the flusher's job; also at shutdown), and each
  // changed history at most once per kHistoryPeriod (a history is rewritten whole: a β
  // slider drag would otherwise rewrite it every period); `final`: every changed one now.
  void flush(bool final = false);
  static constexpr std::chrono::milliseconds kHistoryPeriod{1000};

  // Removes sessions idle for longer than the TTL (observed or streaming sessions are
  // never idle). Returns how many expired.
  std::size_t expire_idle();
  void start_sweeper();
  // Ends every session's open streams (UNAVAILABLE: the server is stopping); the sessions
  // stay, so what is still in flight commits and is flushed by shutdown().
  void end_streams();
  // Stops the sweeper, flushes the durable state and closes every session.
  void shutdown();

 // "sessions/ID" or "ID" → ID.
  static std::string id_of(const std::string& name);

 private:

  std::shared_ptr<Session> restore(const std::string& id) const;
  // False when the store holds a newer version of `s` (or none): the copy must go.
  bool still_current(Session& s) const;
  void drop(const std::shared_ptr<Session>& s) const;
  // A session taken out of the registry (deleted, or `expired` here): its stored state is
  // deleted — an expired one's only while the store still holds what this replica wrote —
  // and its streams end.
  void forget(Session& s, bool expired = false);
  void save_locked(Session& session, Session::Persisted& p,
                   const Session::PendingPose* pending = nullptr) const;
  // Writes the session's history when it changed since the last write (the flusher's;
  // a history is as durable as a coalesced move: docs/api.md "History and snapshots").
  void save_history_locked(Session& session, Session::Persisted& p) const;
  // Installs the store's step of the session's commit path (Session::StoreGate).
  void gate(Session& session) const;
  void purge_stored(bool meshes_too);

  Limits limits_;
  WorkerPool& pool_;
  Cache& cache_;
  // Stopped first at shutdown; mutable: a restore (in find) queues its mesh.
  mutable BackgroundOrders background_;
  mutable std::mutex mutex_;
  // by id; mutable: find() publishes sessions it restores
  mutable std::map<std::string, std::shared_ptr<Session>> sessions_;
  Persistence persistence_;
  std::unique_ptr<OrderingStore> orderings_;  // with a durable store
  mutable std::atomic<std::size_t> restores_off_pool_{0};
  // One restore per id at a time (a second caller waits for the first and takes its
  // session); different ids restore in parallel. Guarded by mutex_.
  mutable std::map<std::string, std::shared_ptr<std::mutex>> restoring_;
  std::thread flusher_;
  std::chrono::steady_clock::time_point last_purge_ = std::chrono::steady_clock::now();

  std::mutex sweeper_mutex_;
  std::condition_variable sweeper_cv_;
  bool stopping_ = false;
  std::thread sweeper_;
};

}  // namespace hdeform::service

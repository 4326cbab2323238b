// Durable session state (docs/deployment.md "State"): one opaque record per session id and
// uploaded mesh files stored once each, by the SHA-256 of their bytes. Two backends: SQLite
// in a local folder (the embedded default) and Redis (shared by replicas, for failover).
// The service decides what a record holds (stored_session.proto); a backend only keeps bytes.
//
// Every method is thread-safe and blocking. A write has reached the backend's durable store
// when it returns (SQLite: committed with synchronous=FULL; Redis: acknowledged by the
// server). Failures throw StateError with a message that names the store and the problem.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace hdeform::service {

class StateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class StateBackend {
 public:
  virtual ~StateBackend() = default;

  // "sqlite DIR/state.sqlite3" or "redis 127.0.0.1:6379" (never a password): for logs.
  virtual std::string describe() const = 0;

  // ---- session records, by session id ([A-Za-z0-9_-]{1,64}) ----
  // `token_hashes` (32-byte SHA-256 each) are the tokens the record grants access to: the
  // token index (sessions_for) is written with the record, atomically, and replaced by
  // each put; deleting a record drops its entries.
  // Stores `record` only if `id` has none yet; false when it exists (someone owns the id).
  virtual bool create_session(const std::string& id, const std::string& record,
                              const std::vector<std::string>& token_hashes = {}) = 0;
  // Stores `record` for `id`, replacing any previous one.
  virtual void put_session(const std::string& id, const std::string& record,
                           const std::vector<std::string>& token_hashes = {}) = 0;
  // The ids whose latest record was stored with any of `token_hashes` (ListSessions: the
  // caller's sessions without reading anyone else's record). Any order, no repeats.
  virtual std::vector<std::string> sessions_for(const std::vector<std::string>& token_hashes) = 0;
  // Indexes an existing record under `token_hashes` (a record stored before the index
  // existed); nothing when `id` has no record.
  virtual void index_session(const std::string& id,
                             const std::vector<std::string>& token_hashes) = 0;
  virtual std::optional<std::string> get_session(const std::string& id) = 0;
  // Idempotent.
  virtual void delete_session(const std::string& id) = 0;
  // Deletes `id`'s record only if it is exactly `record` (atomically: a replica that wrote
  // a newer one in between keeps it). True when it deleted.
  virtual bool delete_session_if(const std::string& id, const std::string& record) = 0;
  // Every stored id (any order).
  virtual std::vector<std::string> list_sessions() = 0;

  // ---- a session's history, beside its record ----
  // Stores `history` for `id` only while `id` has a record (false, nothing stored, when it has
  // none); deleting the record deletes it too. The service writes it after the record, so a
  // history may be older than its record, never of a record deleted since.
  virtual bool put_history(const std::string& id, const std::string& history) = 0;
  virtual std::optional<std::string> get_history(const std::string& id) = 0;

  // ---- mesh files, content-addressed ----
  // Stores `bytes` once (a second put of the same bytes is a no-op) and returns its key:
  // 64 lower-case hex digits, the SHA-256 of the bytes.
  virtual std::string put_mesh(const std::string& bytes) = 0;
  // The bytes stored under `key`, verified against it (a corrupt file throws StateError);
  // nullopt when absent. `key` must be 64 hex digits (else StateError).
  virtual std::optional<std::string> get_mesh(const std::string& key) = 0;
  virtual bool has_mesh(const std::string& key) = 0;
  // ---- what the service derives from a mesh, by the engine mesh's hash (64 hex digits) ----
  // A cache beside the meshes (the solver's orderings: StoredOrderings): a put replaces, a
  // get of one never stored is nullopt. Dropped by purge_derived unless in `keep`.
  virtual void put_derived(const std::string& key, const std::string& bytes) = 0;
  virtual std::optional<std::string> get_derived(const std::string& key) = 0;
  virtual std::size_t purge_derived(const std::vector<std::string>& keep) = 0;
  // Counts the times the store was found to have lost everything written before (Redis
  // restarted without persistence: a new connection finds its marker key gone); 0 for a
  // store that cannot.
  virtual std::uint64_t generation() const { return 0; }
  // Drops every stored mesh whose key is not in `keep` (no session refers to it any more).
  // Returns how many were dropped.
  virtual std::size_t purge_meshes(const std::vector<std::string>& keep) = 0;
};

// DIR/state.sqlite3 (WAL mode, synchronous=FULL, application_id 'hdfm', schema version 2:
// version 1, without the history column and the token index, is upgraded in place)
// and DIR/meshes/KEY.mesh; DIR is created if missing. One server per folder: an exclusive
// lock on DIR/lock (StateError naming the folder when another process holds it). A file that
// is not an hdeform state database (another program's SQLite file, a corrupt one, a newer
// schema) throws StateError and is left untouched.
std::unique_ptr<StateBackend> open_sqlite_state(const std::filesystem::path& dir);

// redis://[:PASSWORD@]HOST[:PORT][/DB]. Keys under the prefix "hdeform:" (sessions as
// hdeform:session:ID, their histories as hdeform:history:ID, their ids in the set
// hdeform:sessions, the token index as sets hdeform:token:HASH (ids) and
// hdeform:session-tokens:ID (its hashes, hex), meshes as hdeform:mesh:KEY,
// and hdeform:marker, set once per dataset: its absence on a reconnection bumps generation()).
// Connects at once (StateError when the server cannot be reached), reconnects once per
// call after a broken connection; every command has a 2 s timeout.
std::unique_ptr<StateBackend> open_redis_state(const std::string& url);

// For a replica that may start before its Redis (--state-redis-wait): returns true once a
// connection to `url` is set up (AUTH, SELECT, PING), trying again while Redis cannot be
// reached (connecting fails, the connection breaks or times out, or Redis is still loading
// its dataset) for up to `wait`, with one log line at most every 2 s. Between attempts it
// calls pause(d), which sleeps up to d and returns false to give up (then this returns
// false). Throws StateError at once for any other problem (invalid URL, AUTH or SELECT
// refused), and when `wait` runs out, naming the host and the time waited.
bool wait_for_redis_state(const std::string& url, std::chrono::seconds wait,
                          const std::function<bool(std::chrono::milliseconds)>& pause);

}  // namespace hdeform::service

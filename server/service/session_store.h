// The registry of live sessions: limits, lookup by name, idle-TTL expiry.
#pragma once

#include "request_limits.h"
#include "session.h"

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
};

class SessionStore {
 public:
  SessionStore(const Limits& limits, WorkerPool& pool, Cache& cache);
  ~SessionStore();

  const Limits& limits() const { return limits_; }
  // RESOURCE_EXHAUSTED when no session can be added.
  void check_capacity() const;
  // `id` (the {id} of sessions/{id}): empty → the server picks one; else it must be
  // [A-Za-z0-9_-]{1,64} (INVALID_ARGUMENT) and free (ALREADY_EXISTS).
  // `init` (optional) runs on the new session before it is published: on a throw the
  // session is never reachable.
  std::shared_ptr<Session> create(std::shared_ptr<const MeshRef> mesh, const std::string& id = "",
                                  const std::function<void(Session&)>& init = {});
  // Early checks of a client-chosen id (format, and not taken right now); "" passes.
  void check_id(const std::string& id) const;
  // "sessions/{id}" or "{id}"; nullptr when unknown.
  std::shared_ptr<Session> find(const std::string& name) const;
  std::shared_ptr<Session> get(const std::string& name) const;  // NOT_FOUND
  bool remove(const std::string& name);
  std::vector<std::shared_ptr<Session>> list() const;
  std::size_t size() const;
  // A mesh some live session uses, by content hash (for snapshots without mesh bytes).
  std::shared_ptr<const MeshRef> find_mesh(const std::string& hash) const;

  // Removes sessions idle for longer than the TTL (observed or streaming sessions are
  // never idle). Returns how many expired.
  std::size_t expire_idle();
  void start_sweeper();
  // Stops the sweeper and closes every session (observers get `deleted`).
  void shutdown();

 private:
  static std::string id_of(const std::string& name);

  Limits limits_;
  WorkerPool& pool_;
  Cache& cache_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;  // by id

  std::mutex sweeper_mutex_;
  std::condition_variable sweeper_cv_;
  bool stopping_ = false;
  std::thread sweeper_;
};

}  // namespace hdeform::service

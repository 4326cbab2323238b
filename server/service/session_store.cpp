#include "session_store.h"

#include "errors.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace hdeform::service {

SessionStore::SessionStore(const Limits& limits, WorkerPool& pool, Cache& cache)
    : limits_(limits), pool_(pool), cache_(cache) {}

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
void check_id_format(const std::string& id) {
  if (id.size() > 64)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "session_id must be 1 to 64 characters of [A-Za-z0-9_-], got " +
             std::to_string(id.size()) + " characters");
  for (char c : id)
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
          c == '_' || c == '-'))
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           "session_id '" + id + "' may only contain [A-Za-z0-9_-] (at most 64 characters)");
}
}  // namespace

void SessionStore::check_id(const std::string& id) const {
  if (id.empty()) return;
  check_id_format(id);
  std::lock_guard lock(mutex_);
  if (sessions_.count(id))
    fail(grpc::StatusCode::ALREADY_EXISTS, "session sessions/" + id + " already exists");
}

std::shared_ptr<Session> SessionStore::create(std::shared_ptr<const MeshRef> mesh,
                                              const std::string& requested,
                                              const std::function<void(Session&)>& init) {
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
  auto s = std::make_shared<Session>(id, std::move(mesh), pool_, cache_, limits_.request);
  // Initialised before anyone can reach it (ImportSession's restore): no strand needed,
  // and a failed restore leaves nothing behind.
  if (init) init(*s);
  {
    std::lock_guard lock(mutex_);
    check_locked();  // the id or the last slot may have been taken meanwhile
    if (sessions_.count(id)) fail(grpc::StatusCode::ABORTED, "session id collision; retry");
    sessions_.emplace(id, s);
  }
  spdlog::info("{}: created on mesh {} ({}, {} vertices)", s->name(), s->mesh().display_name(),
               s->mesh().hash, s->mesh().layout->vertex_count());
  return s;
}

std::shared_ptr<Session> SessionStore::find(const std::string& name) const {
  std::lock_guard lock(mutex_);
  auto it = sessions_.find(id_of(name));
  if (it == sessions_.end()) return nullptr;
  it->second->touch();
  return it->second;
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
  s->close();
  spdlog::info("{}: deleted", s->name());
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

std::shared_ptr<const MeshRef> SessionStore::find_mesh(const std::string& hash) const {
  std::lock_guard lock(mutex_);
  for (auto& [id, s] : sessions_)
    if (s->mesh().hash == hash) return s->mesh_ref();
  return nullptr;
}

std::size_t SessionStore::expire_idle() {
  const auto now = std::chrono::steady_clock::now();
  std::vector<std::shared_ptr<Session>> expired;
  {
    std::lock_guard lock(mutex_);
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      auto& s = it->second;
      if (s->busy()) {
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
    s->close();
  }
  return expired.size();
}

void SessionStore::start_sweeper() {
  if (sweeper_.joinable()) return;
  const auto period = std::clamp<std::chrono::milliseconds>(
      limits_.session_ttl / 4, std::chrono::milliseconds(50), std::chrono::milliseconds(10'000));
  sweeper_ = std::thread([this, period] {
    std::unique_lock lock(sweeper_mutex_);
    while (!stopping_) {
      sweeper_cv_.wait_for(lock, period, [this] { return stopping_; });
      if (stopping_) break;
      lock.unlock();
      try {
        expire_idle();
      } catch (const std::exception& e) {
        spdlog::error("session sweeper: {}", e.what());
      }
      lock.lock();
    }
  });
}

void SessionStore::shutdown() {
  {
    std::lock_guard lock(sweeper_mutex_);
    stopping_ = true;
  }
  sweeper_cv_.notify_all();
  if (sweeper_.joinable()) sweeper_.join();
  std::map<std::string, std::shared_ptr<Session>> all;
  {
    std::lock_guard lock(mutex_);
    all.swap(sessions_);
  }
  for (auto& [id, s] : all) s->close();
}

}  // namespace hdeform::service

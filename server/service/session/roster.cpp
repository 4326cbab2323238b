#include "service/session/roster.h"

#include "service/infra/service_error.h"

#include <algorithm>
#include <cstdio>
#include <functional>

namespace hdeform::service {

namespace {

constexpr std::size_t kMaxClientId = 64, kMaxNameChars = 64, kMaxSeenNames = 256;

// Colours for clients that name none: distinct on a grey mesh, picked by client id.
constexpr const char* kPalette[] = {"#e6194b", "#3cb44b", "#4363d8", "#f58231",
                                    "#911eb4", "#42d4f4", "#f032e6", "#9a6324"};

bool valid_id_char(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
         c == '_' || c == '-';
}

bool valid_color(const std::string& c) {
  if (c.size() != 7 || c[0] != '#') return false;
  return std::all_of(c.begin() + 1, c.end(), [](char h) {
    return (h >= '0' && h <= '9') || (h >= 'a' && h <= 'f') || (h >= 'A' && h <= 'F');
  });
}

std::string seconds(Roster::Clock::duration d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f s",
                std::max(0.0, std::chrono::duration<double>(d).count()));
  return buf;
}

}  // namespace

void Roster::check_participant(const pb::Participant& who, const char* op) {
  const std::string& id = who.client_id();
  const std::string prefix = std::string(op) + ": client.";
  if (id.empty() || id.size() > kMaxClientId || !std::all_of(id.begin(), id.end(), valid_id_char))
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         prefix + "client_id must be 1–64 characters of [A-Za-z0-9_-]");
  // Protobuf has checked UTF-8; count code points (bytes that do not continue one).
  const auto& name = who.display_name();
  const auto chars = std::count_if(name.begin(), name.end(), [](char c) {
    return (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  });
  if (static_cast<std::size_t>(chars) > kMaxNameChars)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         prefix + "display_name has " + std::to_string(chars) + " characters, at most " +
             std::to_string(kMaxNameChars));
  if (std::any_of(name.begin(), name.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return u < 0x20 || u == 0x7f;
      }))
    fail(grpc::StatusCode::INVALID_ARGUMENT, prefix + "display_name has control characters");
  if (!who.color().empty() && !valid_color(who.color()))
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         prefix + "color must be \"#rrggbb\", got \"" + who.color().substr(0, 16) + "\"");
}

Roster::Member& Roster::member_locked(const pb::Participant& who, bool editor) {
  auto it = members_.find(who.client_id());
  if (it == members_.end()) {
    if (members_.size() >= limits_.max_participants)
      fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
           "the session has " + std::to_string(members_.size()) +
               " participants, the limit (--max-watchers)");
    it = members_.emplace(who.client_id(), Member{}).first;
    it->second.editor = editor;
    it->second.claim = next_claim_++;
  } else if (it->second.editor != editor) {
    if (!editor)
      fail(grpc::StatusCode::ALREADY_EXISTS,
           "client_id '" + who.client_id() +
               "' belongs to an editor of this session; a view token cannot take it (choose "
               "another client_id)");
    // An edit claim wins over a view one: a fresh binding, which the viewer's streams (and
    // their leave) no longer touch.
    for (const auto& [handle, lease] : it->second.held) holder_.erase(handle);
    it->second = Member{};
    it->second.editor = true;
    it->second.claim = next_claim_++;
  }
  Member& m = it->second;
  m.name = who.display_name().empty() ? "anonymous" : who.display_name();
  if (seen_names_.size() >= kMaxSeenNames) seen_names_.clear();  // bounded; names only
  seen_names_[who.client_id()] = m.name;
  m.color = !who.color().empty()
                ? who.color()
                : kPalette[std::hash<std::string>{}(who.client_id()) % std::size(kPalette)];
  return m;
}

void Roster::prune_locked(const std::string& client_id) {
  auto it = members_.find(client_id);
  if (it != members_.end() && it->second.streams == 0 && it->second.held.empty())
    members_.erase(it);
}

Roster::Claim Roster::join(const pb::Participant& who, bool editor) {
  std::lock_guard lock(mutex_);
  Member& m = member_locked(who, editor);
  ++m.streams;
  return m.claim;
}

Roster::Left Roster::leave(const std::string& client_id, Claim claim) {
  std::lock_guard lock(mutex_);
  auto it = members_.find(client_id);
  if (it == members_.end()) return Left::kAbsent;
  if (it->second.claim != claim) return Left::kDisplaced;
  if (--it->second.streams > 0) return Left::kChanged;  // another tab of the same client
  for (const auto& [handle, lease] : it->second.held) holder_.erase(handle);
  it->second.held.clear();
  members_.erase(it);
  return Left::kChanged;
}

const std::pair<const std::string, Roster::Member>* Roster::other_holder_locked(
    int handle, const std::string& client_id, Clock::time_point now) const {
  auto h = holder_.find(handle);
  if (h == holder_.end() || h->second == client_id) return nullptr;
  auto m = members_.find(h->second);
  if (m == members_.end()) return nullptr;
  auto lease = m->second.held.find(handle);
  if (lease == m->second.held.end() || lease->second.first <= now) return nullptr;  // ran out
  return &*m;
}

void Roster::refuse_locked(int handle, const std::pair<const std::string, Member>& holder,
                           Clock::time_point now, const char* what) const {
  const auto until = holder.second.held.at(handle).first;
  fail(grpc::StatusCode::ABORTED,
       std::string(what) + ": handle " + std::to_string(handle) + " is held by " +
           holder.second.name + " (client " + holder.first + ") for " + seconds(until - now) +
           " more unless renewed; wait until it is released");
}

Roster::Clock::time_point Roster::grab(const pb::Participant& who, bool editor,
                                       const std::vector<int>& handles,
                                       std::chrono::milliseconds lease, Clock::time_point now) {
  if (lease.count() < 0 || lease > limits_.max_lease)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "GrabHandles: lease_ms must be 0 (default " +
             std::to_string(limits_.default_lease.count()) + ") to " +
             std::to_string(limits_.max_lease.count()) + " (--max-lease-ms), got " +
             std::to_string(lease.count()));
  if (lease.count() == 0) lease = limits_.default_lease;
  std::lock_guard lock(mutex_);
  for (int h : handles)
    if (const auto* other = other_holder_locked(h, who.client_id(), now))
      refuse_locked(h, *other, now, "GrabHandles");
  Member& m = member_locked(who, editor);
  const auto until = now + lease;
  for (int h : handles) {
    auto prev = holder_.find(h);
    if (prev != holder_.end() && prev->second != who.client_id()) {  // an expired lease
      const std::string old = prev->second;
      members_[old].held.erase(h);
      prune_locked(old);
    }
    holder_[h] = who.client_id();
    m.held[h] = {until, lease};
  }
  return until;
}

bool Roster::release(const std::string& client_id, const std::vector<int>& handles) {
  std::lock_guard lock(mutex_);
  auto it = members_.find(client_id);
  if (it == members_.end()) return false;
  std::vector<int> which = handles;
  if (which.empty())
    for (const auto& [h, lease] : it->second.held) which.push_back(h);
  bool any = false;
  for (int h : which)
    if (it->second.held.erase(h) > 0) {
      holder_.erase(h);
      any = true;
    }
  prune_locked(client_id);
  return any;
}

void Roster::check_move(const std::string& client_id, const std::vector<int>& handles,
                        Clock::time_point now) {
  std::lock_guard lock(mutex_);
  for (int h : handles)
    if (const auto* other = other_holder_locked(h, client_id, now))
      refuse_locked(h, *other, now, "update");
  if (client_id.empty()) return;
  auto it = members_.find(client_id);
  if (it == members_.end()) return;
  for (int h : handles) {
    auto lease = it->second.held.find(h);
    if (lease != it->second.held.end()) lease->second.first = now + lease->second.second;
  }
}

bool Roster::expire(Clock::time_point now) {
  std::lock_guard lock(mutex_);
  std::vector<std::string> touched;
  for (auto& [id, m] : members_)
    for (auto it = m.held.begin(); it != m.held.end();) {
      if (it->second.first <= now) {
        holder_.erase(it->first);
        it = m.held.erase(it);
        touched.push_back(id);
      } else {
        ++it;
      }
    }
  for (const auto& id : touched) prune_locked(id);
  return !touched.empty();
}

bool Roster::release_all() {
  std::lock_guard lock(mutex_);
  if (holder_.empty()) return false;
  holder_.clear();
  std::vector<std::string> ids;
  for (auto& [id, m] : members_) {
    m.held.clear();
    ids.push_back(id);
  }
  for (const auto& id : ids) prune_locked(id);
  return true;
}

void Roster::describe(pb::Presence* out) const {
  std::lock_guard lock(mutex_);
  for (const auto& [id, m] : members_) {
    auto* p = out->add_participants();
    p->set_client_id(id);
    p->set_display_name(m.name);
    p->set_color(m.color);
    p->set_editor(m.editor);
    p->set_watching(m.streams > 0);
    for (const auto& [h, lease] : m.held) p->add_held_handles(h);
  }
}

std::string Roster::name_of(const std::string& client_id) const {
  std::lock_guard lock(mutex_);
  if (auto it = members_.find(client_id); it != members_.end()) return it->second.name;
  auto seen = seen_names_.find(client_id);
  return seen == seen_names_.end() ? "anonymous" : seen->second;
}

bool Roster::empty() const {
  std::lock_guard lock(mutex_);
  return members_.empty();
}

}  // namespace hdeform::service

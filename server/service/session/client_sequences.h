// The newest UpdateHandles each client has had applied to a session (docs/api.md "Pipelined
// updates"). A client's pipelined updates are concurrent calls and may reach the server in
// either order; an older one arriving after a newer one must not undo its move.
// Not thread-safe: the session guards it with its mutex. Bounded: it forgets the least
// recently applied client beyond kMaxClients (client ids are self-chosen strings).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>

namespace hdeform::service {

class ClientSequences {
 public:
  static constexpr std::size_t kMaxClients = 256;
  struct Applied {
    std::int64_t sequence = 0;  // UpdateHandlesRequest.sequence
    bool dragging = false;      // it left a drag in progress
  };
  // client_id's last applied update; none for an anonymous (empty) or unknown client.
  std::optional<Applied> last(const std::string& client_id) const;
  // An update of client_id had its moves committed (an anonymous client is not recorded).
  // Its sequence replaces the last one even when lower: a client that restarts counts anew
  // with a non-coalescing update (only coalescing updates are checked against `last`).
  void applied(const std::string& client_id, Applied a);
  std::size_t size() const { return by_client_.size(); }

 private:
  struct Entry {
    Applied applied;
    std::uint64_t tick = 0;  // when, in applied() calls (least recent is forgotten first)
  };
  std::unordered_map<std::string, Entry> by_client_;
  std::uint64_t tick_ = 0;
};

}  // namespace hdeform::service

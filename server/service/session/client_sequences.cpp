#include "service/session/client_sequences.h"

#include <algorithm>

namespace hdeform::service {

std::optional<ClientSequences::Applied> ClientSequences::last(const std::string& client_id) const {
  if (client_id.empty()) return std::nullopt;
  const auto it = by_client_.find(client_id);
  if (it == by_client_.end()) return std::nullopt;
  return it->second.applied;
}

void ClientSequences::applied(const std::string& client_id, Applied a) {
  if (client_id.empty()) return;
  auto [it, inserted] = by_client_.try_emplace(client_id);
  it->second = Entry{a, ++tick_};
  if (inserted && by_client_.size() > kMaxClients) {
    // O(kMaxClients), only when a new client pushes the table over its bound.
    const auto oldest = std::min_element(by_client_.begin(), by_client_.end(),
                                         [](const auto& x, const auto& y) {
                                           return x.second.tick < y.second.tick;
                                         });
    by_client_.erase(oldest);
  }
}

}  // namespace hdeform::service

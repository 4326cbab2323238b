// A session's history in its stored form (stored_session.proto, StoredHistory), so Undo and
// Redo keep working after a restart or on another replica. Not thread-safe: the session
// calls these under its own mutex.
#pragma once

#include "service/session/history.h"
#include "stored_session.pb.h"

#include <functional>
#include <map>
#include <memory>
#include <string>

namespace hdeform::service {

inline constexpr std::uint32_t kHistoryFormat = 1;

hdeform::state::StoredHistory history_to_record(const History& history);

// What the stored steps are read against: the session as restored. Values equal to the
// session's current ones (its constraints, timeline, named snapshots) become the very same
// objects, since History compares timelines and snapshots by identity ("unchanged since").
struct HistoryContext {
  EditState current;
  std::map<std::string, std::shared_ptr<const pb::NamedSnapshot>> snapshots;
  // The stored β (with local entries) as the session holds it; throws for one it refuses.
  std::function<SessionBeta(const pb::Beta&)> parse_beta;
};

// Replaces `history` by the stored one. Throws (std::runtime_error, or the InvalidInput of
// a transform or β the session refuses) naming what is wrong: an unknown format, a reference
// out of range, constraints without their transforms; the history is then left as it was.
void history_from_record(const hdeform::state::StoredHistory& record, const HistoryContext& context,
                         History& history);

}  // namespace hdeform::service

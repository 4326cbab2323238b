// A Session → its durable record (stored_session.proto), for SessionStore; reading one back
// is stored_record.h.
#pragma once

#include "service/session/session.h"
#include "service/state/stored_record.h"

#include <cstdint>
#include <string>

namespace hdeform::service {

// The record of `session` now; `*version` is the version it shows. With `pending`, the record
// of the move about to be committed: its transforms, β and version in place of the session's.
hdeform::state::StoredSession make_record(const Session& session, const std::string& mesh_key,
                                          std::int64_t last_used_unix_ms, std::int64_t* version,
                                          const Session::PendingPose* pending = nullptr);

}  // namespace hdeform::service

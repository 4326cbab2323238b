// A Session ⇄ its durable record (stored_session.proto), for SessionStore.
#pragma once

#include "session.h"
#include "stored_session.pb.h"

#include <cstdint>
#include <string>

namespace hdeform::service {

inline constexpr std::uint32_t kRecordFormat = 1;

// The record of `session` now; `*version` is the version it shows.
hdeform::state::StoredSession make_record(const Session& session, const std::string& mesh_key,
                                          std::int64_t last_used_unix_ms, std::int64_t* version);

// Parses and checks a stored record (StateError naming the id and the problem: not a record,
// an unknown format, another id, token hashes of the wrong size).
hdeform::state::StoredSession parse_record(const std::string& id, const std::string& bytes);

SessionTokens tokens_of(const hdeform::state::StoredSession& record);

}  // namespace hdeform::service

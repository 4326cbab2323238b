// How `hdeform sessions` shows sessions: a table row, a detail page and a JSON object (the
// same fields for `list --json` and `get --json`, plain numbers, for scripts).
#pragma once

#include "common.h"

#include <nlohmann/json.hpp>

#include <ostream>
#include <string>
#include <vector>

namespace hdeform::cli {

// "2026-12-02T07:43:08Z" (UTC, seconds); "-" for 0.
std::string utc_time(std::int64_t unix_ms);

// The `sessions list` table: a header and one row per session.
std::vector<std::vector<std::string>> session_table(const std::vector<pb::Session>& sessions);
// `sessions get`: "key: value" lines.
void print_session(std::ostream& out, const pb::Session& s);
// name, mesh, mesh_hash, vertices, triangles, version, config_version, constrained, fixed,
// handles, beta {value, units, automatic, local}, transforms (protobuf JSON), observers,
// created/updated (ISO 8601 UTC). Never the tokens.
nlohmann::json session_json(const pb::Session& s);

}  // namespace hdeform::cli

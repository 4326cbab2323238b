// The two kinds of key the durable state uses (docs/api.md "Sessions", "Durable state").
// Both become Redis keys and SQLite rows, and mesh keys become file names, so each backend and
// the session store check them with these same rules.
#pragma once

#include <string_view>

namespace hdeform::service {

// A session id: 1 to 64 characters of [A-Za-z0-9_-].
inline bool is_session_id_char(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
         c == '_' || c == '-';
}
inline bool is_session_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id)
    if (!is_session_id_char(c)) return false;
  return true;
}

// A stored mesh's key: exactly the lower-case hex SHA-256 of its bytes (64 characters), so no
// path trick can pass as one.
inline bool is_mesh_key(std::string_view key) {
  if (key.size() != 64) return false;
  for (char c : key)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

}  // namespace hdeform::service

// Capability tokens (docs/api.md "Access"): each session has an edit token and a view token,
// 256 random bits each from the OS CSPRNG, of which the server keeps only the SHA-256.
// Presented tokens are hashed and compared in constant time. An operator token
// (--admin-token) opens every session.
#pragma once

#include <grpcpp/grpcpp.h>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hdeform::service {

using TokenHash = std::array<std::uint8_t, 32>;  // SHA-256

enum class Access { kNone = 0, kView = 1, kEdit = 2 };
const char* access_name(Access a);  // "view" / "edit"

struct IssuedTokens {
  std::string edit, view;  // plain text: returned to the creator once, never stored
};

struct SessionTokens {
  TokenHash edit{}, view{};
  bool set = false;  // false: no token opens the session (never issued)

  // Fresh tokens; `*this` keeps their hashes.
  IssuedTokens issue();
  // What `token_hashes` (the hashes of the presented tokens) grant.
  Access grant(const std::vector<TokenHash>& token_hashes) const;
};

TokenHash hash_token(const std::string& token);

// A fresh token: 256 bits from the OS CSPRNG as 64 hex digits (`hdeform-server --gen-token`).
std::string new_token();

// Empty if `token` may be the operator token, else why not. It opens every session, so it
// must carry ≥ 128 bits that a guess cannot find: ≥ 32 characters, printable ASCII without
// spaces or commas (a comma splits an Authorization value), ≥ 8 distinct symbols (sixteen
// "a", or "abab…", are refused). 32 hex digits pass, as does anything --gen-token prints.
std::string operator_token_problem(std::string_view token);
bool same_hash(const TokenHash& a, const TokenHash& b);  // constant time

// The tokens a call presents: every `authorization` metadata entry, "Bearer " removed, each
// value also split at commas (HTTP proxies may join repeated headers). At most 64 are
// considered; each at most 256 characters.
std::vector<std::string> presented_tokens(const grpc::ServerContextBase& ctx);
// One `authorization` value's tokens, appended to `out` (the same rules and bounds).
void parse_authorization(std::string_view value, std::vector<std::string>& out);
std::vector<TokenHash> presented_token_hashes(const grpc::ServerContextBase& ctx);

}  // namespace hdeform::service

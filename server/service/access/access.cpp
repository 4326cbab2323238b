#include "service/access/access.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include <cctype>
#include <stdexcept>
#include <string_view>
#include <utility>

namespace hdeform::service {

namespace {
constexpr std::size_t kTokenBytes = 32;
constexpr std::size_t kMaxTokens = 64, kMaxTokenChars = 256;

std::string random_hex_token() {
  unsigned char raw[kTokenBytes];
  if (RAND_bytes(raw, sizeof raw) != 1) throw std::runtime_error("RAND_bytes failed");
  static const char* kHex = "0123456789abcdef";
  std::string out;
  out.reserve(2 * kTokenBytes);
  for (unsigned char c : raw) {
    out += kHex[c >> 4];
    out += kHex[c & 15];
  }
  return out;
}

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

bool starts_with_bearer(std::string_view s) {
  static constexpr std::string_view kBearer = "bearer ";
  if (s.size() < kBearer.size()) return false;
  for (std::size_t i = 0; i < kBearer.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[i])) != kBearer[i]) return false;
  return true;
}
}  // namespace

const char* access_name(Access a) {
  switch (a) {
    case Access::kEdit: return "edit";
    case Access::kView: return "view";
    default: return "no";
  }
}

std::string new_token() { return random_hex_token(); }

std::string operator_token_problem(std::string_view token) {
  constexpr std::size_t kMinChars = 32, kMinSymbols = 8;
  for (const char ch : token) {
    const auto c = static_cast<unsigned char>(ch);
    if (c <= 0x20 || c >= 0x7F || c == ',') {
      return "the operator token may hold only printable ASCII without spaces or commas";
    }
  }
  if (token.size() < kMinChars) {
    return "the operator token is " + std::to_string(token.size()) + " characters; it needs at least " +
           std::to_string(kMinChars) + " (hdeform-server --gen-token prints a good one)";
  }
  bool seen[128] = {};
  std::size_t symbols = 0;
  for (const char ch : token) symbols += !std::exchange(seen[static_cast<unsigned char>(ch)], true);
  if (symbols < kMinSymbols) {
    return "the operator token uses " + std::to_string(symbols) + " distinct characters; it needs " +
           "at least " + std::to_string(kMinSymbols) + " (hdeform-server --gen-token prints a good one)";
  }
  return {};
}

TokenHash hash_token(const std::string& token) {
  TokenHash h{};
  unsigned int n = 0;
  if (EVP_Digest(token.data(), token.size(), h.data(), &n, EVP_sha256(), nullptr) != 1 ||
      n != h.size())
    throw std::runtime_error("SHA-256 failed");
  return h;
}

bool same_hash(const TokenHash& a, const TokenHash& b) {
  return CRYPTO_memcmp(a.data(), b.data(), a.size()) == 0;
}

IssuedTokens SessionTokens::issue() {
  IssuedTokens t{random_hex_token(), random_hex_token()};
  edit = hash_token(t.edit);
  view = hash_token(t.view);
  set = true;
  return t;
}

Access SessionTokens::grant(const std::vector<TokenHash>& token_hashes) const {
  if (!set) return Access::kNone;
  Access best = Access::kNone;
  for (const auto& h : token_hashes) {
    // Both comparisons always run: the time taken does not tell which one matched.
    const bool e = same_hash(h, edit), v = same_hash(h, view);
    if (e) best = Access::kEdit;
    else if (v && best == Access::kNone) best = Access::kView;
  }
  return best;
}

void parse_authorization(std::string_view value, std::vector<std::string>& out) {
  while (!value.empty() && out.size() < kMaxTokens) {
    const auto comma = value.find(',');
    std::string part = trim(value.substr(0, comma));
    value = comma == std::string_view::npos ? std::string_view{} : value.substr(comma + 1);
    if (starts_with_bearer(part)) part = trim(std::string_view(part).substr(7));
    if (!part.empty() && part.size() <= kMaxTokenChars) out.push_back(std::move(part));
  }
}

std::vector<std::string> presented_tokens(const grpc::ServerContextBase& ctx) {
  std::vector<std::string> out;
  const auto& md = ctx.client_metadata();
  auto range = md.equal_range("authorization");
  for (auto it = range.first; it != range.second && out.size() < kMaxTokens; ++it)
    parse_authorization(std::string_view(it->second.data(), it->second.size()), out);
  return out;
}

std::vector<TokenHash> presented_token_hashes(const grpc::ServerContextBase& ctx) {
  std::vector<TokenHash> out;
  for (const auto& t : presented_tokens(ctx)) out.push_back(hash_token(t));
  return out;
}

}  // namespace hdeform::service

// libFuzzer target for the `authorization` header parser (server/service/access/access.h): any
// bytes a client sends. At most 64 tokens, each 1–256 characters, none with the "Bearer "
// prefix or surrounding blanks left on.
#include "service/access/access.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> tokens;
  hdeform::service::parse_authorization(
      std::string_view(reinterpret_cast<const char*>(data), size), tokens);
  if (tokens.size() > 64) __builtin_trap();
  for (const auto& t : tokens) {
    if (t.empty() || t.size() > 256) __builtin_trap();
    if (t.front() == ' ' || t.back() == ' ' || t.find(',') != std::string::npos) __builtin_trap();
    hdeform::service::hash_token(t);
  }
  return 0;
}

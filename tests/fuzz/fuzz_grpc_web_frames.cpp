// libFuzzer target for the gRPC-Web wire helpers (server/gateway/grpc_web.h): parse_frames
// on the whole input — every message must be a view inside the body, and a body without an
// error must be covered exactly by its frames — and parse_timeout on the input and on its
// first line (a grpc-timeout header value).
#include "gateway/grpc_web.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace gw = hdeform::gateway::grpc_web;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view body(reinterpret_cast<const char*>(data), size);
  const gw::ParsedBody parsed = gw::parse_frames(body);
  std::size_t covered = 0;
  for (const std::string_view m : parsed.messages) {
    if (m.data() < body.data() || m.data() + m.size() > body.data() + body.size()) __builtin_trap();
    covered += m.size() + 5;
  }
  if (parsed.error.empty() && covered > body.size()) __builtin_trap();

  const auto t = gw::parse_timeout(body);
  if (t && t->count() < 0) __builtin_trap();
  const std::string_view first = body.substr(0, body.find('\n'));
  const auto t1 = gw::parse_timeout(first);
  if (t1 && t1->count() < 0) __builtin_trap();
  return 0;
}

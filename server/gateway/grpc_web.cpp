#include "gateway/grpc_web.h"

#include <array>

namespace hdeform::gateway::grpc_web {

std::array<char, 5> frame_prefix(std::uint8_t flag, std::uint32_t length) {
  return {static_cast<char>(flag), static_cast<char>((length >> 24) & 0xFF),
          static_cast<char>((length >> 16) & 0xFF), static_cast<char>((length >> 8) & 0xFF),
          static_cast<char>(length & 0xFF)};
}

ParsedBody parse_frames(std::string_view body) {
  // Every length is checked against the bytes present before use, and nothing is allocated
  // from a length: a prefix claiming 4 GiB in a short body is "truncated", not an allocation.
  ParsedBody out;
  std::size_t at = 0;
  while (at < body.size()) {
    if (body.size() - at < 5) {
      out.error = "truncated gRPC-Web frame header";
      return out;
    }
    const auto flag = static_cast<std::uint8_t>(body[at]);
    const std::uint32_t length = (std::uint32_t(std::uint8_t(body[at + 1])) << 24) |
                                 (std::uint32_t(std::uint8_t(body[at + 2])) << 16) |
                                 (std::uint32_t(std::uint8_t(body[at + 3])) << 8) |
                                 std::uint32_t(std::uint8_t(body[at + 4]));
    at += 5;
    if (body.size() - at < length) {
      out.error = "truncated gRPC-Web frame";
      return out;
    }
    if (flag & kCompressedBit) {
      out.error = "compressed gRPC-Web frames are not supported";
      return out;
    }
    if (!(flag & kTrailerFlag)) out.messages.push_back(body.substr(at, length));
    at += length;
  }
  return out;
}

std::string percent_encode(std::string_view text) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c > 0x7E || c == '%') {
      out += '%';
      out += kHex[c >> 4];
      out += kHex[c & 0xF];
    } else {
      out += ch;
    }
  }
  return out;
}

std::string trailers_frame(const grpc::Status& status) {
  std::string text = "grpc-status:" + std::to_string(static_cast<int>(status.error_code())) +
                     "\r\ngrpc-message:" + percent_encode(status.error_message()) + "\r\n";
  const auto prefix = frame_prefix(kTrailerFlag, static_cast<std::uint32_t>(text.size()));
  return std::string(prefix.data(), prefix.size()) + text;
}

std::optional<std::chrono::nanoseconds> parse_timeout(std::string_view value) {
  // At most 8 digits and a unit (PROTOCOL-HTTP2.md), so n < 10^8 and the arithmetic below
  // cannot overflow; "99999999H" would still overflow nanoseconds (and `now() + timeout`),
  // so every value is clamped to kMaxTimeout first.
  if (value.size() < 2 || value.size() > 9) return std::nullopt;
  std::int64_t n = 0;
  for (std::size_t i = 0; i + 1 < value.size(); ++i) {
    if (value[i] < '0' || value[i] > '9') return std::nullopt;
    n = n * 10 + (value[i] - '0');
  }
  using namespace std::chrono;
  std::int64_t nanos_per_unit = 0;
  switch (value.back()) {
    case 'H': nanos_per_unit = 3'600'000'000'000; break;
    case 'M': nanos_per_unit = 60'000'000'000; break;
    case 'S': nanos_per_unit = 1'000'000'000; break;
    case 'm': nanos_per_unit = 1'000'000; break;
    case 'u': nanos_per_unit = 1'000; break;
    case 'n': nanos_per_unit = 1; break;
    default: return std::nullopt;
  }
  const auto max_units = duration_cast<nanoseconds>(kMaxTimeout).count() / nanos_per_unit;
  return n > max_units ? duration_cast<nanoseconds>(kMaxTimeout) : nanoseconds(n * nanos_per_unit);
}

int http_status_for(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return 200;
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::OUT_OF_RANGE: return 400;
    case grpc::StatusCode::UNAUTHENTICATED: return 401;
    case grpc::StatusCode::PERMISSION_DENIED: return 403;
    case grpc::StatusCode::NOT_FOUND: return 404;
    case grpc::StatusCode::ALREADY_EXISTS:
    case grpc::StatusCode::ABORTED: return 409;
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return 413;
    case grpc::StatusCode::UNIMPLEMENTED: return 501;
    case grpc::StatusCode::UNAVAILABLE: return 503;
    case grpc::StatusCode::DEADLINE_EXCEEDED: return 504;
    case grpc::StatusCode::CANCELLED: return 499;
    default: return 500;
  }
}

}  // namespace hdeform::gateway::grpc_web

// gRPC-Web wire helpers (https://github.com/grpc/grpc/blob/master/doc/PROTOCOL-WEB.md):
// a body is a sequence of frames, each a 1-byte flag (0x00 data, 0x80 trailers, bit 0x01 =
// compressed) and a 4-byte big-endian length, then that many bytes.
#pragma once

#include <grpcpp/grpcpp.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hdeform::gateway::grpc_web {

inline constexpr std::uint8_t kDataFlag = 0x00;
inline constexpr std::uint8_t kTrailerFlag = 0x80;
inline constexpr std::uint8_t kCompressedBit = 0x01;

// The 5-byte prefix of a frame.
std::array<char, 5> frame_prefix(std::uint8_t flag, std::uint32_t length);

struct ParsedBody {
  std::vector<std::string_view> messages;  // views into the body
  std::string error;                       // non-empty: malformed
};
// Splits a request body into its data frames (trailer frames from the client are ignored).
// Pure and total: any input gives either the messages or an error (truncated frame, frame
// header or compressed frame), never an allocation larger than O(body.size()).
ParsedBody parse_frames(std::string_view body);

// A whole trailers frame: grpc-status / grpc-message (percent-encoded).
std::string trailers_frame(const grpc::Status& status);

// Percent-encoding of grpc-message (PROTOCOL-HTTP2.md: bytes outside 0x20–0x7E and '%').
std::string percent_encode(std::string_view text);

// Longest deadline a grpc-timeout may set (so that now() + timeout cannot overflow).
inline constexpr std::chrono::hours kMaxTimeout{24 * 365 * 10};

// grpc-timeout header ("100m", "5S", …: 1–8 digits and a unit) → duration, clamped to
// kMaxTimeout; nullopt when absent or malformed. Pure and total, like parse_frames.
std::optional<std::chrono::nanoseconds> parse_timeout(std::string_view value);

// HTTP status for a gRPC status, for the plain-HTTP endpoints (/upload).
int http_status_for(grpc::StatusCode code);

}  // namespace hdeform::gateway::grpc_web

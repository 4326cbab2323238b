// grpc_web's pure helpers on hostile input: frame lengths near 4 GiB, truncated frames and
// frame headers, compressed frames, and grpc-timeout values that would overflow. Each must
// give an error (or a clamped value), never a crash, UB or an allocation from a length.
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <string>

#include "gateway/grpc_web.h"

namespace {

namespace gw = hdeform::gateway::grpc_web;
using namespace std::chrono_literals;

std::string frame(std::uint8_t flag, std::uint32_t length, std::string_view payload) {
  const auto prefix = gw::frame_prefix(flag, length);
  return std::string(prefix.data(), prefix.size()) + std::string(payload);
}

TEST(GrpcWebFrames, WellFormedBodies) {
  EXPECT_TRUE(gw::parse_frames("").messages.empty());
  EXPECT_TRUE(gw::parse_frames("").error.empty());
  const auto body = frame(0, 3, "abc") + frame(0, 0, "") + frame(0x80, 2, "xy");
  const auto parsed = gw::parse_frames(body);
  EXPECT_TRUE(parsed.error.empty()) << parsed.error;
  ASSERT_EQ(parsed.messages.size(), 2u);  // the client's trailer frame is ignored
  EXPECT_EQ(parsed.messages[0], "abc");
  EXPECT_EQ(parsed.messages[1], "");
}

TEST(GrpcWebFrames, LengthNear4GiBIsTruncatedNotAllocated) {
  for (const std::uint32_t length : {0xFFFFFFFFu, 0xFFFFFFFBu, 0x80000000u, 6u}) {
    const auto parsed = gw::parse_frames(frame(0, length, "hello"));
    EXPECT_EQ(parsed.error, "truncated gRPC-Web frame") << length;
    EXPECT_TRUE(parsed.messages.empty());
  }
  // After a good frame too.
  const auto parsed = gw::parse_frames(frame(0, 1, "a") + frame(0, 0xFFFFFFFFu, ""));
  EXPECT_EQ(parsed.error, "truncated gRPC-Web frame");
}

TEST(GrpcWebFrames, TruncatedFrameHeaders) {
  for (std::size_t n = 1; n < 5; ++n) {
    const auto parsed = gw::parse_frames(std::string(n, '\0'));
    EXPECT_EQ(parsed.error, "truncated gRPC-Web frame header") << n;
  }
  EXPECT_EQ(gw::parse_frames(frame(0, 1, "a") + std::string(3, '\xFF')).error,
            "truncated gRPC-Web frame header");
}

TEST(GrpcWebFrames, CompressedFramesAreRefused) {
  for (const std::uint8_t flag : {0x01, 0x81, 0xFF}) {
    EXPECT_EQ(gw::parse_frames(frame(flag, 2, "zz")).error,
              "compressed gRPC-Web frames are not supported")
        << int(flag);
  }
}

TEST(GrpcWebFrames, EveryByteOfEveryShortBodyIsSafe) {
  // All bodies of up to 6 bytes over interesting bytes: no crash, views stay in the body.
  const std::string alphabet("\x00\x01\x80\x81\xFF\x05", 6);
  std::string body;
  std::function<void(std::size_t)> walk = [&](std::size_t depth) {
    const auto parsed = gw::parse_frames(body);
    for (const auto m : parsed.messages) {
      EXPECT_GE(m.data(), body.data());
      EXPECT_LE(m.data() + m.size(), body.data() + body.size());
    }
    if (depth == 6) return;
    for (const char c : alphabet) {
      body.push_back(c);
      walk(depth + 1);
      body.pop_back();
    }
  };
  walk(0);
}

TEST(GrpcWebTimeout, ParsesUnits) {
  EXPECT_EQ(gw::parse_timeout("100m"), std::chrono::nanoseconds(100ms));
  EXPECT_EQ(gw::parse_timeout("5S"), std::chrono::nanoseconds(5s));
  EXPECT_EQ(gw::parse_timeout("2M"), std::chrono::nanoseconds(2min));
  EXPECT_EQ(gw::parse_timeout("1H"), std::chrono::nanoseconds(1h));
  EXPECT_EQ(gw::parse_timeout("7u"), std::chrono::nanoseconds(7us));
  EXPECT_EQ(gw::parse_timeout("99999999n"), std::chrono::nanoseconds(99999999));
}

TEST(GrpcWebTimeout, MalformedValuesAreIgnored) {
  for (const char* v : {"", "S", "5", "5s", "5x", "-5S", "+5S", " 5S", "5 S", "123456789S",
                        "1e3S", "0x1S", "\xd9\xa3S"}) {
    EXPECT_FALSE(gw::parse_timeout(v).has_value()) << v;
  }
}

TEST(GrpcWebTimeout, HugeValuesAreClampedNotOverflowed) {
  const auto max = std::chrono::duration_cast<std::chrono::nanoseconds>(gw::kMaxTimeout);
  EXPECT_EQ(gw::parse_timeout("99999999H"), max);
  EXPECT_EQ(gw::parse_timeout("99999999M"), max);
  EXPECT_EQ(gw::parse_timeout("99999999S"), std::chrono::nanoseconds(99999999s));
  // The clamped value can be added to the clock without overflow.
  const auto deadline = std::chrono::system_clock::now() + *gw::parse_timeout("99999999H");
  EXPECT_GT(deadline, std::chrono::system_clock::now());
}

}  // namespace

// libFuzzer target for the HTTP door's request handling (server/gateway/request_checks.h,
// grpc_web.h) on a whole request stream: the input after its first byte is what a client sent
// on one connection, parsed by Beast as the gateway does (header_limit 16 KiB, body_limit) and
// handed to the checks it runs — up to 8 pipelined requests, each with a fresh parser on the
// bytes the previous one left.
//
// First byte (control): bits 0–5 are the split stride (0: every byte at once, else the bytes
// arrive that many at a time, so Beast's incremental parsing — a header re-presented with more
// bytes, a chunk header cut in two — is exercised); bit 6 picks the gateway's two parsers (the
// header with request_parser<empty_body>, then moved into request_parser<string_body> for the
// body) instead of one request_parser<string_body> throughout.
//
// Per header: framing_refusal, host_refusal (a fixed policy and "*"), cross_site_refusal,
// has_upload_header, host_of on the Host and X-Forwarded-Host values, and a HostPolicy built
// from the Host value's comma-separated parts. Per complete body: parse_frames and
// parse_timeout(grpc-timeout). Facts that hold by construction are checked with
// __builtin_trap(); any exception but HostPolicy's std::invalid_argument is a crash too.
#include "gateway/grpc_web.h"
#include "gateway/request_checks.h"

#include <boost/asio/buffer.hpp>
#include <boost/beast/http.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace {

namespace http = boost::beast::http;
namespace gw = hdeform::gateway;
namespace grpc_web = hdeform::gateway::grpc_web;

constexpr std::size_t kHeaderLimit = 16u << 10;  // the gateway's kMaxHeaderBytes
constexpr std::size_t kBodyLimit = 1u << 20;
constexpr int kMaxRequests = 8;

std::string_view view(boost::beast::string_view s) { return {s.data(), s.size()}; }

const gw::HostPolicy& fixed_policy() {
  static const gw::HostPolicy policy({"viewer.example", ".team.example"});
  return policy;
}

const gw::HostPolicy& any_policy() {
  static const gw::HostPolicy policy({"*"});
  return policy;
}

// host_of's result: empty, a bracketed IPv6 literal ('[' first, the only ']' last, then only
// hex digits, ':' and '.'; no zone), or a name of 1–253 bytes of [a-z0-9._-] — so never a ':'
// outside brackets, never upper case.
void check_host_of(std::string_view value) {
  const std::string h = gw::host_of(value);
  if (h.empty()) return;
  if (h.front() == '[') {
    if (h.size() < 3 || h.find(']') != h.size() - 1) __builtin_trap();
    const auto address = std::string_view(h).substr(1, h.size() - 2);
    for (const char c : address) {
      const bool ok = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f') || c == ':' || c == '.';
      if (!ok) __builtin_trap();
    }
    for (const char c : h)
      if (c >= 'A' && c <= 'Z') __builtin_trap();
    return;
  }
  if (h.size() > 253) __builtin_trap();
  for (const char c : h) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '-' ||
                    c == '_';
    if (!ok) __builtin_trap();
  }
}

std::string_view trimmed(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// HostPolicy from the Host value's comma-separated parts (as --allowed-hosts would give them).
void fuzz_policy(std::string_view value) {
  std::vector<std::string> entries;
  for (std::size_t at = 0;;) {
    const auto comma = value.find(',', at);
    entries.emplace_back(value.substr(at, comma == std::string_view::npos ? comma : comma - at));
    if (comma == std::string_view::npos || entries.size() >= 8) break;
    at = comma + 1;
  }
  try {
    const gw::HostPolicy policy(entries);
    if (policy.describe().empty()) __builtin_trap();
    const bool allowed = policy.allows(value);
    if (allowed && gw::host_of(value).empty()) __builtin_trap();  // malformed: never allowed
    // A policy from one exact name allows that name.
    if (entries.size() == 1) {
      const auto e = trimmed(entries[0]);
      if (!e.empty() && e != "*" && !e.starts_with('.') && !e.starts_with("*.") &&
          !policy.allows(entries[0]))
        __builtin_trap();
    }
  } catch (const std::invalid_argument&) {
  }
}

// The shapes a host allowed by fixed_policy() can have.
bool fixed_policy_may_allow(const std::string& h) {
  if (h.empty()) return false;
  if (h == "viewer.example" || h.ends_with(".team.example")) return true;
  if (h == "localhost" || h.ends_with(".localhost")) return true;
  if (h.front() == '[' && h.back() == ']') return true;
  return std::all_of(h.begin(), h.end(), [](char c) { return (c >= '0' && c <= '9') || c == '.'; });
}

void check_header(const gw::RequestHeader& req, bool chunked) {
  // Framing: accepted with a Transfer-Encoding only when Beast frames the body as chunked too.
  const std::string framing = gw::framing_refusal(req);
  const auto encodings = req.count(http::field::transfer_encoding);
  if (framing.empty() && encodings > 0) {
    if (!chunked || encodings != 1 || req.count(http::field::content_length) != 0) __builtin_trap();
  }

  // Host.
  const std::string refusal = gw::host_refusal(req, fixed_policy());
  const std::string refusal_any = gw::host_refusal(req, any_policy());
  const auto hosts = req.count(http::field::host);
  const std::string_view host_value = view(req[http::field::host]);
  const std::string host = gw::host_of(host_value);
  if (refusal_any.empty() != (hosts == 1 && !host.empty())) __builtin_trap();
  if (refusal.empty() && !refusal_any.empty()) __builtin_trap();  // "*" allows a superset
  if (refusal.empty() && !fixed_policy_may_allow(host)) __builtin_trap();
  for (const auto& field : req)  // every Host (equal_range is not one run of the list)
    if (field.name() == http::field::host) check_host_of(view(field.value()));
  check_host_of(view(req["x-forwarded-host"]));
  if (hosts > 0) fuzz_policy(host_value);

  // Origin: none passes; "http://" + a well-formed Host value passes.
  const std::string cross = gw::cross_site_refusal(req);
  if (req.count(http::field::origin) == 0 && !cross.empty()) __builtin_trap();
  if (!host.empty() && host_value.find_first_of("/?#@ \t") == std::string_view::npos) {
    gw::RequestHeader same = req;
    same.set(http::field::origin, "http://" + std::string(host_value));
    if (!gw::cross_site_refusal(same).empty()) __builtin_trap();
  }

  (void)gw::has_upload_header(req);
}

template <class Parser>
void check_body(const Parser& parser) {
  const auto& req = parser.get();
  const std::string_view body = req.body();
  if (body.size() > kBodyLimit) __builtin_trap();
  if (!parser.chunked()) {
    if (const auto length = parser.content_length(); length && *length != body.size())
      __builtin_trap();
  }

  const grpc_web::ParsedBody parsed = grpc_web::parse_frames(body);
  std::size_t covered = 0;
  for (const std::string_view m : parsed.messages) {
    if (m.data() < body.data() || m.data() + m.size() > body.data() + body.size()) __builtin_trap();
    covered += m.size() + 5;
  }
  if (covered > body.size()) __builtin_trap();

  const auto timeout = grpc_web::parse_timeout(view(req["grpc-timeout"]));
  if (timeout && (timeout->count() < 0 || *timeout > grpc_web::kMaxTimeout)) __builtin_trap();
}

// The bytes of one connection, handed to parsers `stride` at a time (0: all at once).
struct Stream {
  const char* data;
  std::size_t size;
  std::size_t stride;
  std::size_t consumed = 0;  // by parsers
  std::size_t arrived = 0;   // bytes the parsers may see: [consumed, arrived)

  bool more() {
    if (arrived == size) return false;
    arrived = stride == 0 ? size : std::min(size, arrived + stride);
    return true;
  }
};

// Feeds `parser` until `done(parser)`; false on a parse error (the gateway would answer or
// close) or when the stream ends first (put_eof, like a peer that closed).
template <class Parser, class Done>
bool feed(Parser& parser, Stream& s, Done done) {
  while (!done(parser)) {
    if (s.consumed == s.arrived && !s.more()) {
      boost::beast::error_code ec;
      parser.put_eof(ec);
      return !ec && done(parser);
    }
    boost::beast::error_code ec;
    const std::size_t n =
        parser.put(boost::asio::buffer(s.data + s.consumed, s.arrived - s.consumed), ec);
    if (n > s.arrived - s.consumed) __builtin_trap();
    s.consumed += n;
    if (ec == http::error::need_more || (!ec && n == 0)) {
      if (!s.more()) {
        parser.put_eof(ec);
        return !ec && done(parser);
      }
      continue;
    }
    if (ec) return false;
  }
  return true;
}

// One request as the gateway reads it; false when the connection would end.
bool one_request(Stream& s, bool gateway_parsers) {
  const auto header_done = [](const auto& p) { return p.is_header_done(); };
  const auto message_done = [](const auto& p) { return p.is_done(); };
  if (gateway_parsers) {
    http::request_parser<http::empty_body> header;
    header.header_limit(kHeaderLimit);
    header.body_limit(kBodyLimit);
    if (!feed(header, s, header_done)) return false;
    check_header(header.get(), header.chunked());
    http::request_parser<http::string_body> parser(std::move(header));
    parser.body_limit(kBodyLimit);
    parser.eager(true);
    if (!feed(parser, s, message_done)) return false;
    check_body(parser);
    return true;
  }
  http::request_parser<http::string_body> parser;
  parser.header_limit(kHeaderLimit);
  parser.body_limit(kBodyLimit);
  parser.eager(true);
  if (!feed(parser, s, header_done)) return false;
  check_header(parser.get(), parser.chunked());
  if (!feed(parser, s, message_done)) return false;
  check_body(parser);
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t control = data[0];
  Stream s{reinterpret_cast<const char*>(data) + 1, size - 1, std::size_t(control & 0x3F)};
  const bool gateway_parsers = (control & 0x40) != 0;
  for (int i = 0; i < kMaxRequests && s.consumed < s.size; ++i) {
    if (!one_request(s, gateway_parsers)) break;
  }
  return 0;
}

// libFuzzer target for the HTTP door's request handling on a whole request stream: the input
// after its first byte is what a client sent on one connection, read as the door reads it
// (server/gateway/door.cpp, relay.cpp, upload.cpp) and handed to the door's own checks and
// gRPC-Web frame splitter — up to 8 pipelined requests, each with a fresh header parser on
// the bytes the previous one left, the next one read only when the door would keep the
// connection (keep-alive, and no early answer that closes it).
//
// As the door: the header through request_parser<empty_body> (header_limit kMaxHeaderBytes,
// body_limit the server's default max_body_bytes, not eager), each read a Beast read_some
// (put what is buffered; more bytes only on need_more); then Host/framing refusals, the
// path's url_decode, the cross-site refusal for POST, and by path: a gRPC-Web call (the
// header moved into request_parser<string_body> with the door's body limit — Content-Length
// or kChunkedBodyLimit —, the Content-Type rule, grpc_web::parse_frames, body_refusal and its
// trailers frame, grpc-timeout), /upload (the query's filename/library/repair rules, the
// header moved into request_parser<buffer_body> read into a fixed chunk, refilled as the
// door's read_more does), GET/HEAD (a body announced is refused; string_body with none); anything else
// ends the connection.
//
// First byte (control): bits 0–5 are the split stride (0: every byte at once, else the bytes
// arrive that many at a time, so Beast's incremental parsing — a header re-presented with more
// bytes, a chunk header cut in two — is exercised); bit 6 picks the Host policy "*" instead of
// a fixed list (so more requests get past the Host check); bit 7 the door's 1 MiB upload chunk
// instead of 13 bytes (which makes the upload body refill the chunk many times).
//
// Per header, beyond what the door does: framing_refusal, host_refusal (both policies),
// cross_site_refusal, has_upload_header, host_of on the Host and X-Forwarded-Host values, and
// a HostPolicy built from the Host value's comma-separated parts. Facts that hold by
// construction are checked with __builtin_trap(); any exception but HostPolicy's
// std::invalid_argument is a crash too.
#include "gateway/call_checks.h"
#include "gateway/grpc_web.h"
#include "gateway/request_checks.h"
#include "gateway/static_files.h"

#include <boost/asio/buffer.hpp>
#include <boost/beast/http.hpp>

#include <algorithm>
#include <charconv>
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

// hdeform-server's default GatewayOptions::max_body_bytes: --max-upload-mb 256, plus 16 MiB.
constexpr std::size_t kMaxBodyBytes = (256u << 20) + (16u << 20);
constexpr std::size_t kUploadChunk = 1u << 20;  // upload.cpp's chunk
constexpr std::size_t kSmallChunk = 13;
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


// The bytes of one connection, arriving `stride` at a time (0: all at once) into the door's
// read buffer; [consumed, arrived) is what the buffer holds.
struct Stream {
  const char* data;
  std::size_t size;
  std::size_t stride;
  std::size_t consumed = 0;  // by parsers
  std::size_t arrived = 0;

  std::size_t buffered() const { return arrived - consumed; }
  // A socket read: false at the end of the stream (the peer closed).
  bool read() {
    if (arrived == size) return false;
    arrived = stride == 0 ? size : std::min(size, arrived + stride);
    return true;
  }
};

// http::async_read_some(stream, flat_buffer, parser) as Beast 1.74 implements it
// (http/impl/read.hpp, read_some_op): put() what is buffered, reading more only on need_more
// (or when nothing is buffered); at the end of the stream put_eof() if the parser got some
// bytes, else end_of_stream.
template <class Parser>
boost::beast::error_code read_some(Parser& parser, Stream& s) {
  boost::beast::error_code ec;
  bool must_read = s.buffered() == 0;
  for (;;) {
    if (!must_read) {
      const std::size_t n = parser.put(boost::asio::buffer(s.data + s.consumed, s.buffered()), ec);
      if (n > s.buffered()) __builtin_trap();
      s.consumed += n;
      if (ec != http::error::need_more) return ec;
    }
    must_read = false;
    if (!s.read()) {
      if (!parser.got_some()) return http::error::end_of_stream;
      ec = {};
      parser.put_eof(ec);
      if (!ec && !parser.is_done()) __builtin_trap();  // Beast asserts this
      return ec;
    }
  }
}

// http::async_read_header (done = is_header_done) and the door's read_body (done = is_done):
// read_some until done or an error.
template <class Parser, class Done>
boost::beast::error_code read_until(Parser& parser, Stream& s, Done done) {
  while (!done(parser)) {
    if (const auto ec = read_some(parser, s)) return ec;
  }
  return {};
}

const auto header_done = [](const auto& p) { return p.is_header_done(); };
const auto message_done = [](const auto& p) { return p.is_done(); };

// A gRPC-Web call as relay.cpp's grpc_web_call reads and checks it; true when the door would
// read the next request on this connection.
bool grpc_web_call(http::request_parser<http::empty_body>& header, Stream& s,
                   const std::string& path) {
  const auto length = header.content_length();
  const std::size_t limit = length ? kMaxBodyBytes : std::min(kMaxBodyBytes, gw::kChunkedBodyLimit);
  if (length && *length > limit) return false;  // 413, close
  http::request_parser<http::string_body> parser(std::move(header));
  parser.body_limit(limit);
  if (read_until(parser, s, message_done)) return false;  // 413, or the connection ends

  const auto& req = parser.get();
  const std::string_view body = req.body();
  if (body.size() > limit) __builtin_trap();
  if (!parser.chunked() && length && *length != body.size()) __builtin_trap();
  const bool keep_alive = req.keep_alive();
  const auto content_type = req[http::field::content_type];
  if (!content_type.starts_with("application/grpc-web") ||
      content_type.starts_with("application/grpc-web-text"))
    return keep_alive;  // 415

  // The door's frame splitter on the whole body, then its refusal or the relay.
  const grpc_web::ParsedBody parsed = grpc_web::parse_frames(body);
  std::size_t covered = 0;
  for (const std::string_view m : parsed.messages) {
    if (m.data() < body.data() || m.data() + m.size() > body.data() + body.size()) __builtin_trap();
    covered += m.size() + 5;
  }
  if (covered > body.size()) __builtin_trap();
  const auto* method = gw::find_method(path);
  if (const auto refusal = gw::body_refusal(path, parsed)) {
    const auto code = refusal->error_code();
    if (code != grpc::StatusCode::INVALID_ARGUMENT && code != grpc::StatusCode::UNIMPLEMENTED)
      __builtin_trap();
    if (parsed.error.empty() && method && (method->client_streaming() || parsed.messages.size() == 1))
      __builtin_trap();  // a call the relay would take, refused
    // Its trailers frame, as the door writes it: flag 0x80, then exactly the length it says.
    const std::string frame = grpc_web::trailers_frame(*refusal);
    if (frame.size() < 5 || std::uint8_t(frame[0]) != grpc_web::kTrailerFlag) __builtin_trap();
    const std::uint32_t n = (std::uint32_t(std::uint8_t(frame[1])) << 24) |
                            (std::uint32_t(std::uint8_t(frame[2])) << 16) |
                            (std::uint32_t(std::uint8_t(frame[3])) << 8) | std::uint8_t(frame[4]);
    if (n != frame.size() - 5) __builtin_trap();
    for (std::size_t i = 5; i < frame.size(); ++i)  // percent-encoded: printable ASCII and CRLF
      if ((frame[i] < 0x20 || frame[i] > 0x7e) && frame[i] != '\r' && frame[i] != '\n')
        __builtin_trap();
  } else {
    if (!parsed.error.empty() || !method) __builtin_trap();
    if (!method->client_streaming() && parsed.messages.size() != 1) __builtin_trap();
  }
  const auto timeout = grpc_web::parse_timeout(view(req["grpc-timeout"]));
  if (timeout && (timeout->count() < 0 || *timeout > grpc_web::kMaxTimeout)) __builtin_trap();
  return keep_alive;
}

// POST /upload as upload.cpp reads it: the query's rules, then the body through
// request_parser<buffer_body> into a chunk of `chunk_size`, refilled as read_more does.
bool upload(http::request_parser<http::empty_body>& header, Stream& s, std::string_view query,
            std::size_t chunk_size) {
  const std::string filename = gw::query_param(query, "filename");
  const std::string library = gw::query_param(query, "library");
  if (filename.empty() == library.empty()) return false;  // 400
  if (const auto repair = gw::query_param(query, "repair"); !repair.empty()) {
    double tolerance = 0;
    const auto [end, ec] = std::from_chars(repair.data(), repair.data() + repair.size(), tolerance);
    if (ec != std::errc() || end != repair.data() + repair.size()) return false;  // 400
  }
  const auto length = header.content_length();
  const bool keep_alive = header.get().keep_alive();
  http::request_parser<http::buffer_body> parser(std::move(header));
  parser.body_limit(kMaxBodyBytes);
  std::string chunk(chunk_size, '\0');
  std::size_t filled = 0;
  std::uint64_t total = 0;
  while (!parser.is_done()) {
    auto& b = parser.get().body();
    b.data = chunk.data() + filled;
    b.size = chunk.size() - filled;
    auto ec = read_some(parser, s);
    if (ec == http::error::need_buffer) ec = {};
    if (ec) return false;  // stalled, gone, or 413
    const std::size_t now = chunk.size() - parser.get().body().size;
    if (now < filled || now > chunk.size()) __builtin_trap();
    filled = now;
    if (filled < chunk.size() && !parser.is_done()) continue;
    total += filled;  // send_chunk: one CreateSession chunk message
    filled = 0;
  }
  if (total > kMaxBodyBytes) __builtin_trap();
  if (!parser.chunked() && length && *length != total) __builtin_trap();
  return keep_alive;
}

struct Config {
  const gw::HostPolicy* hosts;
  std::size_t upload_chunk;
};

// One request as the door reads it (door.cpp: read_header, on_header, handle); true when the
// door would read another request on this connection.
bool one_request(Stream& s, const Config& config) {
  http::request_parser<http::empty_body> header;
  header.header_limit(gw::kMaxHeaderBytes);
  header.body_limit(kMaxBodyBytes);  // a larger Content-Length fails: 413
  if (read_until(header, s, header_done)) return false;  // 413, 400, or the connection ends
  const auto& req = header.get();
  check_header(req, header.chunked());
  if (!gw::framing_refusal(req).empty()) return false;             // 400
  if (!gw::host_refusal(req, *config.hosts).empty()) return false;  // 421

  const auto method = req.method();
  const bool keep_alive = req.keep_alive();
  const std::string target(req.target());
  const auto qmark = target.find('?');
  const std::string_view raw_path = std::string_view(target).substr(0, qmark);
  const std::string path = gw::url_decode(raw_path);
  const std::string query = qmark == std::string::npos ? "" : target.substr(qmark + 1);
  if (path.size() > raw_path.size()) __builtin_trap();
  if (raw_path.find('%') == std::string_view::npos && path != raw_path) __builtin_trap();

  if (method == http::verb::post && !gw::cross_site_refusal(req).empty()) return false;  // 403
  if (path.starts_with(gw::kServicePrefix)) {
    if (method != http::verb::post) return false;  // 405
    return grpc_web_call(header, s, path);
  }
  if (path == "/upload") {
    if (method != http::verb::post || !gw::has_upload_header(req)) return false;  // 405, 403
    return upload(header, s, query, config.upload_chunk);
  }
  if (method == http::verb::get || method == http::verb::head) {
    if (header.chunked() || header.content_length().value_or(0) > 0) return false;  // 400
    http::request_parser<http::string_body> parser(std::move(header));
    parser.body_limit(0);
    if (read_until(parser, s, message_done)) return false;
    return keep_alive;  // the file, /healthz or 404: the connection stays
  }
  return false;  // 405
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t control = data[0];
  Stream s{reinterpret_cast<const char*>(data) + 1, size - 1, std::size_t(control & 0x3F)};
  const Config config{(control & 0x40) ? &any_policy() : &fixed_policy(),
                      (control & 0x80) ? kUploadChunk : kSmallChunk};
  for (int i = 0; i < kMaxRequests; ++i) {
    if (!one_request(s, config)) break;
    if (s.consumed == s.size) break;  // nothing more on the connection
  }
  return 0;
}

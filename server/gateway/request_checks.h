// What the HTTP door checks on a request header before anything runs: the Host it is for
// (DNS rebinding), how its body is framed (request smuggling), and whether a POST came from a
// page this server served (cross-site requests). Pure functions over a parsed header, so the
// fuzzer drives them on whole request streams (tests/fuzz/fuzz_http_request.cpp).
#pragma once

#include <boost/beast/http.hpp>

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace hdeform::gateway {

using RequestHeader = boost::beast::http::request_header<>;

// The largest request header the door reads (request line and fields; Beast's header_limit).
inline constexpr std::size_t kMaxHeaderBytes = 16u << 10;

// The Host names the door answers for (--allowed-hosts). Always: localhost names
// ("localhost", "*.localhost") and IP literals (a request naming the server by address cannot
// come from a rebound name). Entries add: "name" (exact), ".name" (its subdomains), "*" (any:
// only behind a proxy that checks Host itself). Names are compared lower-case, without the
// port and a trailing dot.
class HostPolicy {
 public:
  HostPolicy() = default;
  // Throws std::invalid_argument naming a malformed entry.
  explicit HostPolicy(const std::vector<std::string>& entries);
  bool allows(std::string_view host_header) const;
  std::string describe() const;  // for the refusal text and the log

 private:
  bool any_ = false;
  std::vector<std::string> exact_, suffixes_;  // suffixes_ hold ".name"
};

// The host part of a Host header value, lower-case, without port or trailing dot ("[::1]"
// keeps its brackets); empty if the value is not a syntactically valid host[:port].
std::string host_of(std::string_view host_header);

// Empty if the request's Host is allowed, else the refusal text (answered 421).
std::string host_refusal(const RequestHeader& req, const HostPolicy& policy);

// Empty if the body framing is unambiguous, else the refusal text (answered 400): a
// Transfer-Encoding other than exactly "chunked" (RFC 9112 §6.1: the server cannot know the
// length), or with a Content-Length as well (§6.3: a smuggling attempt through a proxy).
std::string framing_refusal(const RequestHeader& req);

// Empty if a POST may proceed, else why it is refused (403): an Origin header that names
// neither the Host nor the first X-Forwarded-Host. Requests without Origin pass (not from a
// browser, or same-origin).
std::string cross_site_refusal(const RequestHeader& req);

// /upload needs a header that a cross-site page cannot send without a CORS preflight, which
// this server never approves: X-Session-Id (the viewer) or X-Hdeform-Upload.
bool has_upload_header(const RequestHeader& req);

}  // namespace hdeform::gateway

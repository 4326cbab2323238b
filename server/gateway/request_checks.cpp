#include "gateway/request_checks.h"

#include <boost/asio/ip/address.hpp>

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace hdeform::gateway {
namespace http = boost::beast::http;

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (auto& ch : out) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return out;
}

std::string_view trimmed(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string_view header_value(const RequestHeader& req, std::string_view name) {
  const auto it = req.find(boost::beast::string_view(name.data(), name.size()));
  return it == req.end() ? std::string_view()
                         : std::string_view(it->value().data(), it->value().size());
}

// A registered name (RFC 3986 reg-name, restricted to what DNS can hold) of ≤ 253 bytes.
bool is_name(std::string_view s) {
  if (s.empty() || s.size() > 253) return false;
  return std::all_of(s.begin(), s.end(), [](char ch) {
    const auto c = static_cast<unsigned char>(ch);
    return std::isalnum(c) || c == '-' || c == '.' || c == '_';
  });
}

bool is_ip_literal(std::string_view host) {
  boost::system::error_code ec;
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    boost::asio::ip::make_address_v6(std::string(host.substr(1, host.size() - 2)), ec);
    return !ec;
  }
  boost::asio::ip::make_address_v4(std::string(host), ec);
  return !ec;
}

bool is_localhost(std::string_view host) {
  return host == "localhost" || host.ends_with(".localhost");
}

// host[:port], lower-case, with a default port (80, 443) dropped: the gateway cannot know the
// scheme a proxy terminated, so "https://a.example" and Host "a.example:443" compare equal.
std::string normalized_authority(std::string_view authority) {
  std::string out = lower(authority);
  if (out.ends_with(":80")) out.resize(out.size() - 3);
  if (out.ends_with(":443")) out.resize(out.size() - 4);
  return out;
}

// The host[:port] of an Origin header ("scheme://host[:port]"); empty for "null" (sandboxed
// frames, file: pages) and anything malformed, which then matches no host.
std::string origin_authority(std::string_view origin) {
  const auto sep = origin.find("://");
  if (sep == std::string_view::npos || sep == 0) return {};
  const auto authority = origin.substr(sep + 3);
  if (authority.empty() || authority.find_first_of("/?#@ \t") != std::string_view::npos) return {};
  return normalized_authority(authority);
}

std::string quoted(std::string_view s) {
  std::string out(1, '\'');  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on a + b + c
  out.append(s.substr(0, 200));
  out += '\'';
  return out;
}

}  // namespace

std::string host_of(std::string_view value) {
  value = trimmed(value);
  std::string_view host = value, port;
  if (value.starts_with('[')) {
    const auto close = value.find(']');
    if (close == std::string_view::npos) return {};
    host = value.substr(0, close + 1);
    // A zone ("%eth0") means nothing to another host, and the address parser would take any
    // bytes after '%' as one: refuse it, as browsers never send it.
    if (host.find('%') != std::string_view::npos) return {};
    const auto rest = value.substr(close + 1);
    if (!rest.empty()) {
      if (rest.front() != ':') return {};
      port = rest.substr(1);
    }
    if (!is_ip_literal(host)) return {};
  } else if (const auto colon = value.find(':'); colon != std::string_view::npos) {
    host = value.substr(0, colon);
    port = value.substr(colon + 1);
  }
  if (port.size() > 5 || !std::all_of(port.begin(), port.end(), [](char c) {
        return c >= '0' && c <= '9';
      })) {
    return {};
  }
  if (host.ends_with('.')) host.remove_suffix(1);
  if (!host.starts_with('[') && !is_name(host)) return {};
  return lower(host);
}

HostPolicy::HostPolicy(const std::vector<std::string>& entries) {
  for (const auto& raw : entries) {
    const auto entry = trimmed(raw);
    if (entry.empty()) continue;
    if (entry == "*") {
      any_ = true;
      continue;
    }
    const bool subdomains = entry.starts_with('.') || entry.starts_with("*.");
    const auto name = entry.substr(entry.starts_with("*.") ? 2 : subdomains ? 1 : 0);
    const auto host = host_of(name);
    if (host.empty() || host.find(':') != std::string::npos) {
      throw std::invalid_argument("--allowed-hosts: " + quoted(entry) +
                                  " is not a host name (use NAME, .NAME for its subdomains, "
                                  "or * for any)");
    }
    (subdomains ? suffixes_ : exact_).push_back(subdomains ? "." + host : host);
  }
}

bool HostPolicy::allows(std::string_view host_header) const {
  const auto host = host_of(host_header);
  if (host.empty()) return false;  // malformed, even with "*": nothing should route on it
  if (any_ || is_localhost(host) || is_ip_literal(host)) return true;
  if (std::find(exact_.begin(), exact_.end(), host) != exact_.end()) return true;
  return std::any_of(suffixes_.begin(), suffixes_.end(),
                     [&](const std::string& s) { return host.ends_with(s); });
}

std::string HostPolicy::describe() const {
  if (any_) return "any host";
  std::string out = "localhost names, IP addresses";
  for (const auto& e : exact_) out += ", " + e;
  for (const auto& s : suffixes_) out += ", *" + s;
  return out;
}

std::string host_refusal(const RequestHeader& req, const HostPolicy& policy) {
  if (req.count(http::field::host) != 1) {
    return "misdirected request: exactly one Host header is required\n";
  }
  const auto host = header_value(req, "host");
  if (policy.allows(host)) return {};
  return "misdirected request: this server does not answer for Host " + quoted(host) +
         " (it answers for " + policy.describe() +
         "; the operator adds names with --allowed-hosts)\n";
}

std::string framing_refusal(const RequestHeader& req) {
  const auto encodings = req.count(http::field::transfer_encoding);
  if (encodings == 0) return {};
  if (encodings > 1) return "bad request: more than one Transfer-Encoding header\n";
  const auto value = trimmed(header_value(req, "transfer-encoding"));
  if (lower(value) != "chunked") {
    return "bad request: Transfer-Encoding " + quoted(value) +
           " is not supported; only 'chunked' is (RFC 9112 §6.1)\n";
  }
  if (req.count(http::field::content_length) > 0) {
    return "bad request: both Transfer-Encoding and Content-Length (RFC 9112 §6.3)\n";
  }
  return {};
}

// A page on another site can make the user's browser POST here: a "simple" request (a form,
// or fetch with a CORS-safelisted Content-Type) is sent without asking the server first. Two
// independent rules stop it. (1) Browsers put Origin on every cross-origin POST; it must name
// this server (the Host the browser connected to, or the X-Forwarded-Host a proxy passed on —
// a page cannot set that header cross-site without a preflight). (2) /upload, whose body is
// any bytes, also needs a custom header, which forces a CORS preflight that this server never
// approves (it answers OPTIONS with 405), even in a browser that omits Origin. gRPC-Web calls
// need no extra header: their Content-Type (application/grpc-web…) already forces a preflight.
// A page on a rebound name is same-origin by the browser's rules; host_refusal stops it.
std::string cross_site_refusal(const RequestHeader& req) {
  const auto it = req.find(http::field::origin);
  if (it == req.end()) return {};
  const std::string_view origin(it->value().data(), it->value().size());
  const auto from = origin_authority(origin);
  auto forwarded = header_value(req, "x-forwarded-host");
  forwarded = trimmed(forwarded.substr(0, forwarded.find(',')));  // the client-facing proxy
  if (!from.empty() && (from == normalized_authority(header_value(req, "host")) ||
                        (!forwarded.empty() && from == normalized_authority(forwarded)))) {
    return {};
  }
  return "cross-site request refused: Origin " + quoted(origin) + " is not this server (" +
         std::string(header_value(req, "host").substr(0, 200)) +
         "); hdeform only answers pages it served itself\n";
}

bool has_upload_header(const RequestHeader& req) {
  return req.count("x-session-id") > 0 || req.count("x-hdeform-upload") > 0;
}

}  // namespace hdeform::gateway

// The door's files and URLs: content types, URL decoding, and the one rule for static files —
// a request path names a regular file inside the web root, or nothing.
#pragma once

#include <boost/beast/http/status.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace hdeform::gateway {

// Content-Type for a file name (by extension; application/octet-stream otherwise).
std::string_view mime_type(std::string_view path);

// Decodes %XX escapes in a URL component ('+' stays '+'; it is a path, not a form). A '%' not
// followed by two hex digits stays as it is. Decodes once: "%252F" becomes "%2F", never "/".
// Never throws; the result may contain NUL, which callers that build paths must reject.
std::string url_decode(std::string_view in);

// The decoded value of `key` in a query string ("a=1&b=2"); empty if absent.
std::string query_param(std::string_view query, std::string_view key);

struct StaticLookup {
  boost::beast::http::status status = boost::beast::http::status::ok;  // ok, bad_request, not_found
  std::filesystem::path file;  // canonical, a regular file, when ok
};

// Maps a decoded URL path to a regular file inside `root` (canonical; "/" and folders:
// index.html). FIFOs, devices and sockets are refused before anything opens them.
StaticLookup find_static(const std::filesystem::path& root, std::string_view path);

}  // namespace hdeform::gateway

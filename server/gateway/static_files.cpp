#include "gateway/static_files.h"

#include <algorithm>

namespace hdeform::gateway {

namespace http = boost::beast::http;

std::string_view mime_type(std::string_view path) {
  const auto dot = path.rfind('.');
  const std::string_view ext = dot == std::string_view::npos ? "" : path.substr(dot + 1);
  if (ext == "html" || ext == "htm") return "text/html; charset=utf-8";
  if (ext == "js" || ext == "mjs") return "text/javascript; charset=utf-8";
  if (ext == "css") return "text/css; charset=utf-8";
  if (ext == "json" || ext == "map") return "application/json";
  if (ext == "wasm") return "application/wasm";
  if (ext == "svg") return "image/svg+xml";
  if (ext == "png") return "image/png";
  if (ext == "jpg" || ext == "jpeg") return "image/jpeg";
  if (ext == "gif") return "image/gif";
  if (ext == "webp") return "image/webp";
  if (ext == "ico") return "image/x-icon";
  if (ext == "txt" || ext == "md") return "text/plain; charset=utf-8";
  if (ext == "woff2") return "font/woff2";
  if (ext == "woff") return "font/woff";
  if (ext == "glb") return "model/gltf-binary";
  if (ext == "gltf") return "model/gltf+json";
  if (ext == "obj" || ext == "off" || ext == "ply" || ext == "stl") return "text/plain";
  return "application/octet-stream";
}

// Value of one hex digit, or -1.
static int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string url_decode(std::string_view in) {
  std::string out;
  out.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    const int hi = in[i] == '%' && i + 2 < in.size() ? hex_value(in[i + 1]) : -1;
    const int lo = hi >= 0 ? hex_value(in[i + 2]) : -1;
    if (lo >= 0) {
      out += static_cast<char>(hi * 16 + lo);
      i += 2;
    } else {
      out += in[i];
    }
  }
  return out;
}

std::string query_param(std::string_view query, std::string_view key) {
  while (!query.empty()) {
    const auto amp = query.find('&');
    const auto part = query.substr(0, amp);
    const auto eq = part.find('=');
    if (part.substr(0, eq) == key) {
      return eq == std::string_view::npos ? std::string() : url_decode(part.substr(eq + 1));
    }
    if (amp == std::string_view::npos) break;
    query.remove_prefix(amp + 1);
  }
  return {};
}

namespace {

// ---- static files --------------------------------------------------------------------------
// A request path must never name a file outside the web root. Joining strings is not enough:
// `root / "/etc/passwd"` is "/etc/passwd", and symlinks inside the root may point anywhere. So
// the path is rebuilt one segment at a time (no segment can be absolute or "..") and the
// result is accepted only if its canonical form (symlinks resolved) still lies in the root.

// The decoded URL path as a path under `root`; nullopt for a malformed path (400).
std::optional<std::filesystem::path> join_under(const std::filesystem::path& root,
                                                std::string_view path) {
  if (path.empty() || path.front() != '/') return std::nullopt;
  if (path.find('\0') != std::string_view::npos || path.find('\\') != std::string_view::npos) {
    return std::nullopt;
  }
  std::filesystem::path out = root;
  while (!path.empty()) {
    const auto slash = path.find('/');
    const auto segment = path.substr(0, slash);
    path.remove_prefix(slash == std::string_view::npos ? path.size() : slash + 1);
    if (segment.empty() || segment == ".") continue;  // "//" and "/./" add nothing
    if (segment == "..") return std::nullopt;
    out /= std::filesystem::path(segment);  // no '/' inside: always one relative component
  }
  return out;
}

// The canonical form of `candidate` if it exists and lies inside `root` (itself canonical).
std::optional<std::filesystem::path> inside(const std::filesystem::path& root,
                                            const std::filesystem::path& candidate) {
  std::error_code ec;
  auto canonical = std::filesystem::canonical(candidate, ec);
  if (ec) return std::nullopt;
  // Component-wise prefix test: "/srv/www" contains "/srv/www/a" but not "/srv/www2/a".
  const auto [r, c] = std::mismatch(root.begin(), root.end(), canonical.begin(), canonical.end());
  if (r != root.end()) return std::nullopt;
  return canonical;
}

}  // namespace

// Maps a decoded URL path to a regular file inside `root` ("/" and folders: index.html).
// FIFOs, devices and sockets are refused before anything opens them (opening a FIFO blocks).
StaticLookup find_static(const std::filesystem::path& root, std::string_view path) {
  const auto joined = join_under(root, path);
  if (!joined) return {http::status::bad_request, {}};
  auto file = inside(root, *joined);
  std::error_code ec;
  if (file && std::filesystem::is_directory(*file, ec)) file = inside(root, *file / "index.html");
  if (!file || !std::filesystem::is_regular_file(*file, ec)) return {http::status::not_found, {}};
  return {http::status::ok, std::move(*file)};
}

}  // namespace hdeform::gateway

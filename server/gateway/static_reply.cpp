// GET/HEAD: /healthz and the viewer's files from the web root (static_files.h decides which).
#include "gateway/door.h"

#include "gateway/static_files.h"

namespace hdeform::gateway {

void HttpGateway::Impl::static_file(const ConnectionPtr& c, const std::string& path, bool head,
                                    unsigned version, bool keep_alive) {
  const After after = keep_alive ? After::keep_alive : After::close;
  if (path == "/healthz") return send_text(c, http::status::ok, "ok\n", version, after);
  if (web_root.empty()) {
    return send_text(c, http::status::not_found,
                     "not found (this server was started without the web viewer)\n", version,
                     after);
  }
  const auto found = find_static(web_root, path);
  if (found.status == http::status::bad_request)
    return send_text(c, http::status::bad_request, "bad path\n", version, after);
  http::file_body::value_type body;
  beast::error_code ec;
  if (found.status == http::status::ok) body.open(found.file.c_str(), beast::file_mode::scan, ec);
  if (found.status != http::status::ok || ec)
    return send_text(c, http::status::not_found, "not found\n", version, after);
  const auto size = body.size();
  const bool immutable = path.starts_with("/assets/");  // vite's content-hashed files
  const auto type_sv = mime_type(found.file.string());
  const beast::string_view type(type_sv.data(), type_sv.size());
  const auto cache = immutable ? "public, max-age=31536000, immutable" : "no-cache";
  const auto done = [this, c, after](bool ok) { after_response(c, ok ? after : After::close); };
  if (head) {
    auto res = std::make_shared<http::response<http::empty_body>>(http::status::ok, version);
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, cache);
    res->content_length(size);
    res->keep_alive(keep_alive);
    return write_message(c, std::move(res), done);
  }
  // The file is read as it is written, a piece at a time, on this strand.
  auto res = std::make_shared<http::response<http::file_body>>(
      std::piecewise_construct, std::make_tuple(std::move(body)),
      std::make_tuple(http::status::ok, version));
  res->set(http::field::content_type, type);
  res->set(http::field::cache_control, cache);
  res->set("X-Content-Type-Options", "nosniff");
  res->content_length(size);
  res->keep_alive(keep_alive);
  write_message(c, std::move(res), done);
}

}  // namespace hdeform::gateway

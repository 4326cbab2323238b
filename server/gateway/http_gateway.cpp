// gRPC-Web gateway: Boost.Beast HTTP/1.1 in front of the in-process gRPC channel.
//
// Model: one thread per HTTP connection doing synchronous Beast I/O (browsers keep at most
// six connections per origin; a WatchSession stream holds one for its lifetime). Every
// gRPC-Web call — unary, server-streaming, or a one-message client stream — is forwarded as
// raw bytes through grpc::GenericStub as a generic streaming call driven on a private
// CompletionQueue: write the request messages, WritesDone, relay every response message as
// one HTTP chunk (gRPC-Web data frame), then the trailers frame. No per-method code.
//
// Endpoints:
//   POST /hdeform.v1.Deformation/<Method>   application/grpc-web(+proto) — the API
//   POST /upload?filename=NAME              raw mesh bytes → client-streaming CreateSession;
//   POST /upload?library=NAME               (empty body) a library mesh; optional
//                                           &session_id=ID (CreateSessionHeader.session_id).
//                                           Reply: the Session as
//                                           binary protobuf (application/x-protobuf), or a
//                                           plain-text error with the mapped HTTP status.
//   GET  /healthz                           "ok"
//   GET  /…                                 static files from web_root (index.html for /)
#include "http_gateway.h"

#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <array>
#include <atomic>
#include <chrono>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <condition_variable>
#include <algorithm>
#include <filesystem>
#include <grpcpp/generic/generic_stub.h>
#include <list>
#include <mutex>
#include <optional>
#include <thread>

#include "grpc_web.h"
#include "hdeform/v1/deform.pb.h"

namespace hdeform::gateway {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

namespace {

constexpr std::string_view kServicePrefix = "/hdeform.v1.Deformation/";
constexpr std::size_t kUploadChunk = 1u << 20;  // CreateSession chunk size (< 4 MiB limit)
constexpr std::size_t kMaxConnections = 256;
constexpr std::size_t kMaxHeaderBytes = 16u << 10;

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
int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Decodes %XX escapes in a URL component ('+' stays '+'; it is a path, not a form). A '%' not
// followed by two hex digits stays as it is. Decodes once: "%252F" becomes "%2F", never "/".
// Never throws; the result may contain NUL, which callers that build paths must reject.
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

grpc::ByteBuffer to_byte_buffer(std::string_view bytes) {
  grpc::Slice slice(bytes.data(), bytes.size());
  return grpc::ByteBuffer(&slice, 1);
}

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

struct StaticLookup {
  http::status status = http::status::ok;  // ok, bad_request or not_found
  std::filesystem::path file;               // canonical, a regular file, when ok
};

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

// One generic gRPC call driven synchronously on its own completion queue. While waiting it
// polls the HTTP socket so a browser that goes away cancels a long server stream.
class GenericCall {
 public:
  GenericCall(grpc::GenericStub& stub, const std::string& method, int socket_fd)
      : socket_fd_(socket_fd) {
    stream_ = stub.PrepareCall(&context_, method, &cq_);
  }
  ~GenericCall() {
    cq_.Shutdown();
    void* tag;
    bool ok;
    while (cq_.Next(&tag, &ok)) {
    }
  }
  grpc::ClientContext& context() { return context_; }

  bool start() {
    if (!stream_) return false;
    stream_->StartCall(tag(1));
    return wait(tag(1));
  }
  bool write(std::string_view message) {
    stream_->Write(to_byte_buffer(message), tag(2));
    return wait(tag(2));
  }
  bool writes_done() {
    stream_->WritesDone(tag(3));
    return wait(tag(3));
  }
  bool read(grpc::ByteBuffer* out) {
    stream_->Read(out, tag(4));
    return wait(tag(4));
  }
  grpc::Status finish() {
    if (!stream_) return {grpc::StatusCode::INTERNAL, "gateway: could not prepare the call"};
    grpc::Status status;
    stream_->Finish(&status, tag(5));
    wait(tag(5));
    return status;
  }
  void cancel() { context_.TryCancel(); }

 private:
  static void* tag(std::intptr_t n) { return reinterpret_cast<void*>(n); }

  bool peer_gone() const {
    if (socket_fd_ < 0) return false;
    char byte;
    const auto n = ::recv(socket_fd_, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
    if (n == 0) return true;  // orderly shutdown by the browser
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return true;
    return false;
  }

  bool wait(void* expected) {
    for (;;) {
      void* got = nullptr;
      bool ok = false;
      const auto deadline = std::chrono::system_clock::now() + std::chrono::milliseconds(500);
      switch (cq_.AsyncNext(&got, &ok, deadline)) {
        case grpc::CompletionQueue::GOT_EVENT:
          if (got == expected) return ok;
          continue;  // cannot happen: one operation at a time
        case grpc::CompletionQueue::TIMEOUT:
          if (!cancelled_ && peer_gone()) {
            cancelled_ = true;
            context_.TryCancel();
          }
          continue;
        case grpc::CompletionQueue::SHUTDOWN:
          return false;
      }
    }
  }

  int socket_fd_;
  bool cancelled_ = false;
  grpc::ClientContext context_;
  grpc::CompletionQueue cq_;
  std::unique_ptr<grpc::GenericClientAsyncReaderWriter> stream_;
};

}  // namespace

struct HttpGateway::Impl {
  struct Connection {
    tcp::socket socket;
    std::thread thread;
    std::atomic<bool> done{false};
    std::mutex mu;                           // guards call
    grpc::ClientContext* call = nullptr;     // the call in progress, for cancellation
    explicit Connection(tcp::socket s) : socket(std::move(s)) {}
  };

  GatewayOptions options;
  std::filesystem::path web_root;
  std::shared_ptr<grpc::Channel> backend;
  grpc::GenericStub stub;
  asio::io_context ioc;
  tcp::acceptor acceptor{ioc};
  std::thread io_thread;
  std::atomic<bool> stopping{false};
  std::mutex mu;
  std::list<std::shared_ptr<Connection>> connections;
  int bound_port = 0;

  Impl(const GatewayOptions& opts, std::shared_ptr<grpc::Channel> channel)
      : options(opts), backend(channel), stub(channel) {
    if (!options.web_root.empty()) {
      std::error_code ec;
      web_root = std::filesystem::canonical(options.web_root, ec);
      if (ec || !std::filesystem::is_directory(web_root)) {
        spdlog::warn("hdeform-gateway: web root '{}' is not a folder; serving the API only",
                     options.web_root);
        web_root.clear();
      }
    }
    const tcp::endpoint endpoint(asio::ip::make_address(options.address),
                                 static_cast<unsigned short>(options.port));
    acceptor.open(endpoint.protocol());
    acceptor.set_option(asio::socket_base::reuse_address(true));
    acceptor.bind(endpoint);
    acceptor.listen(asio::socket_base::max_listen_connections);
    bound_port = acceptor.local_endpoint().port();
    do_accept();
    io_thread = std::thread([this] { ioc.run(); });
  }

  void do_accept() {
    acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
      if (ec || stopping) return;
      reap();
      std::lock_guard lock(mu);
      if (connections.size() >= kMaxConnections) {
        spdlog::warn("hdeform-gateway: connection limit ({}) reached", kMaxConnections);
        beast::error_code ignored;
        socket.close(ignored);
      } else {
        beast::error_code ignored;
        socket.set_option(tcp::no_delay(true), ignored);  // frames are small; send them now
        auto conn = std::make_shared<Connection>(std::move(socket));
        connections.push_back(conn);
        conn->thread = std::thread([this, conn] {
          try {
            serve(*conn);
          } catch (const std::exception& e) {
            spdlog::debug("hdeform-gateway: connection ended: {}", e.what());
          }
          beast::error_code ignored;
          conn->socket.shutdown(tcp::socket::shutdown_both, ignored);
          conn->done = true;
        });
      }
      do_accept();
    });
  }

  // Joins the threads of finished connections.
  void reap() {
    std::list<std::shared_ptr<Connection>> finished;
    {
      std::lock_guard lock(mu);
      for (auto it = connections.begin(); it != connections.end();) {
        if ((*it)->done) {
          finished.push_back(*it);
          it = connections.erase(it);
        } else {
          ++it;
        }
      }
    }
    for (auto& c : finished) {
      if (c->thread.joinable()) c->thread.join();
    }
  }

  void stop() {
    if (stopping.exchange(true)) return;
    asio::post(ioc, [this] {
      beast::error_code ignored;
      acceptor.close(ignored);
    });
    // Cancel the calls in progress; their handlers end each response with an UNAVAILABLE
    // trailers frame, so browsers see a clean "shutting down" rather than a cut stream.
    auto calls_in_progress = [this](bool cancel) {
      std::size_t busy = 0;
      std::lock_guard lock(mu);
      for (auto& c : connections) {
        std::lock_guard call_lock(c->mu);
        if (c->call) {
          ++busy;
          if (cancel) c->call->TryCancel();
        }
      }
      return busy;
    };
    calls_in_progress(true);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    while (calls_in_progress(false) > 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    {
      std::lock_guard lock(mu);
      for (auto& c : connections) {
        beast::error_code ignored;
        c->socket.shutdown(tcp::socket::shutdown_both, ignored);
      }
    }
    if (io_thread.joinable()) io_thread.join();
    std::list<std::shared_ptr<Connection>> all;
    {
      std::lock_guard lock(mu);
      all.swap(connections);
    }
    for (auto& c : all) {
      if (c->thread.joinable()) c->thread.join();
    }
  }

  // ---- one connection -------------------------------------------------------------------

  template <class Body>
  void send(Connection& conn, http::response<Body>& res) {
    res.prepare_payload();
    http::write(conn.socket, res);
  }

  void send_text(Connection& conn, http::status status, std::string text, unsigned version,
                 bool keep_alive) {
    http::response<http::string_body> res{status, version};
    res.set(http::field::content_type, "text/plain; charset=utf-8");
    res.set(http::field::cache_control, "no-store");
    res.keep_alive(keep_alive);
    res.body() = std::move(text);
    send(conn, res);
  }

  // Clears the connection's registered call (set by set_call) when the call's scope ends.
  struct CallRegistration {
    Impl* self;
    Connection& conn;
    ~CallRegistration() { self->set_call(conn, nullptr); }
  };

  // After an early answer (413) the client may still be sending the body. Closing with
  // unread data makes the kernel reset the connection, which can destroy the answer before
  // the client reads it; so half-close and drain for a bounded time first (as nginx's
  // lingering close does).
  static void linger_close(Connection& conn) {
    beast::error_code ec;
    conn.socket.shutdown(tcp::socket::shutdown_send, ec);
    timeval tv{0, 200 * 1000};
    ::setsockopt(conn.socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    std::array<char, 64 * 1024> sink;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    std::size_t drained = 0;
    while (drained < (256u << 20) && std::chrono::steady_clock::now() < deadline) {
      const std::size_t n = conn.socket.read_some(asio::buffer(sink), ec);
      if (ec) break;
      drained += n;
    }
  }

  void too_large(Connection& conn, const std::string& text, unsigned version) {
    send_text(conn, http::status::payload_too_large, text, version, false);
    linger_close(conn);
  }

  void serve(Connection& conn) {
    beast::flat_buffer buffer;
    for (;;) {
      http::request_parser<http::empty_body> header_parser;
      header_parser.header_limit(kMaxHeaderBytes);
      header_parser.body_limit(options.max_body_bytes);
      beast::error_code ec;
      http::read_header(conn.socket, buffer, header_parser, ec);
      if (ec == http::error::end_of_stream || ec == asio::error::eof || stopping) return;
      if (ec == http::error::body_limit) {  // Content-Length above the limit
        too_large(conn,
                  "request body too large: the limit is " +
                      std::to_string(options.max_body_bytes) + " bytes\n",
                  header_parser.get().version());
        return;
      }
      if (ec) {
        if (ec != asio::error::connection_reset && ec != asio::error::operation_aborted &&
            ec != asio::error::bad_descriptor) {
          send_text(conn, http::status::bad_request, "bad request: " + ec.message() + "\n", 11,
                    false);
        }
        return;
      }
      const auto& req = header_parser.get();
      const unsigned version = req.version();
      const std::string target(req.target());
      const auto qmark = target.find('?');
      const std::string path = url_decode(target.substr(0, qmark));
      const std::string query = qmark == std::string::npos ? "" : target.substr(qmark + 1);

      if (const auto length = header_parser.content_length();
          length && *length > options.max_body_bytes) {
        too_large(conn,
                  "request body too large: " + std::to_string(*length) + " bytes; the limit is " +
                      std::to_string(options.max_body_bytes) + " bytes\n",
                  version);
        return;  // the body is unread: close the connection
      }

      bool keep_alive = req.keep_alive();
      if (path.starts_with(kServicePrefix)) {
        if (req.method() != http::verb::post) {
          send_text(conn, http::status::method_not_allowed, "gRPC-Web calls must be POST\n",
                    version, false);
          return;
        }
        http::request_parser<http::string_body> parser(std::move(header_parser));
        parser.body_limit(options.max_body_bytes);
        http::read(conn.socket, buffer, parser, ec);
        if (ec == http::error::body_limit) {
          too_large(conn,
                    "request body too large: the limit is " +
                        std::to_string(options.max_body_bytes) + " bytes\n",
                    version);
          return;
        }
        if (ec) return;
        if (!grpc_web_call(conn, parser.get(), path)) return;
      } else if (path == "/upload") {
        if (req.method() != http::verb::post) {
          send_text(conn, http::status::method_not_allowed, "POST the mesh file to /upload\n",
                    version, false);
          return;
        }
        if (!upload(conn, buffer, std::move(header_parser), query)) return;
      } else if (req.method() == http::verb::get || req.method() == http::verb::head) {
        http::request_parser<http::string_body> parser(std::move(header_parser));
        http::read(conn.socket, buffer, parser, ec);  // GETs have no body; consume it anyway
        if (ec) return;
        static_file(conn, path, req.method() == http::verb::head, version, keep_alive);
      } else {
        send_text(conn, http::status::method_not_allowed, "method not allowed\n", version, false);
        return;
      }
      if (!keep_alive || stopping) return;
    }
  }

  void set_call(Connection& conn, grpc::ClientContext* ctx) {
    std::lock_guard lock(conn.mu);
    conn.call = ctx;
    if (ctx && stopping) ctx->TryCancel();
  }

  // Forwards one gRPC-Web call; returns false when the connection must close.
  bool grpc_web_call(Connection& conn, const http::request<http::string_body>& req,
                     const std::string& path) {
    const auto content_type = req[http::field::content_type];
    const unsigned version = req.version();
    if (!content_type.starts_with("application/grpc-web") ||
        content_type.starts_with("application/grpc-web-text")) {
      send_text(conn, http::status::unsupported_media_type,
                "expected Content-Type application/grpc-web or application/grpc-web+proto "
                "(binary; grpc-web-text is not supported)\n",
                version, req.keep_alive());
      return req.keep_alive();
    }

    http::response<http::empty_body> res{http::status::ok, version};
    res.set(http::field::content_type, "application/grpc-web+proto");
    res.set(http::field::cache_control, "no-store");
    res.keep_alive(req.keep_alive());
    res.chunked(true);
    http::response_serializer<http::empty_body> serializer{res};
    beast::error_code ec;

    const auto body = grpc_web::parse_frames(req.body());
    if (!body.error.empty()) {
      http::write_header(conn.socket, serializer, ec);
      if (ec) return false;
      const auto trailers = grpc_web::trailers_frame(
          grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "gateway: " + body.error));
      asio::write(conn.socket, http::make_chunk(asio::buffer(trailers)), ec);
      asio::write(conn.socket, http::make_chunk_last(), ec);
      return !ec && req.keep_alive();
    }

    GenericCall call(stub, path, conn.socket.native_handle());
    const auto timeout_header = req["grpc-timeout"];
    if (const auto timeout = grpc_web::parse_timeout(
            std::string_view(timeout_header.data(), timeout_header.size()))) {
      call.context().set_deadline(std::chrono::system_clock::now() + *timeout);
    }
    set_call(conn, &call.context());
    const CallRegistration unset{this, conn};

    const auto started = std::chrono::steady_clock::now();
    bool ok = call.start();
    for (std::size_t i = 0; ok && i < body.messages.size(); ++i) ok = call.write(body.messages[i]);
    if (ok) call.writes_done();

    http::write_header(conn.socket, serializer, ec);
    bool http_ok = !ec;
    grpc::ByteBuffer message;
    std::size_t count = 0;
    while (call.read(&message)) {
      if (!http_ok) continue;  // drain; the call is being cancelled
      std::vector<grpc::Slice> slices;
      if (!message.Dump(&slices).ok()) continue;
      const auto prefix =
          grpc_web::frame_prefix(grpc_web::kDataFlag, static_cast<std::uint32_t>(message.Length()));
      std::vector<asio::const_buffer> buffers;
      buffers.reserve(slices.size() + 1);
      buffers.emplace_back(prefix.data(), prefix.size());
      for (const auto& s : slices) buffers.emplace_back(s.begin(), s.size());
      asio::write(conn.socket, http::make_chunk(buffers), ec);
      ++count;
      if (ec) {
        http_ok = false;
        call.cancel();
      }
    }
    grpc::Status status = call.finish();
    if (stopping && status.error_code() == grpc::StatusCode::CANCELLED) {
      status = grpc::Status(grpc::StatusCode::UNAVAILABLE, "hdeform-server is shutting down");
    }
    spdlog::debug("hdeform-gateway: {} → {} ({} messages, {:.1f} ms)", path,
                  static_cast<int>(status.error_code()), count,
                  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() -
                                                            started)
                      .count());
    if (!http_ok) return false;
    const auto trailers = grpc_web::trailers_frame(status);
    asio::write(conn.socket, http::make_chunk(asio::buffer(trailers)), ec);
    if (ec) return false;
    asio::write(conn.socket, http::make_chunk_last(), ec);
    return !ec && req.keep_alive();
  }

  // POST /upload: the request body, streamed, becomes a client-streaming CreateSession.
  bool upload(Connection& conn, beast::flat_buffer& buffer,
              http::request_parser<http::empty_body>&& header_parser, const std::string& query) {
    const unsigned version = header_parser.get().version();
    const bool keep_alive = header_parser.get().keep_alive();
    const std::string filename = query_param(query, "filename");
    const std::string library = query_param(query, "library");
    if (filename.empty() == library.empty()) {
      send_text(conn, http::status::bad_request,
                "upload: give exactly one of ?filename=NAME (with the file as the body) or "
                "?library=NAME\n",
                version, false);
      return false;
    }

    hdeform::v1::CreateSessionRequest first;
    auto* header = first.mutable_header();
    if (!filename.empty()) {
      header->set_filename(filename);
      if (const auto length = header_parser.content_length()) {
        header->set_total_bytes(static_cast<std::int64_t>(*length));
      }
    } else {
      header->set_library_mesh(library);
    }
    // The client may choose the id (for load balancers that hash x-session-id).
    if (auto id = query_param(query, "session_id"); !id.empty()) header->set_session_id(id);

    GenericCall call(stub, std::string(kServicePrefix) + "CreateSession",
                     conn.socket.native_handle());
    set_call(conn, &call.context());
    const CallRegistration unset{this, conn};

    bool ok = call.start() && call.write(first.SerializeAsString());

    http::request_parser<http::buffer_body> parser(std::move(header_parser));
    parser.body_limit(options.max_body_bytes);
    std::string chunk(kUploadChunk, '\0');
    hdeform::v1::CreateSessionRequest part;
    std::string serialized;
    beast::error_code ec;
    bool body_ok = true;
    std::string body_error;
    while (!parser.is_done()) {
      parser.get().body().data = chunk.data();
      parser.get().body().size = chunk.size();
      http::read(conn.socket, buffer, parser, ec);
      if (ec == http::error::need_buffer) ec = {};
      if (ec) {
        body_ok = false;
        body_error = ec == http::error::body_limit
                         ? "upload too large: the limit is " +
                               std::to_string(options.max_body_bytes) + " bytes"
                         : "upload interrupted: " + ec.message();
        break;
      }
      const std::size_t n = chunk.size() - parser.get().body().size;
      if (n == 0 || !ok) continue;  // after a server-side failure keep reading to report it
      part.set_chunk(chunk.data(), n);
      part.SerializeToString(&serialized);
      ok = call.write(serialized);
    }
    if (!body_ok) {
      call.cancel();
      call.finish();
      if (ec == http::error::body_limit) {
        too_large(conn, body_error + "\n", version);
      }
      return false;
    }
    if (ok) call.writes_done();
    grpc::ByteBuffer reply;
    std::string reply_bytes;
    if (call.read(&reply)) {
      std::vector<grpc::Slice> slices;
      if (reply.Dump(&slices).ok()) {
        for (const auto& s : slices) reply_bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
      }
    }
    const grpc::Status status = call.finish();
    if (!status.ok()) {
      http::response<http::string_body> res{
          static_cast<http::status>(grpc_web::http_status_for(status.error_code())), version};
      res.set(http::field::content_type, "text/plain; charset=utf-8");
      res.set(http::field::cache_control, "no-store");
      res.set("grpc-status", std::to_string(static_cast<int>(status.error_code())));
      res.set("grpc-message", grpc_web::percent_encode(status.error_message()));
      res.keep_alive(keep_alive);
      res.body() = status.error_message() + "\n";
      send(conn, res);
      return keep_alive;
    }
    http::response<http::string_body> res{http::status::ok, version};
    res.set(http::field::content_type, "application/x-protobuf");
    res.set(http::field::cache_control, "no-store");
    res.set("grpc-status", "0");
    res.keep_alive(keep_alive);
    res.body() = std::move(reply_bytes);
    send(conn, res);
    return keep_alive;
  }

  void static_file(Connection& conn, const std::string& path, bool head, unsigned version,
                   bool keep_alive) {
    if (path == "/healthz") {
      send_text(conn, http::status::ok, "ok\n", version, keep_alive);
      return;
    }
    if (web_root.empty()) {
      send_text(conn, http::status::not_found,
                "not found (this server was started without the web viewer)\n", version,
                keep_alive);
      return;
    }
    const auto found = find_static(web_root, path);
    if (found.status == http::status::bad_request) {
      send_text(conn, http::status::bad_request, "bad path\n", version, keep_alive);
      return;
    }
    http::file_body::value_type body;
    beast::error_code ec;
    if (found.status == http::status::ok) body.open(found.file.c_str(), beast::file_mode::scan, ec);
    if (found.status != http::status::ok || ec) {
      send_text(conn, http::status::not_found, "not found\n", version, keep_alive);
      return;
    }
    const auto& file = found.file;
    const auto size = body.size();
    const bool immutable = path.starts_with("/assets/");  // vite's content-hashed files
    const auto type_sv = mime_type(file.string());
    const beast::string_view type(type_sv.data(), type_sv.size());
    const auto cache = immutable ? "public, max-age=31536000, immutable" : "no-cache";
    if (head) {
      http::response<http::empty_body> res{http::status::ok, version};
      res.set(http::field::content_type, type);
      res.set(http::field::cache_control, cache);
      res.content_length(size);
      res.keep_alive(keep_alive);
      http::write(conn.socket, res);
      return;
    }
    http::response<http::file_body> res{std::piecewise_construct, std::make_tuple(std::move(body)),
                                        std::make_tuple(http::status::ok, version)};
    res.set(http::field::content_type, type);
    res.set(http::field::cache_control, cache);
    res.set("X-Content-Type-Options", "nosniff");
    res.content_length(size);
    res.keep_alive(keep_alive);
    http::write(conn.socket, res);
  }
};

HttpGateway::HttpGateway(const GatewayOptions& options, std::shared_ptr<grpc::Channel> backend)
    : impl_(std::make_unique<Impl>(options, std::move(backend))) {
  spdlog::debug("hdeform-gateway listening on {}:{}{}", options.address, impl_->bound_port,
               impl_->web_root.empty() ? " (API only)"
                                       : " (viewer: " + impl_->web_root.string() + ")");
}

HttpGateway::~HttpGateway() { stop(); }

int HttpGateway::port() const { return impl_->bound_port; }

void HttpGateway::stop() {
  if (impl_) impl_->stop();
}

}  // namespace hdeform::gateway

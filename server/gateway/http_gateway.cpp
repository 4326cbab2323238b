// gRPC-Web gateway: Boost.Beast HTTP/1.1 in front of the in-process gRPC channel.
//
// Model. Waiting costs no thread: a few I/O threads (GatewayOptions::threads) run one
// io_context that accepts connections and reads request headers asynchronously, each
// connection on its own strand with Beast's tcp_stream deadlines (header_timeout for a whole
// header, idle_timeout between keep-alive requests). Only when a complete request header has
// arrived is the connection handed to a worker thread for that one request; afterwards a
// keep-alive connection goes back to waiting on the io_context. So two separate caps bound the
// cost: max_idle_connections for waiting connections (the oldest is closed when full, so idle
// clients cannot lock others out) and max_connections for requests in progress (503 above).
// Workers write in blocking style, but each socket operation is an asynchronous Beast
// operation with a stall_timeout deadline that the worker waits for (await_op), so a stalled
// body or an unread response ends the connection and stop() can abort any of them.
//
// Every gRPC-Web call — unary, server-streaming, or a one-message client stream — is forwarded
// as raw bytes through grpc::GenericStub as a generic streaming call driven on a private
// CompletionQueue: write the request messages, WritesDone, relay every response message as
// one HTTP chunk (gRPC-Web data frame), then the trailers frame. No per-method code. A server
// stream may stay quiet for any time: no socket operation is pending while it waits.
//
// TLS (GatewayOptions::tls_cert_file/tls_key_file): the same model over HTTPS. A connection's
// Stream is plain TCP or TLS over it, with the deadlines on the TCP layer either way; a new TLS
// connection's handshake and its first request header share one header_timeout, and a failed
// handshake (a plain-HTTP client, an untrusted client certificate, a silent peer) is logged at
// debug and closes the connection. TLS 1.2 at least; with tls_client_ca_file every client must
// present a certificate signed by that CA.
//
// The request header Authorization (every value) is passed on as gRPC metadata
// `authorization` to every gRPC-Web call and to /upload's CreateSession (capability tokens).
//
// Safe to expose: static files are served only if their canonical path is a regular file
// inside the canonical web root; a POST whose Origin is not the request's own host is refused
// (403), and /upload also needs a header a cross-site page cannot send without a CORS
// preflight (which this server never approves); accept() errors (EMFILE, ECONNABORTED, …)
// pause accepting briefly, never end it.
//
// Endpoints:
//   POST /hdeform.v1.Deformation/<Method>   application/grpc-web(+proto) — the API
//   POST /upload?filename=NAME              raw mesh bytes → client-streaming CreateSession;
//   POST /upload?library=NAME               (empty body) a library mesh; optional
//                                           &session_id=ID (CreateSessionHeader.session_id),
//                                           &repair=TOL (CreateSessionHeader.repair with
//                                           merge_tolerance TOL; 0: equal positions).
//                                           Needs the header X-Session-Id or X-Hdeform-Upload.
//                                           Reply: the Session as
//                                           binary protobuf (application/x-protobuf), or a
//                                           plain-text error with the mapped HTTP status.
//   GET  /healthz                           "ok"
//   GET  /…                                 static files from web_root (index.html for /)
#include "gateway/http_gateway.h"

#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <future>
#include <grpcpp/generic/generic_stub.h>
#include <latch>
#include <list>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "common/tls_files.h"
#include "gateway/grpc_web.h"
#include "gateway/request_checks.h"
#include "hdeform/v1/deform.pb.h"

namespace hdeform::gateway {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;
using std::chrono::milliseconds;

namespace {

constexpr std::string_view kServicePrefix = "/hdeform.v1.Deformation/";
constexpr std::size_t kUploadChunk = 1u << 20;  // CreateSession chunk size (< 4 MiB limit)
constexpr std::size_t kMaxHeaderBytes = 16u << 10;
constexpr std::size_t kFirstRead = 4u << 10;    // first bytes of a keep-alive request
constexpr milliseconds kLingerTime{2000};       // lingering close: at most this long …
constexpr std::size_t kLingerBytes = 256u << 20;  // … and this many bytes drained
constexpr std::size_t kDrainChunk = 64u << 10;
constexpr milliseconds kMinAcceptPause{10};     // accept() failures: pause, doubling …
constexpr milliseconds kMaxAcceptPause{1000};   // … up to this

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

// ---- TLS ------------------------------------------------------------------------------------

// A connection's byte stream: plain TCP, or TLS over TCP. Either way one beast::tcp_stream
// owns the socket and carries the deadlines (expires_after), so the rest of the gateway is the
// same for both. Like tcp_stream it is not thread-safe: use it on its strand only.
class Stream {
 public:
  using executor_type = beast::tcp_stream::executor_type;

  Stream(tcp::socket socket, asio::ssl::context* tls) {
    if (tls) {
      tls_.emplace(std::move(socket), *tls);
    } else {
      plain_.emplace(std::move(socket));
    }
  }
  bool is_tls() const { return tls_.has_value(); }
  beast::tcp_stream& tcp_layer() { return tls_ ? tls_->next_layer() : *plain_; }
  executor_type get_executor() { return tcp_layer().get_executor(); }
  tcp::socket& socket() { return tcp_layer().socket(); }
  void expires_after(milliseconds timeout) { tcp_layer().expires_after(timeout); }
  void close() { tcp_layer().close(); }  // also cancels its operations; no TLS close_notify

  template <class Handler>
  void async_handshake(Handler&& handler) {
    tls_->async_handshake(asio::ssl::stream_base::server, std::forward<Handler>(handler));
  }
  template <class MutableBuffers, class Token>
  auto async_read_some(const MutableBuffers& buffers, Token&& token) {
    return asio::async_initiate<Token, void(beast::error_code, std::size_t)>(
        [this](auto handler, const MutableBuffers& b) {
          if (tls_) {
            tls_->async_read_some(b, std::move(handler));
          } else {
            plain_->async_read_some(b, std::move(handler));
          }
        },
        token, buffers);
  }
  template <class ConstBuffers, class Token>
  auto async_write_some(const ConstBuffers& buffers, Token&& token) {
    return asio::async_initiate<Token, void(beast::error_code, std::size_t)>(
        [this](auto handler, const ConstBuffers& b) {
          if (tls_) {
            tls_->async_write_some(b, std::move(handler));
          } else {
            plain_->async_write_some(b, std::move(handler));
          }
        },
        token, buffers);
  }

 private:
  std::optional<beast::tcp_stream> plain_;
  std::optional<beast::ssl_stream<beast::tcp_stream>> tls_;
};

// The server's TLS context (TLS 1.2 at least) from files load_tls_files has checked.
std::unique_ptr<asio::ssl::context> make_tls_context(const GatewayOptions& o) {
  const auto files = service::load_tls_files("hdeform-gateway", o.tls_cert_file, o.tls_key_file,
                                             o.tls_client_ca_file);
  if (!files) return nullptr;
  auto ctx = std::make_unique<asio::ssl::context>(asio::ssl::context::tls_server);
  ctx->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::single_dh_use);
  const auto fail = [](const std::string& why) {
    ERR_clear_error();
    throw std::runtime_error("hdeform-gateway: " + why);
  };
  if (SSL_CTX_set_min_proto_version(ctx->native_handle(), TLS1_2_VERSION) != 1)
    fail("cannot require TLS 1.2");
  beast::error_code ec;
  ctx->use_certificate_chain(asio::buffer(files->cert_chain), ec);
  if (ec) fail("cannot use the certificate in '" + o.tls_cert_file + "': " + ec.message());
  ctx->use_private_key(asio::buffer(files->private_key), asio::ssl::context::pem, ec);
  if (ec) fail("cannot use the private key in '" + o.tls_key_file + "': " + ec.message());
  if (!files->client_ca.empty()) {
    // Trust every certificate in the file for client certificates, and name them to clients.
    std::unique_ptr<BIO, decltype(&BIO_free)> bio(
        BIO_new_mem_buf(files->client_ca.data(), static_cast<int>(files->client_ca.size())),
        BIO_free);
    while (X509* x = PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr)) {
      const bool ok = X509_STORE_add_cert(SSL_CTX_get_cert_store(ctx->native_handle()), x) == 1 &&
                      SSL_CTX_add_client_CA(ctx->native_handle(), x) == 1;
      X509_free(x);
      if (!ok) fail("cannot use a certificate in '" + o.tls_client_ca_file + "'");
    }
    ctx->set_verify_mode(asio::ssl::verify_peer | asio::ssl::verify_fail_if_no_peer_cert);
  }
  ERR_clear_error();
  return ctx;
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

// The request's Authorization values become gRPC metadata `authorization` (capability
// tokens for the service). gRPC only accepts printable ASCII there; another value is left out,
// so the service sees no token rather than the call failing in gRPC. The header parser bounds
// the whole header (kMaxHeaderBytes), so the values are bounded too.
void forward_authorization(const http::request_header<>& req, grpc::ClientContext& context) {
  for (auto [it, end] = req.equal_range(http::field::authorization); it != end; ++it) {
    const auto value = it->value();
    if (std::all_of(value.begin(), value.end(), [](char ch) { return ch >= 0x20 && ch <= 0x7e; })) {
      context.AddMetadata("authorization", std::string(value.data(), value.size()));
    } else {
      spdlog::debug("hdeform-gateway: an Authorization value with non-ASCII bytes is not passed on");
    }
  }
}

// One generic gRPC call driven synchronously on its own completion queue. While waiting it
// polls the HTTP socket so a browser that goes away cancels a long server stream.
class GenericCall {
 public:
  // `request` is the HTTP request header (its Authorization is forwarded); `tls`: the socket
  // carries TLS, so a peer that went away is seen by its FIN even with unread bytes queued.
  // `deadline`: from the request's grpc-timeout; like the metadata it must be set before the
  // call is prepared (gRPC reads both there).
  GenericCall(grpc::GenericStub& stub, const std::string& method, int socket_fd, bool tls,
              const http::request_header<>& request,
              std::optional<std::chrono::system_clock::time_point> deadline = std::nullopt)
      : socket_fd_(socket_fd), tls_(tls) {
    forward_authorization(request, context_);
    if (deadline) context_.set_deadline(*deadline);
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
    if (tls_) {
      // A TLS client's close_notify stays unread in the socket, so a peek would never see the
      // end of the stream: ask the kernel whether the peer shut its side instead.
      pollfd p{socket_fd_, POLLRDHUP, 0};
      return ::poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR)) != 0;
    }
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
  bool tls_;
  bool cancelled_ = false;
  grpc::ClientContext context_;
  grpc::CompletionQueue cq_;
  std::unique_ptr<grpc::GenericClientAsyncReaderWriter> stream_;
};


// A call the backend would never answer, refused at once: a malformed body, an unknown
// method, or a unary method given other than one message (the server would wait for the
// client to half-close a stream it does not expect, holding the request slot meanwhile).
std::optional<grpc::Status> body_refusal(std::string_view path, const grpc_web::ParsedBody& body) {
  if (!body.error.empty()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "gateway: " + body.error);
  }
  const auto name = path.substr(kServicePrefix.size());
  const auto* service =
      hdeform::v1::CreateSessionRequest::descriptor()->file()->FindServiceByName("Deformation");
  const auto* method = service->FindMethodByName(std::string(name));
  if (!method) {
    return grpc::Status(grpc::StatusCode::UNIMPLEMENTED,
                        "gateway: " + std::string(service->full_name()) + " has no method '" +
                            std::string(name.substr(0, 100)) + "'");
  }
  if (!method->client_streaming() && body.messages.size() != 1) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "gateway: " + std::string(name) + " takes exactly one request message; " +
                            "the body holds " + std::to_string(body.messages.size()));
  }
  return std::nullopt;
}

http::response<http::string_body> text_response(http::status status, std::string text,
                                                unsigned version, bool keep_alive) {
  http::response<http::string_body> res{status, version};
  res.set(http::field::content_type, "text/plain; charset=utf-8");
  res.set(http::field::cache_control, "no-store");
  res.keep_alive(keep_alive);
  res.body() = std::move(text);
  res.prepare_payload();
  return res;
}

std::string too_large_text(std::size_t limit) {
  return "request body too large: the limit is " + std::to_string(limit) + " bytes\n";
}

}  // namespace

struct HttpGateway::Impl {
  // One TCP connection. Stream is not thread-safe, so every operation on it starts on
  // its strand (its executor); worker threads get there through await_op.
  struct Connection {
    Connection(tcp::socket socket, asio::ssl::context* tls) : stream(std::move(socket), tls) {}
    Stream stream;                                                 // plain TCP or TLS
    bool handshaken = false;                                       // TLS: handshake done
    beast::flat_buffer buffer;                                     // read ahead of the parser
    std::optional<http::request_parser<http::empty_body>> header;  // the request being read
    bool served = false;  // answered a request before: the next one may keep it idle longer
    // Guarded by Impl::mu: which list holds the connection, and where.
    enum class Phase { none, waiting, active } phase = Phase::none;
    std::list<std::shared_ptr<Connection>>::iterator slot;
    // Guarded by call_mu: the gRPC call in progress, which stop() cancels.
    std::mutex call_mu;
    grpc::ClientContext* call = nullptr;
  };
  using ConnectionPtr = std::shared_ptr<Connection>;
  using Phase = Connection::Phase;

  // A worker thread; joined by the next start_worker (or stop) once it marked itself done.
  struct Worker {
    std::thread thread;
    std::atomic<bool> done{false};
  };

  // What becomes of a connection after its worker answered a request.
  enum class After { keep_alive, close, linger };

  GatewayOptions options;
  HostPolicy hosts;
  std::filesystem::path web_root;  // canonical; empty = API only
  grpc::GenericStub stub;
  std::unique_ptr<asio::ssl::context> tls;  // null: plain HTTP
  asio::io_context ioc;
  // Keeps ioc.run() going while no connection is pending: a worker may start an operation
  // at any time until stop() has joined it.
  asio::executor_work_guard<asio::io_context::executor_type> work{ioc.get_executor()};
  tcp::acceptor acceptor{asio::make_strand(ioc)};
  asio::steady_timer accept_pause{acceptor.get_executor()};
  milliseconds accept_delay{0};      // acceptor strand only
  std::size_t accept_failures = 0;   // acceptor strand only (for log throttling)
  std::vector<std::thread> io_threads;
  std::atomic<bool> stopping{false};
  std::mutex mu;                     // guards the lists below and Connection::phase
  std::list<ConnectionPtr> waiting;  // waiting for a request header, oldest first
  std::list<ConnectionPtr> active;   // a worker is answering their request
  std::list<std::unique_ptr<Worker>> workers;
  // Every connection, in any phase (also lingering or answering 503), so that stop() can
  // close them all; expired entries are pruned as it grows.
  std::list<std::weak_ptr<Connection>> all;
  std::size_t prune_at = 64;
  int bound_port = 0;

  Impl(const GatewayOptions& opts, std::shared_ptr<grpc::Channel> channel)
      : options(opts), hosts(opts.allowed_hosts), stub(std::move(channel)),
        tls(make_tls_context(opts)) {
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
    asio::dispatch(acceptor.get_executor(), [this] { do_accept(); });
    for (int i = 0; i < std::max(1, options.threads); ++i) {
      io_threads.emplace_back([this] { run_io(); });
    }
  }

  // An exception escaping a handler must not end an I/O thread (nor the process).
  void run_io() {
    for (;;) {
      try {
        ioc.run();
        return;
      } catch (const std::exception& e) {
        spdlog::error("hdeform-gateway: I/O handler failed: {}", e.what());
      }
    }
  }

  // ---- accepting (acceptor strand) -----------------------------------------------------------

  void do_accept() {
    acceptor.async_accept(asio::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
      if (stopping || ec == asio::error::operation_aborted) return;
      if (ec) {
        accept_failed(ec);
        return;
      }
      accept_delay = milliseconds(0);
      accept_failures = 0;
      beast::error_code ignored;
      socket.set_option(tcp::no_delay(true), ignored);  // frames are small; send them now
      auto c = std::make_shared<Connection>(std::move(socket), tls.get());
      remember(c);
      asio::dispatch(c->stream.get_executor(), [this, c] { await_request(c); });
      do_accept();
    });
  }

  // accept() failed. A peer that gave up during the handshake concerns that peer only: go on.
  // Otherwise (out of descriptors, memory, …) the listener stays readable and retrying at once
  // would spin: pause, doubling up to a second. Out of descriptors, also close the oldest
  // waiting connection, so idle clients cannot hold every descriptor. Never stop accepting.
  void accept_failed(const beast::error_code& ec) {
    if (ec == asio::error::connection_aborted || ec == asio::error::connection_reset) {
      do_accept();
      return;
    }
    if (ec == boost::system::errc::too_many_files_open ||
        ec == boost::system::errc::too_many_files_open_in_system) {
      evict_oldest_waiting();
    }
    accept_delay = std::clamp(accept_delay * 2, kMinAcceptPause, kMaxAcceptPause);
    if (accept_failures++ % 100 == 0) {
      spdlog::warn("hdeform-gateway: accept failed ({}); retrying in {} ms", ec.message(),
                   accept_delay.count());
    }
    accept_pause.expires_after(accept_delay);
    accept_pause.async_wait([this](beast::error_code wait_ec) {
      if (!wait_ec && !stopping) do_accept();
    });
  }

  // ---- bookkeeping (any thread) --------------------------------------------------------------

  void remember(const ConnectionPtr& c) {
    std::lock_guard lock(mu);
    all.push_back(c);
    if (all.size() >= prune_at) {
      all.remove_if([](const auto& weak) { return weak.expired(); });
      prune_at = std::max<std::size_t>(64, 2 * all.size());
    }
  }

  // Registers a connection as waiting for a request; false when stopping. Closes the oldest
  // waiting connection when the cap is reached.
  bool enter_waiting(const ConnectionPtr& c) {
    std::lock_guard lock(mu);
    if (stopping) return false;
    if (waiting.size() >= std::max<std::size_t>(1, options.max_idle_connections)) evict_locked();
    c->slot = waiting.insert(waiting.end(), c);
    c->phase = Phase::waiting;
    return true;
  }

  // Registers a request in progress; false when stopping or at the cap.
  bool enter_active(const ConnectionPtr& c) {
    std::lock_guard lock(mu);
    if (stopping || active.size() >= options.max_connections) return false;
    c->slot = active.insert(active.end(), c);
    c->phase = Phase::active;
    return true;
  }

  // Unregisters; returns the phase it was in (none: evicted meanwhile).
  Phase leave(Connection& c) {
    std::lock_guard lock(mu);
    const Phase was = c.phase;
    if (was == Phase::waiting) waiting.erase(c.slot);
    if (was == Phase::active) active.erase(c.slot);
    c.phase = Phase::none;
    return was;
  }

  void evict_oldest_waiting() {
    std::lock_guard lock(mu);
    evict_locked();
  }

  void evict_locked() {
    if (waiting.empty()) return;
    ConnectionPtr victim = std::move(waiting.front());
    waiting.pop_front();
    victim->phase = Phase::none;
    asio::post(victim->stream.get_executor(), [victim] { close(*victim); });
  }

  static void close(Connection& c) { c.stream.close(); }  // also cancels its operations

  // ---- waiting for a request (I/O threads, on the connection's strand) -----------------------

  void await_request(const ConnectionPtr& c) {
    if (!enter_waiting(c)) {
      close(*c);
      return;
    }
    if (c->stream.is_tls() && !c->handshaken) {
      // A new TLS connection: the handshake and then the first request header must arrive
      // within one header_timeout together (a peer that never says hello is closed by it).
      c->stream.expires_after(options.header_timeout);
      c->stream.async_handshake([this, c](beast::error_code ec) {
        if (ec) {
          spdlog::debug("hdeform-gateway: TLS handshake failed: {}", ec.message());
          leave(*c);
          close(*c);
          return;
        }
        c->handshaken = true;
        read_header(c, /*fresh_deadline=*/false);
      });
      return;
    }
    if (!c->served || c->buffer.size() > 0) {  // a new connection, or a pipelined request
      read_header(c);
      return;
    }
    // Keep-alive: the next request may take idle_timeout to begin; from its first byte on,
    // its header has header_timeout to arrive whole.
    c->stream.expires_after(options.idle_timeout);
    c->stream.async_read_some(c->buffer.prepare(kFirstRead),
                              [this, c](beast::error_code ec, std::size_t n) {
                                c->buffer.commit(n);
                                if (ec) {
                                  leave(*c);
                                  close(*c);
                                  return;
                                }
                                read_header(c);
                              });
  }

  // `fresh_deadline` false: the deadline already running (a TLS handshake's) covers the header.
  void read_header(const ConnectionPtr& c, bool fresh_deadline = true) {
    c->header.emplace();
    c->header->header_limit(kMaxHeaderBytes);
    c->header->body_limit(options.max_body_bytes);  // a larger Content-Length fails: 413
    if (fresh_deadline) c->stream.expires_after(options.header_timeout);
    http::async_read_header(c->stream, c->buffer, *c->header,
                            [this, c](beast::error_code ec, std::size_t) { on_header(c, ec); });
  }

  void on_header(const ConnectionPtr& c, beast::error_code ec) {
    if (leave(*c) != Phase::waiting || stopping) {  // evicted, or shutting down
      close(*c);
      return;
    }
    const unsigned version = c->header->get().version() ? c->header->get().version() : 11;
    if (ec == http::error::body_limit) {
      reply_and_close(c, http::status::payload_too_large, too_large_text(options.max_body_bytes),
                      version);
      return;
    }
    if (ec) {
      // Timeouts, resets, a peer that closed: just drop. A malformed request gets a 400.
      const bool malformed = ec.category() == http::make_error_code(http::error::bad_target).category() &&
                             ec != http::error::end_of_stream && ec != http::error::partial_message;
      if (malformed) {
        reply_and_close(c, http::status::bad_request, "bad request: " + ec.message() + "\n", 11);
      } else {
        close(*c);
      }
      return;
    }
    // Refused before any worker, file or call: a smuggling attempt, a rebound DNS name.
    if (auto why = framing_refusal(c->header->get()); !why.empty()) {
      reply_and_close(c, http::status::bad_request, std::move(why), version);
      return;
    }
    if (auto why = host_refusal(c->header->get(), hosts); !why.empty()) {
      spdlog::debug("hdeform-gateway: {}", why);
      reply_and_close(c, http::status::misdirected_request, std::move(why), version);
      return;
    }
    if (!enter_active(c)) {
      reply_and_close(c, http::status::service_unavailable,
                      "hdeform-gateway is busy: " + std::to_string(options.max_connections) +
                          " requests in progress; try again shortly\n",
                      version);
      return;
    }
    start_worker(c);
  }

  // An early answer from the strand (the request was not handed to a worker).
  void reply_and_close(const ConnectionPtr& c, http::status status, std::string text,
                       unsigned version) {
    auto res = std::make_shared<http::response<http::string_body>>(
        text_response(status, std::move(text), version, false));
    if (status == http::status::service_unavailable) res->set(http::field::retry_after, "1");
    c->stream.expires_after(options.stall_timeout);
    http::async_write(c->stream, *res, [this, c, res](beast::error_code ec, std::size_t) {
      if (ec) {
        close(*c);
      } else {
        linger(c);
      }
    });
  }

  // After an early answer the client may still be sending a body. Closing with unread data
  // makes the kernel reset the connection, which can destroy the answer before the client
  // reads it; so half-close and drain for a bounded time and size first (as nginx's
  // lingering close does). Over TLS the raw bytes are drained, undecrypted.
  void linger(const ConnectionPtr& c) {
    beast::error_code ignored;
    c->stream.socket().shutdown(tcp::socket::shutdown_send, ignored);
    c->stream.expires_after(kLingerTime);
    drain(c, 0);
  }

  void drain(const ConnectionPtr& c, std::size_t drained) {
    c->buffer.clear();
    c->stream.tcp_layer().async_read_some(
        c->buffer.prepare(kDrainChunk), [this, c, drained](beast::error_code ec, std::size_t n) {
          if (ec || drained + n >= kLingerBytes) {
            close(*c);
          } else {
            drain(c, drained + n);
          }
        });
  }

  // ---- workers -------------------------------------------------------------------------------

  void start_worker(const ConnectionPtr& c) {
    join_finished_workers();
    try {
      std::lock_guard lock(mu);
      auto& worker = workers.emplace_back(std::make_unique<Worker>());
      worker->thread = std::thread([this, c, w = worker.get()] {
        serve(c);
        w->done = true;
      });
    } catch (const std::exception& e) {  // no thread to be had
      {
        std::lock_guard lock(mu);
        if (!workers.empty() && !workers.back()->thread.joinable()) workers.pop_back();
      }
      leave(*c);
      spdlog::warn("hdeform-gateway: cannot start a worker: {}", e.what());
      reply_and_close(c, http::status::service_unavailable,
                      "hdeform-gateway cannot take more requests now; try again shortly\n", 11);
    }
  }

  void join_finished_workers() {
    std::list<std::unique_ptr<Worker>> finished;
    {
      std::lock_guard lock(mu);
      for (auto it = workers.begin(); it != workers.end();) {
        const auto next = std::next(it);
        if ((*it)->done) finished.splice(finished.end(), workers, it);
        it = next;
      }
    }
    for (auto& w : finished) w->thread.join();
  }

  // A worker: answers the one request whose header arrived, then hands the connection back.
  void serve(const ConnectionPtr& c) {
    After after = After::close;
    try {
      after = handle(*c);
    } catch (const std::exception& e) {
      spdlog::debug("hdeform-gateway: connection ended: {}", e.what());
    }
    leave(*c);
    if (after == After::keep_alive && !stopping) {
      c->served = true;
      asio::post(c->stream.get_executor(), [this, c] { await_request(c); });
    } else if (after == After::linger && !stopping) {
      asio::post(c->stream.get_executor(), [this, c] { linger(c); });
    } else {
      asio::post(c->stream.get_executor(), [c] { close(*c); });
    }
  }

  // Runs one asynchronous operation on the connection's strand with a fresh deadline and
  // waits for it. Worker threads only: an I/O thread waiting here could deadlock.
  template <class Start>
  beast::error_code await_op(Connection& c, milliseconds timeout, Start&& start) {
    std::promise<beast::error_code> result;
    auto done = result.get_future();
    asio::dispatch(c.stream.get_executor(), [&] {
      c.stream.expires_after(timeout);
      start([&result](beast::error_code ec, std::size_t) { result.set_value(ec); });
    });
    return done.get();
  }

  // Writes a whole response, each piece within stall_timeout (a large file to a slow but
  // reading client is fine; a client that stops reading is dropped).
  template <class Body>
  bool write_message(Connection& c, http::response<Body>& res) {
    http::response_serializer<Body> serializer{res};
    while (!serializer.is_done()) {
      const auto ec = await_op(c, options.stall_timeout, [&](auto done) {
        http::async_write_some(c.stream, serializer, std::move(done));
      });
      if (ec) return false;
    }
    return true;
  }

  bool send_text(Connection& c, http::status status, std::string text, unsigned version,
                 bool keep_alive) {
    auto res = text_response(status, std::move(text), version, keep_alive);
    return write_message(c, res);
  }

  // Answers and closes before the request body was read (it may still be arriving).
  After refuse(Connection& c, http::status status, std::string text, unsigned version) {
    send_text(c, status, std::move(text), version, false);
    return After::linger;
  }

  // Reads the rest of a request body; each read may wait stall_timeout for bytes.
  template <class Parser>
  beast::error_code read_body(Connection& c, Parser& parser) {
    while (!parser.is_done()) {
      const auto ec = await_op(c, options.stall_timeout, [&](auto done) {
        http::async_read_some(c.stream, c.buffer, parser, std::move(done));
      });
      if (ec) return ec;
    }
    return {};
  }

  template <class Buffers>
  bool write_chunk(Connection& c, const Buffers& buffers) {
    return !await_op(c, options.stall_timeout, [&](auto done) {
      asio::async_write(c.stream, http::make_chunk(buffers), std::move(done));
    });
  }

  bool write_last_chunk(Connection& c) {
    return !await_op(c, options.stall_timeout, [&](auto done) {
      asio::async_write(c.stream, http::make_chunk_last(), std::move(done));
    });
  }

  // ---- one request (worker thread) -----------------------------------------------------------

  After handle(Connection& c) {
    const auto& req = c.header->get();
    const auto method = req.method();
    const unsigned version = req.version();
    const bool keep_alive = req.keep_alive();
    const std::string target(req.target());
    const auto qmark = target.find('?');
    const std::string path = url_decode(std::string_view(target).substr(0, qmark));
    const std::string query = qmark == std::string::npos ? "" : target.substr(qmark + 1);

    if (method == http::verb::post) {
      if (auto why = cross_site_refusal(req); !why.empty()) {
        spdlog::debug("hdeform-gateway: {}", why);
        return refuse(c, http::status::forbidden, std::move(why), version);
      }
    }
    if (path.starts_with(kServicePrefix)) {
      if (method != http::verb::post) {
        return refuse(c, http::status::method_not_allowed, "gRPC-Web calls must be POST\n", version);
      }
      return grpc_web_call(c, path);
    }
    if (path == "/upload") {
      if (method != http::verb::post) {
        return refuse(c, http::status::method_not_allowed, "POST the mesh file to /upload\n", version);
      }
      if (!has_upload_header(req)) {
        return refuse(c, http::status::forbidden,
                      "upload refused: send the header X-Hdeform-Upload: 1 (or X-Session-Id) with "
                      "POST /upload; a page on another site cannot add it\n",
                      version);
      }
      return upload(c, query);
    }
    if (method == http::verb::get || method == http::verb::head) {
      http::request_parser<http::string_body> parser(std::move(*c.header));  // `req` ends here
      if (read_body(c, parser)) return After::close;  // GETs have no body; consume it anyway
      if (!static_file(c, path, method == http::verb::head, version, keep_alive)) return After::close;
      return keep_alive ? After::keep_alive : After::close;
    }
    return refuse(c, http::status::method_not_allowed, "method not allowed\n", version);
  }

  void set_call(Connection& c, grpc::ClientContext* ctx) {
    std::lock_guard lock(c.call_mu);
    c.call = ctx;
    if (ctx && stopping) ctx->TryCancel();
  }

  // Clears the connection's registered call (set by set_call) when the call's scope ends.
  struct CallRegistration {
    Impl* self;
    Connection& conn;
    ~CallRegistration() { self->set_call(conn, nullptr); }
  };

  // Forwards one gRPC-Web call.
  After grpc_web_call(Connection& c, const std::string& path) {
    http::request_parser<http::string_body> parser(std::move(*c.header));
    parser.body_limit(options.max_body_bytes);
    if (const auto ec = read_body(c, parser)) {
      if (ec != http::error::body_limit) return After::close;
      return refuse(c, http::status::payload_too_large, too_large_text(options.max_body_bytes),
                    parser.get().version());
    }
    const auto& req = parser.get();
    const unsigned version = req.version();
    const After next = req.keep_alive() ? After::keep_alive : After::close;
    const auto content_type = req[http::field::content_type];
    if (!content_type.starts_with("application/grpc-web") ||
        content_type.starts_with("application/grpc-web-text")) {
      const bool sent = send_text(c, http::status::unsupported_media_type,
                                  "expected Content-Type application/grpc-web or "
                                  "application/grpc-web+proto (binary; grpc-web-text is not "
                                  "supported)\n",
                                  version, req.keep_alive());
      return sent ? next : After::close;
    }

    http::response<http::empty_body> res{http::status::ok, version};
    res.set(http::field::content_type, "application/grpc-web+proto");
    res.set(http::field::cache_control, "no-store");
    res.keep_alive(req.keep_alive());
    res.chunked(true);
    http::response_serializer<http::empty_body> serializer{res};
    auto write_header = [&] {
      return !await_op(c, options.stall_timeout, [&](auto done) {
        http::async_write_header(c.stream, serializer, std::move(done));
      });
    };

    const auto body = grpc_web::parse_frames(req.body());
    if (auto refusal = body_refusal(path, body)) {
      const auto trailers = grpc_web::trailers_frame(*refusal);
      const bool sent = write_header() && write_chunk(c, asio::buffer(trailers)) && write_last_chunk(c);
      return sent ? next : After::close;
    }

    std::optional<std::chrono::system_clock::time_point> deadline;
    const auto timeout_header = req["grpc-timeout"];
    if (const auto timeout = grpc_web::parse_timeout(
            std::string_view(timeout_header.data(), timeout_header.size())))
      deadline = std::chrono::system_clock::now() + *timeout;
    GenericCall call(stub, path, c.stream.socket().native_handle(), c.stream.is_tls(), req,
                     deadline);
    set_call(c, &call.context());
    const CallRegistration unset{this, c};

    const auto started = std::chrono::steady_clock::now();
    bool ok = call.start();
    for (std::size_t i = 0; ok && i < body.messages.size(); ++i) ok = call.write(body.messages[i]);
    if (ok) call.writes_done();

    bool http_ok = write_header();
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
      ++count;
      if (!write_chunk(c, buffers)) {
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
    if (!http_ok) return After::close;
    const auto trailers = grpc_web::trailers_frame(status);
    const bool sent = write_chunk(c, asio::buffer(trailers)) && write_last_chunk(c);
    return sent ? next : After::close;
  }

  // POST /upload: the request body, streamed, becomes a client-streaming CreateSession.
  After upload(Connection& c, const std::string& query) {
    const auto& head = c.header->get();
    const unsigned version = head.version();
    const bool keep_alive = head.keep_alive();
    const std::string filename = query_param(query, "filename");
    const std::string library = query_param(query, "library");
    if (filename.empty() == library.empty()) {
      return refuse(c, http::status::bad_request,
                    "upload: give exactly one of ?filename=NAME (with the file as the body) or "
                    "?library=NAME\n",
                    version);
    }

    hdeform::v1::CreateSessionRequest first;
    auto* header = first.mutable_header();
    if (!filename.empty()) {
      header->set_filename(filename);
      if (const auto length = c.header->content_length()) {
        header->set_total_bytes(static_cast<std::int64_t>(*length));
      }
    } else {
      header->set_library_mesh(library);
    }
    // The client may choose the id (for load balancers that hash x-session-id).
    if (auto id = query_param(query, "session_id"); !id.empty()) header->set_session_id(id);
    if (auto repair = query_param(query, "repair"); !repair.empty()) {
      double tolerance = 0;
      const auto [end, ec] =
          std::from_chars(repair.data(), repair.data() + repair.size(), tolerance);
      if (ec != std::errc() || end != repair.data() + repair.size())
        return refuse(c, http::status::bad_request,
                      "upload: repair must be a number (the merge tolerance, 0 to 0.01)\n",
                      version);
      header->mutable_repair()->set_merge_tolerance(tolerance);  // the service checks the range
    }

    GenericCall call(stub, std::string(kServicePrefix) + "CreateSession",
                     c.stream.socket().native_handle(), c.stream.is_tls(), head);
    set_call(c, &call.context());
    const CallRegistration unset{this, c};

    bool ok = call.start() && call.write(first.SerializeAsString());

    // The body goes on in kUploadChunk pieces as it arrives; each read may wait stall_timeout.
    http::request_parser<http::buffer_body> parser(std::move(*c.header));
    parser.body_limit(options.max_body_bytes);
    std::string chunk(kUploadChunk, '\0');
    std::size_t filled = 0;
    hdeform::v1::CreateSessionRequest part;
    std::string serialized;
    while (!parser.is_done()) {
      parser.get().body().data = chunk.data() + filled;
      parser.get().body().size = chunk.size() - filled;
      auto ec = await_op(c, options.stall_timeout, [&](auto done) {
        http::async_read_some(c.stream, c.buffer, parser, std::move(done));
      });
      if (ec == http::error::need_buffer) ec = {};
      if (ec) {
        call.cancel();
        call.finish();
        if (ec != http::error::body_limit) return After::close;  // stalled or gone
        return refuse(c, http::status::payload_too_large,
                      "upload too large: the limit is " + std::to_string(options.max_body_bytes) +
                          " bytes\n",
                      version);
      }
      filled = chunk.size() - parser.get().body().size;
      if (filled < chunk.size() && !parser.is_done()) continue;
      // After a server-side failure keep reading, to report it once the body is in.
      if (ok && filled > 0) {
        part.set_chunk(chunk.data(), filled);
        part.SerializeToString(&serialized);
        ok = call.write(serialized);
      }
      filled = 0;
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
    http::response<http::string_body> res{http::status::ok, version};
    res.set(http::field::cache_control, "no-store");
    res.keep_alive(keep_alive);
    if (status.ok()) {
      res.set(http::field::content_type, "application/x-protobuf");
      res.set("grpc-status", "0");
      res.body() = std::move(reply_bytes);
    } else {
      res.result(static_cast<http::status>(grpc_web::http_status_for(status.error_code())));
      res.set(http::field::content_type, "text/plain; charset=utf-8");
      res.set("grpc-status", std::to_string(static_cast<int>(status.error_code())));
      res.set("grpc-message", grpc_web::percent_encode(status.error_message()));
      res.body() = status.error_message() + "\n";
    }
    res.prepare_payload();
    if (!write_message(c, res)) return After::close;
    return keep_alive ? After::keep_alive : After::close;
  }

  // Returns false when the connection must close.
  bool static_file(Connection& c, const std::string& path, bool head, unsigned version,
                   bool keep_alive) {
    if (path == "/healthz") return send_text(c, http::status::ok, "ok\n", version, keep_alive);
    if (web_root.empty()) {
      return send_text(c, http::status::not_found,
                       "not found (this server was started without the web viewer)\n", version,
                       keep_alive);
    }
    const auto found = find_static(web_root, path);
    if (found.status == http::status::bad_request) {
      return send_text(c, http::status::bad_request, "bad path\n", version, keep_alive);
    }
    http::file_body::value_type body;
    beast::error_code ec;
    if (found.status == http::status::ok) body.open(found.file.c_str(), beast::file_mode::scan, ec);
    if (found.status != http::status::ok || ec) {
      return send_text(c, http::status::not_found, "not found\n", version, keep_alive);
    }
    const auto size = body.size();
    const bool immutable = path.starts_with("/assets/");  // vite's content-hashed files
    const auto type_sv = mime_type(found.file.string());
    const beast::string_view type(type_sv.data(), type_sv.size());
    const auto cache = immutable ? "public, max-age=31536000, immutable" : "no-cache";
    if (head) {
      http::response<http::empty_body> res{http::status::ok, version};
      res.set(http::field::content_type, type);
      res.set(http::field::cache_control, cache);
      res.content_length(size);
      res.keep_alive(keep_alive);
      return write_message(c, res);
    }
    http::response<http::file_body> res{std::piecewise_construct, std::make_tuple(std::move(body)),
                                        std::make_tuple(http::status::ok, version)};
    res.set(http::field::content_type, type);
    res.set(http::field::cache_control, cache);
    res.set("X-Content-Type-Options", "nosniff");
    res.content_length(size);
    res.keep_alive(keep_alive);
    return write_message(c, res);
  }

  // ---- stopping ------------------------------------------------------------------------------

  // Runs `fn(connection)` on each listed connection's strand and waits until all have run.
  template <class Fn>
  void on_each_strand(const std::list<ConnectionPtr>& list, Fn fn) {
    std::latch ran(static_cast<std::ptrdiff_t>(list.size()));
    for (const auto& c : list) {
      asio::post(c->stream.get_executor(), [c, &fn, &ran] {
        fn(*c);
        ran.count_down();
      });
    }
    ran.wait();
  }

  std::size_t calls_in_progress(bool cancel) {
    std::size_t busy = 0;
    std::lock_guard lock(mu);
    for (auto& c : active) {
      std::lock_guard call_lock(c->call_mu);
      if (c->call) {
        ++busy;
        if (cancel) c->call->TryCancel();
      }
    }
    return busy;
  }

  std::list<ConnectionPtr> active_connections() {
    std::lock_guard lock(mu);
    return active;
  }

  void stop() {
    if (stopping.exchange(true)) return;  // from here no connection enters waiting or active
    asio::post(acceptor.get_executor(), [this] {
      beast::error_code ignored;
      acceptor.close(ignored);
      accept_pause.cancel();
    });
    // Cancel the calls in progress; their handlers end each response with an UNAVAILABLE
    // trailers frame, so browsers see a clean "shutting down" rather than a cut stream.
    // Shutting the receiving side makes a worker waiting for a request body give up at once,
    // while responses can still be written.
    calls_in_progress(true);
    on_each_strand(active_connections(), [](Connection& c) {
      beast::error_code ignored;
      c.stream.socket().shutdown(tcp::socket::shutdown_receive, ignored);
    });
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    while (calls_in_progress(false) > 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(milliseconds(10));
    }
    // Whatever a worker still waits for on a socket now fails at once.
    on_each_strand(active_connections(), [](Connection& c) {
      beast::error_code ignored;
      c.stream.socket().shutdown(tcp::socket::shutdown_both, ignored);
    });
    for (;;) {
      std::list<std::unique_ptr<Worker>> finished;
      {
        std::lock_guard lock(mu);
        finished.swap(workers);
      }
      if (finished.empty()) break;
      for (auto& w : finished) w->thread.join();
    }
    // No worker is left to start an operation: close every connection (waiting, lingering,
    // answering 503, or handed back by a worker), then stop the I/O threads.
    std::list<ConnectionPtr> live;
    {
      std::lock_guard lock(mu);
      for (const auto& weak : all) {
        if (auto c = weak.lock()) live.push_back(std::move(c));
      }
      all.clear();
    }
    on_each_strand(live, [](Connection& c) { close(c); });
    live.clear();
    work.reset();
    ioc.stop();
    for (auto& t : io_threads) t.join();
    io_threads.clear();
    std::lock_guard lock(mu);
    waiting.clear();
    active.clear();
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

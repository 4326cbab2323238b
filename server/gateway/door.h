// The HTTP door's state and its request handlers (http_gateway.h is the public face). One
// model: a few I/O threads run one io_context; each connection lives on its own strand, and
// everything about a request — its header, its body, the gRPC call it becomes, the response —
// is an asynchronous operation whose handler runs on that strand. No thread is ever taken by
// a request: a held WatchSession costs a socket, a GrpcCall and a little memory.
#pragma once

#include "gateway/call_checks.h"
#include "gateway/grpc_call.h"
#include "gateway/http_gateway.h"
#include "gateway/request_checks.h"
#include "gateway/stream.h"

#include <boost/beast/http.hpp>
#include <grpcpp/generic/generic_stub.h>

#include <atomic>
#include <filesystem>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace hdeform::gateway {

namespace http = beast::http;

struct HttpGateway::Impl {
  // One TCP connection. Stream is not thread-safe: every operation on it runs on its strand.
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
  };
  using ConnectionPtr = std::shared_ptr<Connection>;
  using Phase = Connection::Phase;

  // What becomes of a connection after a response.
  enum class After { keep_alive, close, linger };

  GatewayOptions options;
  HostPolicy hosts;
  std::filesystem::path web_root;  // canonical; empty = API only
  grpc::GenericStub stub;
  std::unique_ptr<asio::ssl::context> tls;  // null: plain HTTP
  // Before ioc: handlers it still holds when destroyed may release charges or calls.
  LiveCalls live_calls;                    // GrpcCalls whose OnDone has not run
  std::atomic<std::size_t> body_bytes{0};  // charged to max_inflight_body_bytes
  asio::io_context ioc;
  asio::executor_work_guard<asio::io_context::executor_type> work{ioc.get_executor()};
  tcp::acceptor acceptor{asio::make_strand(ioc)};
  asio::steady_timer accept_pause{acceptor.get_executor()};
  milliseconds accept_delay{0};      // acceptor strand only
  std::size_t accept_failures = 0;   // acceptor strand only (for log throttling)
  std::vector<std::thread> io_threads;
  std::atomic<bool> stopping{false};
  std::mutex mu;                     // guards the lists below and Connection::phase
  std::list<ConnectionPtr> waiting;  // waiting for a request header, oldest first
  std::list<ConnectionPtr> active;   // answering a request
  // Every connection, in any phase (also lingering or answering 503), so that stop() can
  // close them all; expired entries are pruned as it grows.
  std::list<std::weak_ptr<Connection>> all;
  std::size_t prune_at = 64;
  int bound_port = 0;

  Impl(const GatewayOptions& opts, std::shared_ptr<grpc::Channel> channel);
  void run_io();
  void stop();

  // ---- door.cpp: accepting, request headers, responses, lingering ---------------------------
  void do_accept();
  void accept_failed(const beast::error_code& ec);
  void remember(const ConnectionPtr& c);
  bool enter_waiting(const ConnectionPtr& c);
  bool enter_active(const ConnectionPtr& c);
  Phase leave(Connection& c);
  void evict_oldest_waiting();
  void evict_locked();
  static void close(Connection& c) { c.stream.close(); }  // also cancels its operations
  void await_request(const ConnectionPtr& c);
  void read_header(const ConnectionPtr& c, bool fresh_deadline = true);
  void on_header(const ConnectionPtr& c, beast::error_code ec);
  void handle(const ConnectionPtr& c);
  // An answer before the request was handled (its body may still be arriving): then linger.
  void reply_and_close(const ConnectionPtr& c, http::status status, std::string text,
                       unsigned version);
  void linger(const ConnectionPtr& c);
  void drain(const ConnectionPtr& c, std::size_t drained);
  // The response is written (or failed): the connection waits for its next request, lingers
  // or closes.
  void after_response(const ConnectionPtr& c, After after);
  void send_text(const ConnectionPtr& c, http::status status, std::string text, unsigned version,
                 After after);
  // Cancels `call` when the peer closes its side while the call runs (a browser tab closed).
  void watch_peer(const ConnectionPtr& c, std::weak_ptr<GrpcCall> call);

  // `bytes` of request body held in memory until the returned charge is destroyed; null (and
  // the request answered 503) when max_inflight_body_bytes would be exceeded.
  std::shared_ptr<void> charge_body(const ConnectionPtr& c, std::size_t bytes);

  // ---- relay.cpp, upload.cpp, static_reply.cpp ----------------------------------------------
  void grpc_web_call(const ConnectionPtr& c, std::string path);
  void upload(const ConnectionPtr& c, const std::string& query);
  void static_file(const ConnectionPtr& c, const std::string& path, bool head, unsigned version,
                   bool keep_alive);

  // ---- asynchronous helpers (on the connection's strand) -----------------------------------

  // Reads the rest of a request body; each read may wait stall_timeout for bytes. Calls
  // done(error) once.
  template <class Parser, class Done>
  void read_body(const ConnectionPtr& c, std::shared_ptr<Parser> parser, Done done) {
    if (parser->is_done()) return done(beast::error_code{});
    c->stream.expires_after(options.stall_timeout);
    http::async_read_some(c->stream, c->buffer, *parser,
                          [this, c, parser, done = std::move(done)](beast::error_code ec,
                                                                    std::size_t) mutable {
                            if (ec) return done(ec);
                            read_body(c, std::move(parser), std::move(done));
                          });
  }

  // Writes a whole message, each piece within stall_timeout (a large file to a slow but
  // reading client is fine; one that stops reading is dropped). Calls done(ok) once.
  template <class Message, class Done>
  void write_message(const ConnectionPtr& c, std::shared_ptr<Message> message, Done done) {
    using Serializer = http::serializer<Message::is_request::value, typename Message::body_type,
                                        typename Message::fields_type>;
    auto serializer = std::make_shared<Serializer>(*message);
    write_step(c, std::move(message), std::move(serializer), std::move(done));
  }
  template <class Message, class Serializer, class Done>
  void write_step(const ConnectionPtr& c, std::shared_ptr<Message> message,
                  std::shared_ptr<Serializer> serializer, Done done) {
    if (serializer->is_done()) return done(true);
    c->stream.expires_after(options.stall_timeout);
    http::async_write_some(
        c->stream, *serializer,
        [this, c, message = std::move(message), serializer, done = std::move(done)](
            beast::error_code ec, std::size_t) mutable {
          if (ec) return done(false);
          write_step(c, std::move(message), std::move(serializer), std::move(done));
        });
  }

  // Writes `buffers` (kept alive by `keep`) whole within stall_timeout; done(ok).
  template <class Buffers, class Keep, class Done>
  void write_buffers(const ConnectionPtr& c, const Buffers& buffers, Keep keep, Done done) {
    c->stream.expires_after(options.stall_timeout);
    asio::async_write(c->stream, buffers,
                      [keep = std::move(keep), done = std::move(done)](beast::error_code ec,
                                                                       std::size_t) mutable {
                        done(!ec);
                      });
  }
};

// Body of a text/plain response.
http::response<http::string_body> text_response(http::status status, std::string text,
                                                unsigned version, bool keep_alive);
std::string too_large_text(std::size_t limit);

}  // namespace hdeform::gateway

// The HTTP door's connections: accepting, request headers, dispatch, responses, stopping.
#include "gateway/door.h"

#include <poll.h>
#include <pthread.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <latch>

#include "gateway/static_files.h"

namespace hdeform::gateway {

namespace {

constexpr std::size_t kFirstRead = 4u << 10;      // first bytes of a keep-alive request
constexpr milliseconds kLingerTime{2000};         // lingering close: at most this long …
constexpr std::size_t kLingerBytes = 256u << 20;  // … and this many bytes drained
constexpr std::size_t kDrainChunk = 64u << 10;
constexpr milliseconds kMinAcceptPause{10};       // accept() failures: pause, doubling …
constexpr milliseconds kMaxAcceptPause{1000};     // … up to this

// True when the peer has closed its side. A TLS client's close_notify stays unread in the
// socket, so a peek would never see the end of the stream: ask the kernel instead.
bool peer_gone(int fd, bool tls) {
  if (tls) {
    pollfd p{fd, POLLRDHUP, 0};
    return ::poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR)) != 0;
  }
  char byte;
  const auto n = ::recv(fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
  if (n == 0) return true;  // orderly shutdown by the browser
  return n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR;
}

}  // namespace

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

HttpGateway::Impl::Impl(const GatewayOptions& opts, std::shared_ptr<grpc::Channel> channel)
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
    io_threads.emplace_back([this] {
      pthread_setname_np(pthread_self(), "hdeform-http");  // tellable apart in top -H / perf
      run_io();
    });
  }
}

// An exception escaping a handler must not end an I/O thread (nor the process).
void HttpGateway::Impl::run_io() {
  for (;;) {
    try {
      ioc.run();
      return;
    } catch (const std::exception& e) {
      spdlog::error("hdeform-gateway: I/O handler failed: {}", e.what());
    }
  }
}

void HttpGateway::Impl::do_accept() {
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
void HttpGateway::Impl::accept_failed(const beast::error_code& ec) {
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

void HttpGateway::Impl::remember(const ConnectionPtr& c) {
  std::lock_guard lock(mu);
  all.push_back(c);
  if (all.size() >= prune_at) {
    all.remove_if([](const auto& weak) { return weak.expired(); });
    prune_at = std::max<std::size_t>(64, 2 * all.size());
  }
}

// Registers a connection as waiting for a request; false when stopping. Closes the oldest
// waiting connection when the cap is reached.
bool HttpGateway::Impl::enter_waiting(const ConnectionPtr& c) {
  std::lock_guard lock(mu);
  if (stopping) return false;
  if (waiting.size() >= std::max<std::size_t>(1, options.max_idle_connections)) evict_locked();
  c->slot = waiting.insert(waiting.end(), c);
  c->phase = Phase::waiting;
  return true;
}

// Registers a request in progress; false when stopping or at the cap.
bool HttpGateway::Impl::enter_active(const ConnectionPtr& c) {
  std::lock_guard lock(mu);
  if (stopping || active.size() >= options.max_connections) return false;
  c->slot = active.insert(active.end(), c);
  c->phase = Phase::active;
  return true;
}

// Unregisters; returns the phase it was in (none: evicted meanwhile).
HttpGateway::Impl::Phase HttpGateway::Impl::leave(Connection& c) {
  std::lock_guard lock(mu);
  const Phase was = c.phase;
  if (was == Phase::waiting) waiting.erase(c.slot);
  if (was == Phase::active) active.erase(c.slot);
  c.phase = Phase::none;
  return was;
}

void HttpGateway::Impl::evict_oldest_waiting() {
  std::lock_guard lock(mu);
  evict_locked();
}

void HttpGateway::Impl::evict_locked() {
  if (waiting.empty()) return;
  ConnectionPtr victim = std::move(waiting.front());
  waiting.pop_front();
  victim->phase = Phase::none;
  asio::post(victim->stream.get_executor(), [victim] { close(*victim); });
}

void HttpGateway::Impl::await_request(const ConnectionPtr& c) {
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
void HttpGateway::Impl::read_header(const ConnectionPtr& c, bool fresh_deadline) {
  c->header.emplace();
  c->header->header_limit(kMaxHeaderBytes);
  c->header->body_limit(options.max_body_bytes);  // a larger Content-Length fails: 413
  if (fresh_deadline) c->stream.expires_after(options.header_timeout);
  http::async_read_header(c->stream, c->buffer, *c->header,
                          [this, c](beast::error_code ec, std::size_t) { on_header(c, ec); });
}

void HttpGateway::Impl::on_header(const ConnectionPtr& c, beast::error_code ec) {
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
  handle(c);
}

// An early answer from the strand (the request was not handed to a worker).
void HttpGateway::Impl::reply_and_close(const ConnectionPtr& c, http::status status,
                                        std::string text, unsigned version) {
  leave(*c);  // no longer answering (a no-op before the request was admitted)
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
void HttpGateway::Impl::linger(const ConnectionPtr& c) {
  beast::error_code ignored;
  c->stream.socket().shutdown(tcp::socket::shutdown_send, ignored);
  c->stream.expires_after(kLingerTime);
  drain(c, 0);
}

void HttpGateway::Impl::drain(const ConnectionPtr& c, std::size_t drained) {
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


// ---- one request ------------------------------------------------------------------------------

void HttpGateway::Impl::handle(const ConnectionPtr& c) {
  const auto& req = c->header->get();
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
      return reply_and_close(c, http::status::forbidden, std::move(why), version);
    }
  }
  if (path.starts_with(kServicePrefix)) {
    if (method != http::verb::post) {
      return reply_and_close(c, http::status::method_not_allowed, "gRPC-Web calls must be POST\n",
                             version);
    }
    return grpc_web_call(c, path);
  }
  if (path == "/upload") {
    if (method != http::verb::post) {
      return reply_and_close(c, http::status::method_not_allowed,
                             "POST the mesh file to /upload\n", version);
    }
    if (!has_upload_header(req)) {
      return reply_and_close(
          c, http::status::forbidden,
          "upload refused: send the header X-Hdeform-Upload: 1 (or X-Session-Id) with POST "
          "/upload; a page on another site cannot add it\n",
          version);
    }
    return upload(c, query);
  }
  if (method == http::verb::get || method == http::verb::head) {
    // A GET or HEAD has no body here: one announced is refused before it is read (else the
    // body parser would reserve up to --max-body-bytes outside the upload budget).
    if (c->header->chunked() || c->header->content_length().value_or(0) > 0) {
      return reply_and_close(c, http::status::bad_request,
                             "bad request: a GET or HEAD carries no body\n", version);
    }
    auto parser = std::make_shared<http::request_parser<http::string_body>>(std::move(*c->header));
    parser->body_limit(0);
    const bool head = method == http::verb::head;
    return read_body(c, parser, [this, c, path, head, version, keep_alive](beast::error_code ec) {
      if (ec) return after_response(c, After::close);
      static_file(c, path, head, version, keep_alive);
    });
  }
  reply_and_close(c, http::status::method_not_allowed, "method not allowed\n", version);
}

void HttpGateway::Impl::after_response(const ConnectionPtr& c, After after) {
  leave(*c);
  if (stopping) after = After::close;
  switch (after) {
    case After::keep_alive:
      c->served = true;
      await_request(c);
      break;
    case After::linger: linger(c); break;
    case After::close: close(*c); break;
  }
}

void HttpGateway::Impl::send_text(const ConnectionPtr& c, http::status status, std::string text,
                                  unsigned version, After after) {
  auto res = std::make_shared<http::response<http::string_body>>(
      text_response(status, std::move(text), version, after == After::keep_alive));
  write_message(c, std::move(res), [this, c, after](bool ok) {
    after_response(c, ok ? after : After::close);
  });
}

std::shared_ptr<void> HttpGateway::Impl::charge_body(const ConnectionPtr& c, std::size_t bytes) {
  std::size_t held = body_bytes.load();
  do {
    if (held + bytes > options.max_inflight_body_bytes || held + bytes < held) {
      reply_and_close(c, http::status::service_unavailable,
                      "hdeform-gateway is receiving too many request bytes at once (" +
                          std::to_string(options.max_inflight_body_bytes) +
                          " in flight, --max-upload-inflight-mb); try again shortly\n",
                      c->header->get().version());
      return nullptr;
    }
  } while (!body_bytes.compare_exchange_weak(held, held + bytes));
  struct Charge {
    Charge(std::atomic<std::size_t>& held, std::size_t bytes) : held(held), bytes(bytes) {}
    Charge(const Charge&) = delete;
    ~Charge() { held -= bytes; }
    std::atomic<std::size_t>& held;
    const std::size_t bytes;
  };
  return std::make_shared<Charge>(body_bytes, bytes);
}

void HttpGateway::Impl::watch_peer(const ConnectionPtr& c, std::weak_ptr<GrpcCall> call) {
  c->stream.socket().async_wait(tcp::socket::wait_read, [c, call](beast::error_code ec) {
    if (ec) return;  // cancelled: the call ended first
    auto live = call.lock();
    if (!live) return;
    // Readable: the peer went away, or sent the next (pipelined) request, which waits.
    if (peer_gone(c->stream.socket().native_handle(), c->stream.is_tls())) live->cancel();
  });
}

// ---- stopping -------------------------------------------------------------------------------

namespace {

// Runs `fn(connection)` on each listed connection's strand and waits until all have run.
template <class Connections, class Fn>
void on_each_strand(const Connections& list, Fn fn) {
  std::latch ran(static_cast<std::ptrdiff_t>(list.size()));
  for (const auto& c : list) {
    asio::post(c->stream.get_executor(), [c, &fn, &ran] {
      fn(*c);
      ran.count_down();
    });
  }
  ran.wait();
}

}  // namespace

void HttpGateway::Impl::stop() {
  if (stopping.exchange(true)) return;  // from here no connection enters waiting or active
  asio::post(acceptor.get_executor(), [this] {
    beast::error_code ignored;
    acceptor.close(ignored);
    accept_pause.cancel();
  });
  // Cancel every call, and any that starts from here on; their handlers end each response
  // with an UNAVAILABLE trailers frame, so browsers see a clean "shutting down" rather than a
  // cut stream. (All of them, not only those of active connections: the server's own
  // shutdown cannot reach some in-process streams, live_calls.h.)
  live_calls.close_and_cancel();
  const auto until = [&](auto done, std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (!done() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(milliseconds(5));
    return done();
  };
  if (!until([&] {
        std::lock_guard lock(mu);
        return active.empty();
      }, milliseconds(1000)))
    spdlog::warn("hdeform-gateway: stopping with {} requests still answering", active.size());
  // Close every connection (waiting, lingering, answering 503, or still answering).
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
  // A call's reactor must see OnDone before the channel goes (the owner destroys it next).
  if (!live_calls.wait_empty(milliseconds(10000)))
    spdlog::error("hdeform-gateway: {} gRPC calls did not end", live_calls.size());
  work.reset();
  ioc.stop();
  for (auto& t : io_threads) t.join();
  io_threads.clear();
  std::lock_guard lock(mu);
  waiting.clear();
  active.clear();
}

}  // namespace hdeform::gateway

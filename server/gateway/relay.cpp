// gRPC-Web calls: the request body's frames go to the service as one generic streaming call
// (unary, server-streaming and one-message client streams alike), each response message comes
// back as one HTTP chunk (a gRPC-Web data frame) as soon as it arrives, then the trailers.
//
// The next response message is read once the socket has taken the one before: until then it
// waits in the service, whose streams keep only the newest frame, so a slow link gets the
// newest frame, not one read ahead that went stale behind a 2.4 MB write (WAN bench,
// docs/benchmarks.md "When the door reads the next frame"). A read is outstanding whenever
// no chunk is being written. A call whose method takes one request message is never
// half-closed (the server has its message; WritesDone only matters to client-streaming
// methods), and stop() cancels every call (live_calls.h): together these keep gRPC 1.51's
// in-process transport from stranding a server stream at shutdown.
#include "gateway/door.h"

#include <spdlog/spdlog.h>

#include <array>
#include <utility>

#include "gateway/call_checks.h"
#include "gateway/grpc_web.h"

namespace hdeform::gateway {

namespace {

using Parser = http::request_parser<http::string_body>;

// One relayed call's state; every member is used on the connection's strand only.
struct Relay {
  HttpGateway::Impl* door;
  HttpGateway::Impl::ConnectionPtr c;
  std::shared_ptr<Parser> parser;  // owns the body the messages point into
  grpc_web::ParsedBody body;
  std::string path;
  bool half_close = false;     // a client-streaming method: WritesDone after the messages
  HttpGateway::Impl::After next = HttpGateway::Impl::After::close;
  std::shared_ptr<GrpcCall> call;
  std::size_t written = 0;     // request messages written to the call
  bool reads_over = false;     // the call has no more messages
  bool writes_over = false;    // every message written (and WritesDone issued), or a write failed
  bool writing = false;        // an HTTP chunk is being written (and no read outstanding)
  bool http_ok = true;         // false: the browser is gone; drain the call
  std::optional<grpc::Status> ended;
  std::size_t count = 0;
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  std::shared_ptr<void> charge;  // the body's bytes, charged until the relay ends

  void release_if_idle() {
    if (reads_over && writes_over) call->release();
  }
  void read() { call->read(); }
  void write_next() {
    if (written < body.messages.size()) {
      call->write(body.messages[written++]);
      return;
    }
    if (half_close) call->writes_done();
    writes_over = true;
    release_if_idle();
  }
};

void finish_relay(const std::shared_ptr<Relay>& r);

// Writes one message to the browser as an HTTP chunk; once it is written, reading resumes,
// or the relay finishes if the call has ended.
void send_message(const std::shared_ptr<Relay>& r, std::vector<grpc::Slice> message) {
  auto slices = std::make_shared<std::vector<grpc::Slice>>(std::move(message));
  std::size_t length = 0;
  for (const auto& slice : *slices) length += slice.size();
  auto prefix = std::make_shared<std::array<char, 5>>(
      grpc_web::frame_prefix(grpc_web::kDataFlag, static_cast<std::uint32_t>(length)));
  std::vector<asio::const_buffer> buffers;
  buffers.reserve(slices->size() + 1);
  buffers.emplace_back(prefix->data(), prefix->size());
  for (const auto& slice : *slices) buffers.emplace_back(slice.begin(), slice.size());
  ++r->count;
  r->writing = true;
  r->door->write_buffers(r->c, http::make_chunk(buffers), std::make_pair(slices, prefix),
                         [r](bool written) {
                           r->writing = false;
                           if (!written) {
                             r->http_ok = false;
                             r->call->cancel();
                           }
                           if (r->ended) return finish_relay(r);
                           if (!r->reads_over) r->read();
                         });
}

// A response message arrived (ok) or the call has no more (not ok).
void on_read(const std::shared_ptr<Relay>& r, bool ok) {
  if (!ok) {
    r->reads_over = true;
    r->release_if_idle();
    return;
  }
  std::vector<grpc::Slice> slices;  // references to the message: the buffer can be reused
  if (!r->http_ok || !r->call->message().Dump(&slices).ok()) return r->read();  // drain
  send_message(r, std::move(slices));  // the next read once the socket has taken it
}

void start_relay(const std::shared_ptr<Relay>& r) {
  auto* door = r->door;
  const auto& req = r->parser->get();
  std::optional<std::chrono::system_clock::time_point> deadline;
  const auto timeout_header = req["grpc-timeout"];
  if (const auto timeout = grpc_web::parse_timeout(
          std::string_view(timeout_header.data(), timeout_header.size())))
    deadline = std::chrono::system_clock::now() + *timeout;
  GrpcCall::Events events;
  events.wrote = [r](bool ok) {
    if (!ok) {
      r->writes_over = true;
      r->release_if_idle();
      return;
    }
    r->write_next();
  };
  events.read = [r](bool ok) { on_read(r, ok); };
  events.done = [r](const grpc::Status& status) {
    r->ended = status;
    if (!r->writing) finish_relay(r);
  };
  r->call = GrpcCall::prepare(door->stub, r->path, req, deadline, r->c->stream.get_executor(),
                              std::move(events), door->live_calls);
  r->read();
  r->write_next();
  r->call->begin();
  door->watch_peer(r->c, r->call);
}

// The call ended and no chunk is being written: the trailers, then the next request.
void finish_relay(const std::shared_ptr<Relay>& r) {
  auto* door = r->door;
  beast::error_code ignored;
  r->c->stream.socket().cancel(ignored);  // the peer watch
  grpc::Status status = *r->ended;
  if (door->stopping && status.error_code() == grpc::StatusCode::CANCELLED)
    status = grpc::Status(grpc::StatusCode::UNAVAILABLE, "hdeform-server is shutting down");
  spdlog::debug("hdeform-gateway: {} → {} ({} messages, {:.1f} ms)", r->path,
                static_cast<int>(status.error_code()), r->count,
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() -
                                                          r->started)
                    .count());
  if (!r->http_ok) return door->after_response(r->c, HttpGateway::Impl::After::close);
  auto trailers = std::make_shared<std::string>(grpc_web::trailers_frame(status));
  door->write_buffers(r->c, http::make_chunk(asio::buffer(*trailers)), trailers, [r](bool ok) {
    if (!ok) return r->door->after_response(r->c, HttpGateway::Impl::After::close);
    r->door->write_buffers(r->c, http::make_chunk_last(), 0, [r](bool ok2) {
      r->door->after_response(r->c, ok2 ? r->next : HttpGateway::Impl::After::close);
    });
  });
}

}  // namespace

void HttpGateway::Impl::grpc_web_call(const ConnectionPtr& c, std::string path) {
  // The body is read whole: charged up front (browsers send a Content-Length; a chunked
  // body is capped lower, since its size is not known before it is in).
  const auto length = c->header->content_length();
  const std::size_t limit = length ? options.max_body_bytes
                                   : std::min(options.max_body_bytes, kChunkedBodyLimit);
  if (length && *length > limit) {
    return reply_and_close(c, http::status::payload_too_large, too_large_text(limit),
                           c->header->get().version());
  }
  auto charge = charge_body(c, length ? static_cast<std::size_t>(*length) : limit);
  if (!charge) return;
  auto parser = std::make_shared<Parser>(std::move(*c->header));
  parser->body_limit(limit);
  read_body(c, parser, [this, c, parser, path = std::move(path), limit,
                        charge = std::move(charge)](beast::error_code ec) mutable {
    if (ec) {
      if (ec != http::error::body_limit) return after_response(c, After::close);
      return reply_and_close(c, http::status::payload_too_large, too_large_text(limit),
                             parser->get().version());
    }
    const auto& req = parser->get();
    const unsigned version = req.version();
    const After next = req.keep_alive() ? After::keep_alive : After::close;
    const auto content_type = req[http::field::content_type];
    if (!content_type.starts_with("application/grpc-web") ||
        content_type.starts_with("application/grpc-web-text")) {
      return send_text(c, http::status::unsupported_media_type,
                       "expected Content-Type application/grpc-web or application/grpc-web+proto "
                       "(binary; grpc-web-text is not supported)\n",
                       version, next);
    }
    auto relay = std::make_shared<Relay>();
    relay->door = this;
    relay->c = c;
    relay->parser = parser;
    relay->body = grpc_web::parse_frames(req.body());
    relay->path = std::move(path);
    if (const auto* method = find_method(relay->path)) relay->half_close = method->client_streaming();
    relay->next = next;
    relay->charge = std::move(charge);

    auto res = std::make_shared<http::response<http::empty_body>>(http::status::ok, version);
    res->set(http::field::content_type, "application/grpc-web+proto");
    res->set(http::field::cache_control, "no-store");
    res->keep_alive(req.keep_alive());
    res->chunked(true);
    auto serializer = std::make_shared<http::response_serializer<http::empty_body>>(*res);
    c->stream.expires_after(options.stall_timeout);
    http::async_write_header(
        c->stream, *serializer,
        [this, relay, res, serializer](beast::error_code ec, std::size_t) {
          const auto& c = relay->c;
          if (ec) return after_response(c, After::close);
          if (auto refusal = body_refusal(relay->path, relay->body)) {
            auto trailers = std::make_shared<std::string>(grpc_web::trailers_frame(*refusal));
            return write_buffers(c, http::make_chunk(asio::buffer(*trailers)), trailers,
                                 [this, relay](bool ok) {
                                   if (!ok) return after_response(relay->c, After::close);
                                   write_buffers(relay->c, http::make_chunk_last(), 0,
                                                 [this, relay](bool ok2) {
                                                   after_response(relay->c,
                                                                  ok2 ? relay->next : After::close);
                                                 });
                                 });
          }
          start_relay(relay);
        });
  });
}

}  // namespace hdeform::gateway

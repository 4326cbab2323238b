// POST /upload: the request body, streamed as it arrives, becomes a client-streaming
// CreateSession (a header message, then ≤ 1 MiB chunks); the reply is the Session as binary
// protobuf, or a plain-text error with the mapped HTTP status. One chunk is in flight at a
// time: the next body bytes are read once the call has taken the last ones.
#include "gateway/door.h"

#include "gateway/grpc_web.h"
#include "gateway/static_files.h"
#include "hdeform/v1/deform.pb.h"

#include <charconv>

namespace hdeform::gateway {

namespace {

constexpr std::size_t kUploadChunk = 1u << 20;  // CreateSession chunk size (< 4 MiB limit)

using Parser = http::request_parser<http::buffer_body>;
using After = HttpGateway::Impl::After;

struct Upload {
  HttpGateway::Impl* door;
  HttpGateway::Impl::ConnectionPtr c;
  std::shared_ptr<Parser> parser;
  unsigned version = 11;
  bool keep_alive = false;
  std::shared_ptr<GrpcCall> call;
  std::string chunk = std::string(kUploadChunk, '\0');
  std::size_t filled = 0;
  std::string serialized;
  bool call_ok = true;        // every write so far reached the call
  bool writes_over = false;   // WritesDone issued, a write failed, or the body failed
  bool reply_over = false;    // the one response read finished
  bool body_over = false;     // the body was read whole
  beast::error_code body_error;
  std::string reply;
  std::optional<grpc::Status> ended;
  bool responded = false;
  std::shared_ptr<void> charge;  // the chunk's bytes in the door's budget

  void release_if_idle() {
    if (writes_over && reply_over) call->release();
  }
};

void read_more(const std::shared_ptr<Upload>& u);

// Responds once the call ended and the body was read whole (or failed).
void maybe_respond(const std::shared_ptr<Upload>& u) {
  if (u->responded || !u->ended || !(u->body_over || u->body_error)) return;
  u->responded = true;
  auto* door = u->door;
  if (u->body_error) {
    if (u->body_error != http::error::body_limit) return door->after_response(u->c, After::close);
    return door->reply_and_close(u->c, http::status::payload_too_large,
                                 "upload too large: the limit is " +
                                     std::to_string(door->options.max_body_bytes) + " bytes\n",
                                 u->version);
  }
  const grpc::Status& status = *u->ended;
  auto res = std::make_shared<http::response<http::string_body>>(http::status::ok, u->version);
  res->set(http::field::cache_control, "no-store");
  res->keep_alive(u->keep_alive);
  if (status.ok()) {
    res->set(http::field::content_type, "application/x-protobuf");
    res->set("grpc-status", "0");
    res->body() = std::move(u->reply);
  } else {
    res->result(static_cast<http::status>(grpc_web::http_status_for(status.error_code())));
    res->set(http::field::content_type, "text/plain; charset=utf-8");
    res->set("grpc-status", std::to_string(static_cast<int>(status.error_code())));
    res->set("grpc-message", grpc_web::percent_encode(status.error_message()));
    res->body() = status.error_message() + "\n";
  }
  res->prepare_payload();
  const After after = u->keep_alive ? After::keep_alive : After::close;
  door->write_message(u->c, std::move(res), [door, c = u->c, after](bool ok) {
    door->after_response(c, ok ? after : After::close);
  });
}

// The body is over: the call is told, and answers once it ends.
void body_over(const std::shared_ptr<Upload>& u) {
  u->body_over = true;
  if (!u->writes_over) {
    if (u->call_ok) u->call->writes_done();
    u->writes_over = true;
    u->release_if_idle();
  }
  maybe_respond(u);
}

// Sends the filled chunk to the call (or drops it after a failure), then reads on.
void send_chunk(const std::shared_ptr<Upload>& u) {
  if (u->call_ok && !u->writes_over && u->filled > 0) {
    hdeform::v1::CreateSessionRequest part;
    part.set_chunk(u->chunk.data(), u->filled);
    part.SerializeToString(&u->serialized);
    u->filled = 0;
    u->call->write(u->serialized);  // wrote → read_more
    return;
  }
  u->filled = 0;  // after a server-side failure the body is read to report it once it is in
  read_more(u);
}

void read_more(const std::shared_ptr<Upload>& u) {
  if (u->parser->is_done()) return body_over(u);
  auto& body = u->parser->get().body();
  body.data = u->chunk.data() + u->filled;
  body.size = u->chunk.size() - u->filled;
  u->c->stream.expires_after(u->door->options.stall_timeout);
  http::async_read_some(u->c->stream, u->c->buffer, *u->parser,
                        [u](beast::error_code ec, std::size_t) {
                          if (ec == http::error::need_buffer) ec = {};
                          if (ec) {  // stalled, gone, or too large: the call is abandoned
                            u->body_error = ec;
                            u->call->cancel();
                            if (!u->writes_over) {
                              u->writes_over = true;
                              u->release_if_idle();
                            }
                            return maybe_respond(u);
                          }
                          u->filled = u->chunk.size() - u->parser->get().body().size;
                          if (u->filled < u->chunk.size() && !u->parser->is_done()) return read_more(u);
                          send_chunk(u);
                        });
}

}  // namespace

void HttpGateway::Impl::upload(const ConnectionPtr& c, const std::string& query) {
  const auto& head = c->header->get();
  const std::string filename = query_param(query, "filename");
  const std::string library = query_param(query, "library");
  if (filename.empty() == library.empty()) {
    return reply_and_close(c, http::status::bad_request,
                           "upload: give exactly one of ?filename=NAME (with the file as the "
                           "body) or ?library=NAME\n",
                           head.version());
  }
  hdeform::v1::CreateSessionRequest first;
  auto* header = first.mutable_header();
  if (!filename.empty()) {
    header->set_filename(filename);
    if (const auto length = c->header->content_length())
      header->set_total_bytes(static_cast<std::int64_t>(*length));
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
      return reply_and_close(c, http::status::bad_request,
                             "upload: repair must be a number (the merge tolerance, 0 to 0.01)\n",
                             head.version());
    header->mutable_repair()->set_merge_tolerance(tolerance);  // the service checks the range
  }

  auto charge = charge_body(c, kUploadChunk);  // the chunk buffer below
  if (!charge) return;
  auto u = std::make_shared<Upload>();
  u->charge = std::move(charge);
  u->door = this;
  u->c = c;
  u->version = head.version();
  u->keep_alive = head.keep_alive();
  GrpcCall::Events events;
  events.wrote = [u](bool ok) {
    if (!ok) {
      u->call_ok = false;
      if (!u->writes_over) {
        u->writes_over = true;
        u->release_if_idle();
      }
    }
    read_more(u);
  };
  events.read = [u](bool ok) {
    if (ok) {
      std::vector<grpc::Slice> slices;
      if (u->call->message().Dump(&slices).ok())
        for (const auto& s : slices) u->reply.append(reinterpret_cast<const char*>(s.begin()), s.size());
    }
    u->reply_over = true;
    u->release_if_idle();
  };
  events.done = [u](const grpc::Status& status) {
    u->ended = status;
    maybe_respond(u);
  };
  u->call = GrpcCall::prepare(stub, std::string(kServicePrefix) + "CreateSession", head,
                              std::nullopt, c->stream.get_executor(), std::move(events),
                              live_calls);
  u->parser = std::make_shared<Parser>(std::move(*c->header));  // `head` ends here
  u->parser->body_limit(options.max_body_bytes);
  u->call->read();
  u->serialized = first.SerializeAsString();
  u->call->write(u->serialized);  // wrote → read_more
  u->call->begin();
}

}  // namespace hdeform::gateway

// gRPC-Web gateway: Boost.Beast HTTP/1.1 in front of the in-process gRPC channel.
//
// Model (door.h). Nothing waits on a thread: a few I/O threads (GatewayOptions::threads) run
// one io_context; each connection lives on its own strand with Beast's tcp_stream deadlines
// (header_timeout for a whole header, idle_timeout between keep-alive requests, stall_timeout
// for each piece of a body or response). A request's body, its gRPC call (gRPC's callback API,
// grpc_call.h) and its response are asynchronous operations whose handlers run on that
// strand; a quiet server stream costs a socket, a call and a little memory. Two caps bound the
// rest: max_idle_connections for connections waiting for a request (the oldest is closed) and
// max_connections for requests in progress (503 above).
//
// Every gRPC-Web call — unary, server-streaming, or a one-message client stream — is forwarded
// as raw bytes through grpc::GenericStub as one generic streaming call (relay.cpp): write the
// request messages (WritesDone only for a client-streaming method), relay every response
// message as one HTTP chunk (gRPC-Web data frame) with the next read already outstanding,
// then the trailers frame. No per-method code. A browser that goes away is noticed when its
// socket turns readable with nothing to read (watch_peer) and its call is cancelled. stop()
// cancels every call the door has open (live_calls.h) and waits for their ends.
//
// TLS (GatewayOptions::tls_cert_file/tls_key_file): the same model over HTTPS (stream.h). A
// new TLS connection's handshake and its first request header share one header_timeout; TLS 1.2
// at least; with tls_client_ca_file every client must present a certificate signed by that CA.
//
// The request header Authorization (every value) is passed on as gRPC metadata
// `authorization` to every gRPC-Web call and to /upload's CreateSession (capability tokens).
//
// Safe to expose: a request's Host, framing and Origin are checked before anything runs
// (request_checks.h: 421, 400, 403); static files are served only if their canonical path is
// a regular file inside the canonical web root (static_files.h); /upload also needs a header a
// cross-site page cannot send without a CORS preflight (which this server never approves);
// accept() errors (EMFILE, ECONNABORTED, …) pause accepting briefly, never end it.
//
// Endpoints:
//   POST /hdeform.v1.Deformation/<Method>   application/grpc-web(+proto) — the API
//   POST /upload?filename=NAME              raw mesh bytes → client-streaming CreateSession
//   POST /upload?library=NAME               (upload.cpp); optional &session_id=ID and
//                                           &repair=TOL (CreateSessionHeader.repair with
//                                           merge_tolerance TOL; 0: equal positions). Needs the
//                                           header X-Session-Id or X-Hdeform-Upload. Reply:
//                                           the Session as binary protobuf, or a plain-text
//                                           error with the mapped HTTP status.
//   GET  /healthz                           "ok"
//   GET  /…                                 static files from web_root (index.html for /)
#include "gateway/http_gateway.h"

#include <spdlog/spdlog.h>

#include "gateway/door.h"

namespace hdeform::gateway {

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

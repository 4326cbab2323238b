// gRPC-Web over HTTP/1.1 (Boost.Beast) in front of the same gRPC service, plus the
// viewer's static files: browsers reach the API on the page's own origin.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace hdeform::gateway {

struct GatewayOptions {
  std::string address = "127.0.0.1";
  int port = 8080;                        // 0 = any free port
  std::string web_root;                   // built viewer (web-viewer/dist); empty = API only
  std::size_t max_body_bytes = 256u << 20;
  // Request bodies the door holds in memory, all requests together: a gRPC-Web body is read
  // whole (its Content-Length is charged up front; a chunked one is capped at 4 MiB), an
  // upload holds one 1 MiB chunk. Above it a request is answered 503 before its body is read.
  std::size_t max_inflight_body_bytes = 1u << 30;
  // Host names answered besides localhost names and IP addresses (request_checks.h
  // HostPolicy): "name", ".name" for subdomains, "*" for any. Others get 421 (DNS rebinding).
  std::vector<std::string> allowed_hosts;
  int threads = 2;                        // I/O threads: every request's work runs on them

  // Requests in progress (a WatchSession stream counts for its whole life; it costs a socket,
  // a gRPC call and a few KiB, no thread). Above it a new request is answered 503.
  std::size_t max_connections = 4096;
  // Connections waiting for a request header (new or idle keep-alive ones). They cost a
  // socket and a few KiB but no thread; above the cap the oldest is closed.
  std::size_t max_idle_connections = 1024;
  // A new connection must deliver a whole request header within this time (slowloris)...
  std::chrono::milliseconds header_timeout{10'000};
  // ... and a keep-alive connection may wait this long between requests before it is closed.
  std::chrono::milliseconds idle_timeout{60'000};
  // A request body that sends nothing, or a response the client does not read, for this long
  // ends the connection. A quiet server stream (no frames to send) is never cut by it.
  std::chrono::milliseconds stall_timeout{30'000};
  // HTTPS (--tls-cert, --tls-key, --tls-client-ca): PEM files. Cert and key together turn TLS
  // on (both or neither; TLS 1.2 at least); with a client CA, every client must present a
  // certificate signed by it. The constructor throws naming a missing or bad file.
  std::string tls_cert_file, tls_key_file, tls_client_ca_file;
};

class HttpGateway {
 public:
  // Starts listening; forwards gRPC-Web calls to `backend` (an in-process channel).
  HttpGateway(const GatewayOptions& options, std::shared_ptr<grpc::Channel> backend);
  ~HttpGateway();  // stops and joins
  int port() const;
  void stop();

  struct Impl;  // door.h: the connections and their handlers (internal)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace hdeform::gateway

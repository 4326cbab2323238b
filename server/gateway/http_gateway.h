// gRPC-Web over HTTP/1.1 (Boost.Beast) in front of the same gRPC service, plus the
// viewer's static files: browsers reach the API on the page's own origin.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <memory>
#include <string>

namespace hdeform::gateway {

struct GatewayOptions {
  std::string address = "127.0.0.1";
  int port = 8080;                        // 0 = any free port
  std::string web_root;                   // built viewer (web-viewer/dist); empty = API only
  std::size_t max_body_bytes = 256u << 20;
  int threads = 2;
};

class HttpGateway {
 public:
  // Starts listening; forwards gRPC-Web calls to `backend` (an in-process channel).
  HttpGateway(const GatewayOptions& options, std::shared_ptr<grpc::Channel> backend);
  ~HttpGateway();  // stops and joins
  int port() const;
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hdeform::gateway

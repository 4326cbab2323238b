// A server-streaming call that ends at once with a status (a refused GetMesh, WatchSession,
// ExportAnimation).
#pragma once

#include <grpcpp/support/server_callback.h>
#include <grpcpp/support/status.h>

namespace hdeform::service {

template <class Message>
grpc::ServerWriteReactor<Message>* failed_stream(grpc::Status status) {
  class Fail final : public grpc::ServerWriteReactor<Message> {
   public:
    explicit Fail(grpc::Status s) { this->Finish(std::move(s)); }
    void OnDone() override { delete this; }
  };
  return new Fail(std::move(status));
}

}  // namespace hdeform::service

// One gRPC call of the HTTP door on gRPC's callback API: no thread waits for it. Its events
// (a write or read finished, the call ended) run on the connection's strand, so the door's
// state needs no lock. A hold keeps OnDone back until the door has issued its last operation
// (gRPC forbids starting one once OnDone may run).
#pragma once

#include "gateway/live_calls.h"

#include <boost/asio/any_io_executor.hpp>
#include <boost/beast/http/message.hpp>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace hdeform::gateway {

class GrpcCall final : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
 public:
  struct Events {
    std::function<void(bool ok)> wrote;                // a write() finished
    std::function<void(bool ok)> read;                 // a read() finished: message() holds it
    std::function<void(const grpc::Status&)> done;     // the call ended (the last event)
  };

  // Prepares generic call `method` ("/pkg.Service/Method") with the request's Authorization
  // values as `authorization` metadata and an optional deadline; nothing is sent before
  // begin(). `live` lists it until its OnDone runs (stop() cancels and awaits them).
  static std::shared_ptr<GrpcCall> prepare(
      grpc::GenericStub& stub, const std::string& method,
      const boost::beast::http::request_header<>& request,
      std::optional<std::chrono::system_clock::time_point> deadline,
      boost::asio::any_io_executor strand, Events events, LiveCalls& live);

  void begin();                            // StartCall, holding OnDone back until release()
  void release();                          // the door issues no more operations (once)
  void write(std::string_view message);    // one at a time
  void writes_done();
  void read();                             // one at a time
  grpc::ByteBuffer& message() { return in_; }
  void cancel() { context_.TryCancel(); }

  void OnWriteDone(bool ok) override;
  void OnReadDone(bool ok) override;
  void OnDone(const grpc::Status& status) override;

 private:
  GrpcCall(boost::asio::any_io_executor strand, Events events, LiveCalls& live)
      : strand_(std::move(strand)), events_(std::move(events)), live_(live) {}

  boost::asio::any_io_executor strand_;
  Events events_;
  LiveCalls& live_;
  grpc::ClientContext context_;
  grpc::ByteBuffer in_, out_;
  bool released_ = false;
  std::shared_ptr<GrpcCall> self_;  // alive until OnDone's event has run
};

}  // namespace hdeform::gateway

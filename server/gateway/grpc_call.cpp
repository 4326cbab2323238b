#include "gateway/grpc_call.h"

#include <boost/asio/post.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <utility>

namespace hdeform::gateway {

namespace http = boost::beast::http;

namespace {

// The request's Authorization values become gRPC metadata `authorization` (capability tokens
// for the service). gRPC only accepts printable ASCII there; another value is left out, so
// the service sees no token rather than the call failing in gRPC. The header parser bounds
// the whole header, so the values are bounded too.
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

}  // namespace

std::shared_ptr<GrpcCall> GrpcCall::prepare(
    grpc::GenericStub& stub, const std::string& method, const http::request_header<>& request,
    std::optional<std::chrono::system_clock::time_point> deadline,
    boost::asio::any_io_executor strand, Events events, std::atomic<int>& live) {
  std::shared_ptr<GrpcCall> call(new GrpcCall(std::move(strand), std::move(events), live));
  forward_authorization(request, call->context_);
  if (deadline) call->context_.set_deadline(*deadline);
  call->self_ = call;
  ++live;
  stub.PrepareBidiStreamingCall(&call->context_, method, grpc::StubOptions(), call.get());
  return call;
}

void GrpcCall::begin() {
  AddHold();
  StartCall();
}

void GrpcCall::release() {
  if (std::exchange(released_, true)) return;
  RemoveHold();
}

void GrpcCall::write(std::string_view message) {
  grpc::Slice slice(message.data(), message.size());
  out_ = grpc::ByteBuffer(&slice, 1);
  StartWrite(&out_);
}

void GrpcCall::writes_done() { StartWritesDone(); }

void GrpcCall::read() { StartRead(&in_); }

void GrpcCall::OnWriteDone(bool ok) {
  boost::asio::post(strand_, [self = self_, ok] { self->events_.wrote(ok); });
}

void GrpcCall::OnReadDone(bool ok) {
  boost::asio::post(strand_, [self = self_, ok] { self->events_.read(ok); });
}

void GrpcCall::OnDone(const grpc::Status& status) {
  std::atomic<int>& live = live_;  // the posted event may delete this call before the end
  auto self = std::move(self_);
  boost::asio::post(strand_, [self, status] {
    // Moved out: the handlers may hold what holds this call; dropping them ends the cycle.
    auto events = std::move(self->events_);
    events.done(status);
  });
  --live;  // last: once 0, the door may destroy the channel
}

}  // namespace hdeform::gateway

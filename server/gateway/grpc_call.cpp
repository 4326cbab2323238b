#include "gateway/grpc_call.h"

#include <boost/asio/post.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <utility>
#include <vector>

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
    boost::asio::any_io_executor strand, Events events, LiveCalls& live) {
  std::shared_ptr<GrpcCall> call(new GrpcCall(std::move(strand), std::move(events), live));
  forward_authorization(request, call->context_);
  if (deadline) call->context_.set_deadline(*deadline);
  call->self_ = call;
  live.add(call);
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
  LiveCalls& live = live_;  // the posted event may delete this call before the end
  const GrpcCall* const key = this;
  {
    auto self = std::move(self_);
    boost::asio::post(strand_, [self, status] {
      // Moved out: the handlers may hold what holds this call; dropping them ends the cycle.
      auto events = std::move(self->events_);
      events.done(status);
    });
  }  // OnDone's own reference goes before remove(): were it the last, the call (and its
     // strand executor) would be destroyed after stop() saw none left and the door's
     // io_context went (TSan, TlsGateway.HealthzAndGrpcWebOverHttps)
  live.remove(key);  // last (a key only): once none is left, the door may destroy the channel
}

void LiveCalls::add(const std::shared_ptr<GrpcCall>& call) {
  {
    std::lock_guard lock(mu_);
    calls_.emplace(call.get(), call);
    if (!closed_) return;
  }
  call->cancel();
}

void LiveCalls::remove(const GrpcCall* call) {
  std::lock_guard lock(mu_);
  calls_.erase(call);
  if (calls_.empty()) emptied_.notify_all();
}

void LiveCalls::close_and_cancel() {
  std::vector<std::shared_ptr<GrpcCall>> calls;
  {
    std::lock_guard lock(mu_);
    closed_ = true;
    calls.reserve(calls_.size());
    for (const auto& [key, weak] : calls_)
      if (auto call = weak.lock()) calls.push_back(std::move(call));
  }
  for (const auto& call : calls) call->cancel();
}

bool LiveCalls::wait_empty(std::chrono::milliseconds limit) {
  std::unique_lock lock(mu_);
  return emptied_.wait_for(lock, limit, [&] { return calls_.empty(); });
}

std::size_t LiveCalls::size() {
  std::lock_guard lock(mu_);
  return calls_.size();
}

}  // namespace hdeform::gateway

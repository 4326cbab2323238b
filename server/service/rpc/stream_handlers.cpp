// The two long-lived streams: Deform (a client's drag) and WatchSession (events).
#include "service/rpc/deform_service.h"

#include "service/rpc/failed_stream.h"
#include "service/rpc/reactors.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"

namespace hdeform::service {

grpc::ServerBidiReactor<v1::DeformRequest, v1::Frame>* DeformService::Deform(
    grpc::CallbackServerContext* ctx) {
  return new_deform_reactor(this, ctx);
}

WatchStart DeformService::start_watch(grpc::CallbackServerContext* ctx,
                                     const v1::WatchSessionRequest& request) {
  WatchStart w;
  w.session = session_for(*ctx, request.name(), Access::kView, "WatchSession");
  check_frame_format(request.format(), "WatchSession", /*in_order_stream=*/true);
  if (request.has_client()) Roster::check_participant(request.client(), "WatchSession");
  Session& session = *w.session;
  // Each watcher's memory is bounded (one pending frame, one state); their number is too.
  if (static_cast<std::size_t>(session.observers().watchers()) >= options_.request.max_watchers)
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         session.name() + " has " + std::to_string(session.observers().watchers()) +
             " watchers, the limit (--max-watchers)");
  // MESHOPT_DELTA costs an encode per frame and 8 bytes per vertex per watcher: fewer of them.
  const bool delta = request.format().encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA;
  if (delta && !session.observers().acquire_delta_watcher(options_.request.max_delta_watchers))
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         session.name() + " has " + std::to_string(session.observers().delta_watchers()) +
             " MESHOPT_DELTA watchers, the limit (--max-delta-watchers); ask MESHOPT, whose "
             "encode all watchers share");
  if (request.has_client()) {
    try {
      w.claim = session.join(request.client(), can_edit(*ctx, session));
    } catch (...) {
      if (delta) session.observers().release_delta_watcher();
      throw;
    }
    w.client_id = request.client().client_id();
  }
  return w;
}

grpc::ServerWriteReactor<v1::SessionEvent>* DeformService::WatchSession(
    grpc::CallbackServerContext* ctx, const v1::WatchSessionRequest* request) {
  auto authorize = [this, ctx](AuthorizedStream& a) { bind_stream(*ctx, a, Access::kView); };
  if (!store_.resident(request->name())) {
    // Finding it restores it (parse, factorize) or reads the store: on the pool.
    const auto admitted = guarded([this] { admit_to_pool(); }, "WatchSession");
    if (!admitted.ok()) return failed_stream<v1::SessionEvent>(admitted);
    return new_deferred_watch_reactor([this, ctx, request] { return start_watch(ctx, *request); },
                                      request->format(), *pool_, authorize);
  }
  WatchStart w;
  const auto status = guarded([&] { w = start_watch(ctx, *request); }, "WatchSession");
  if (!status.ok()) return failed_stream<v1::SessionEvent>(status);
  return new_watch_reactor(std::move(w.session), request->format(), std::move(w.client_id),
                           w.claim, *pool_, authorize);
}

}  // namespace hdeform::service

// Session: who is connected (observers.h) and what they are told — tokens and the streams
// they authorized, the events broadcast to watchers, presence and handle grabs.
#include "service/session/session.h"

#include "engine/runtime/elapsed_ms.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

Access Session::grant(const std::vector<TokenHash>& token_hashes) const {
  std::lock_guard lock(mutex_);
  return tokens_.grant(token_hashes);
}

IssuedTokens Session::rotate_tokens() {
  IssuedTokens issued;
  std::vector<std::shared_ptr<AuthorizedStream>> revoked;
  {
    std::lock_guard lock(mutex_);
    issued = tokens_.issue();
    // Every stream opened with a token that no longer grants what it needs ends now.
    revoked = observers_.take_if([&](const AuthorizedStream& a) {
      return !a.token_hashes.empty() &&
             static_cast<int>(tokens_.grant(a.token_hashes)) < static_cast<int>(a.needed);
    });
  }
  const grpc::Status why(grpc::StatusCode::UNAUTHENTICATED,
                         "the tokens of " + name_ +
                             " were rotated (RotateTokens): the token this stream was opened "
                             "with no longer grants access; reconnect with a new token");
  for (auto& r : revoked) r->revoke(why);
  if (!revoked.empty()) broadcast_state();  // the observer count changed
  return issued;
}

SessionTokens Session::tokens() const {
  std::lock_guard lock(mutex_);
  return tokens_;
}

void Session::broadcast_state(const EventSink* except) {
  if (observers_.watchers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_state() = describe();
  observers_.broadcast(std::move(event), except);
}

void Session::broadcast_step(const pb::HistoryStep& step) {
  if (observers_.watchers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_step() = step;
  observers_.broadcast(std::move(event));
}

void Session::broadcast_frame(const std::string& client_id) {
  std::shared_ptr<const ConstraintSet> cs;
  SessionBeta beta;
  std::vector<HandleTransform> transforms;
  std::int64_t version = 0;
  {
    std::lock_guard lock(mutex_);
    cs = cs_;
    beta = beta_;
    transforms = transforms_;
    version = version_;
  }
  if (!cs) return;
  const auto t0 = std::chrono::steady_clock::now();
  Update u;
  u.energies = true;
  std::shared_ptr<hdeform::Frame> frame = solve_move(*cs, transforms, beta, u);
  auto out = std::make_shared<pb::Frame>();
  mesh_->layout->fill(*frame, out.get());
  out->set_session(name_);
  out->set_version(version);
  out->set_client_id(client_id);
  for (const auto& t : transforms) to_proto(t, out->add_transforms());
  beta_to_proto(beta, out->mutable_beta(), false);
  out->set_solve_ms(elapsed_ms(t0));
  {
    std::lock_guard lock(mutex_);
    if (version == version_ && cs == cs_) {
      last_frame_ = frame;
      last_frame_version_ = version;
    }
  }
  if (observers_.watchers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_frame() = *out;
  observers_.broadcast(std::move(event));
}

pb::Presence Session::presence() const {
  pb::Presence out;
  roster_.describe(&out);
  out.set_version(version());
  return out;
}

void Session::broadcast_presence() {
  if (observers_.watchers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_presence() = presence();
  observers_.broadcast(std::move(event));
}

Roster::Claim Session::join(const pb::Participant& who, bool editor) {
  const auto claim = roster_.join(who, editor);
  broadcast_presence();
  return claim;
}

void Session::leave(const std::string& client_id, Roster::Claim claim) {
  const auto left = roster_.leave(client_id, claim);
  if (left == Roster::Left::kDisplaced) return;  // the id is someone else's now
  if (left == Roster::Left::kChanged && !closed_) broadcast_presence();
  close_drag(client_id);  // a vanished client's drag ends where it stopped
}

pb::GrabHandlesResponse Session::grab(const pb::GrabHandlesRequest& request, bool editor) {
  touch();
  Roster::check_participant(request.client(), "GrabHandles");
  if (request.handles_size() == 0)
    fail(grpc::StatusCode::INVALID_ARGUMENT, "GrabHandles: handles is empty");
  const std::vector<int> handles = handle_indices(request.handles(), "GrabHandles");
  const auto now = Roster::Clock::now();
  const auto until = roster_.grab(request.client(), editor, handles,
                                  std::chrono::milliseconds(request.lease_ms()), now);
  broadcast_presence();
  pb::GrabHandlesResponse out;
  *out.mutable_presence() = presence();
  out.set_lease_expire_unix_ms(
      unix_ms_now() + std::chrono::duration_cast<std::chrono::milliseconds>(until - now).count());
  return out;
}

pb::GrabHandlesResponse Session::release(const pb::ReleaseHandlesRequest& request) {
  touch();
  pb::Participant who;
  who.set_client_id(request.client_id());
  Roster::check_participant(who, "ReleaseHandles");
  const std::vector<int> handles = handle_indices(request.handles(), "ReleaseHandles");
  if (roster_.release(request.client_id(), handles)) broadcast_presence();
  close_drag(request.client_id());
  pb::GrabHandlesResponse out;
  *out.mutable_presence() = presence();
  return out;
}

void Session::expire_leases() {
  if (roster_.expire(Roster::Clock::now())) broadcast_presence();
}

void Session::add_watcher(std::shared_ptr<EventSink> sink) {
  touch();
  auto event = std::make_shared<pb::SessionEvent>();
  {
    std::lock_guard lock(mutex_);  // the state the sink gets is the one it joined
    if (observers_.add_watcher(sink))
      describe_locked(event->mutable_state());
    else
      event->set_deleted(name_);
  }
  sink->push(event);
  if (event->has_deleted()) {
    sink->close();
    return;
  }
  auto who = std::make_shared<pb::SessionEvent>();
  *who->mutable_presence() = presence();  // who is here, before anyone moves
  sink->push(std::move(who));
  if (auto t = timeline(); t.keys_size() > 0) {
    auto event = std::make_shared<pb::SessionEvent>();
    *event->mutable_timeline() = std::move(t);
    sink->push(std::move(event));
  }
  // The others see the new observer count; the newcomer's own first event already has it.
  broadcast_state(sink.get());
}

void Session::remove_watcher(const EventSink* sink) {
  const bool removed = observers_.remove_watcher(sink);
  touch();
  if (removed && !closed_) broadcast_state();
}

}  // namespace hdeform::service

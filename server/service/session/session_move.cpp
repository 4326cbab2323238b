// Handle moves: the drag path (begin, solve, commit or supersede) and its coalescing; a
// move that changes β or the pose goes through the store step before it is committed.
#include "service/session/session.h"

#include "engine/runtime/elapsed_ms.h"
#include "engine/runtime/warm_cores.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/handle_update.h"
#include "service/session/session_detail.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

using detail::kNoConstraints;

std::vector<int> Session::handle_indices(
    const google::protobuf::RepeatedField<std::int32_t>& handles, const char* op) const {
  std::lock_guard lock(mutex_);
  if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
  const int n = cs_->num_handles();
  std::vector<bool> seen(static_cast<std::size_t>(n), false);
  std::vector<int> out;
  for (int i = 0; i < handles.size(); ++i) {
    const int h = handles.Get(i);
    if (h < 0 || h >= n)
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           std::string(op) + ": handles[" + std::to_string(i) + "] = " + std::to_string(h) +
               " is not a handle of " + name_ + " (it has " + std::to_string(n) + ")");
    if (seen[static_cast<std::size_t>(h)])
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           std::string(op) + ": handles names handle " + std::to_string(h) + " twice");
    seen[static_cast<std::size_t>(h)] = true;
    out.push_back(h);
  }
  return out;
}

Session::Move Session::begin_move(const Update& u) {
  Move m;
  const bool keep = u.keep_transforms_if_empty && (!u.transforms || u.transforms->empty());
  {
    std::lock_guard lock(mutex_);
    // A Deform stream holds its session directly: after DeleteSession it must stop too.
    if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
    if (!cs_) fail(grpc::StatusCode::FAILED_PRECONDITION, kNoConstraints);
    check_version_locked(u.expected_version);
    m.cs = cs_;
    m.beta = beta_;
    m.key = cs_key_;
    m.transforms = transforms_;  // updates run on the strand: nothing moves them meanwhile
    m.version = version_;
    if (u.sequenced && u.coalesce && u.sequence > 0) {
      const auto last = sequences_.last(u.client_id);
      if (last && u.sequence <= last->sequence) m.newer = last;
    }
  }
  if (keep || m.newer) return m;
  static const google::protobuf::RepeatedPtrField<pb::HandleTransform> kNone;
  static const google::protobuf::RepeatedField<std::int32_t> kAll;
  m.moved = apply_handle_update(u.handles ? *u.handles : kAll,
                                u.transforms ? *u.transforms : kNone, *m.cs, m.transforms);
  roster_.check_move(u.client_id, m.moved, Roster::Clock::now());
  return m;
}

pb::Frame Session::supersede(const Update& u) {
  touch();
  Move m = begin_move(u);
  std::unique_lock<std::mutex> stored;
  if (store_gate_ && !m.newer) {
    const PendingPose pose{m.transforms, m.beta, m.version + 1, false};
    stored = store(&pose);
  }
  std::lock_guard lock(mutex_);
  if (cs_ == m.cs && !m.newer) {
    history_.drag_moved(u.client_id, m.moved, transforms_);  // the newer update ends the step
    transforms_ = std::move(m.transforms);
    ++version_;  // the newer update's frame follows at once
    last_frame_.reset();
    if (u.sequenced && u.sequence > 0) sequences_.applied(u.client_id, {u.sequence, u.dragging});
  }
  return superseded_locked(u);
}

pb::Frame Session::superseded_locked(const Update& u) const {
  pb::Frame out;
  out.set_session(name_);
  out.set_sequence(u.sequence);
  out.set_version(version_);
  out.set_client_id(u.client_id);
  out.set_superseded(true);
  return out;
}

std::shared_ptr<pb::Frame> Session::update(const Update& given) {
  touch();
  // The next move of this drag comes in ≈ 50 ms: the cores must not halt meanwhile.
  if (given.dragging) hdeform::WarmCores::instance().extend();
  const auto t0 = std::chrono::steady_clock::now();
  Move m = begin_move(given);
  Update u = given;
  if (m.newer) {
    // Stale: the client's newer update was applied. If it was solved, nothing is left to do;
    // if it was superseded by this one (it arrived first), solve its pose as it asked.
    std::lock_guard lock(mutex_);
    if (last_frame_ && last_frame_version_ == version_)
      return std::make_shared<pb::Frame>(superseded_locked(u));
    u.dragging = m.newer->dragging;
  }
  const auto& cs = m.cs;
  const auto& key = m.key;
  SessionBeta& beta = m.beta;
  std::vector<HandleTransform>& transforms = m.transforms;
  bool beta_changed = false;
  if (u.beta) {
    SessionBeta b = parse_beta(*u.beta);
    if (b.automatic) pick_beta(b, *cs, transforms);  // at the transforms being committed
    beta_changed = !b.same_as(beta);
    beta = std::move(b);
  }
  std::shared_ptr<hdeform::Frame> frame = solve_move(*cs, transforms, beta, u);
  if (beta_changed) cache_.update_size(key, cs->base_bytes());

  // Stored first where an answered move must be durable: a refusal leaves nothing applied.
  std::unique_lock<std::mutex> stored;
  if (store_gate_) {
    const PendingPose pose{transforms, beta, m.version + 1, beta_changed};
    stored = store(&pose);
  }
  auto out = std::make_shared<pb::Frame>();
  pb::HistoryStep recorded;
  mesh_->layout->fill(*frame, out.get());
  out->set_session(name_);
  out->set_sequence(u.sequence);
  out->set_client_id(u.client_id);
  for (const auto& t : transforms) to_proto(t, out->add_transforms());
  beta_to_proto(beta, out->mutable_beta(), false);
  {
    std::lock_guard lock(mutex_);
    if (cs_ != cs) {
      // SetConstraints cannot interleave (same strand); this guards against misuse.
      fail(grpc::StatusCode::ABORTED, "constraints changed during the update");
    }
    // History: a drag is one step, from its first frame's before to its last frame.
    history_.drag_moved(u.client_id, m.moved, transforms_);
    std::map<int, HandleTransform> started;
    if (!u.dragging) started = history_.end_drag(u.client_id);
    bool moved_any = false;
    for (const auto& [h, t] : started)
      moved_any = moved_any || !same_transform(t, transforms[static_cast<std::size_t>(h)]);
    std::optional<Step> step_made;
    if (moved_any || beta_changed) {
      Step& step = step_made.emplace();
      step.before = edit_state_locked();
      for (const auto& [h, t] : started) {
        // A handle sent back to where it was (or a frame refresh) is not a change.
        if (same_transform(t, transforms[static_cast<std::size_t>(h)])) continue;
        step.before.transforms[static_cast<std::size_t>(h)] = t;
        step.handles.push_back(h);
      }
      step.beta = beta_changed;
      step.after = edit_state_locked();
      step.after.beta = beta;
      step.after.transforms = transforms;
      step.info.set_kind(step.handles.empty() ? pb::STEP_KIND_BETA : pb::STEP_KIND_MOVE);
      step.info.set_client_id(u.client_id);
      std::string summary;
      for (int h : step.handles) summary += (summary.empty() ? "moved handle " : ", ") + std::to_string(h);
      if (beta_changed) summary += std::string(summary.empty() ? "" : "; ") + "beta changed";
      step.info.set_summary(summary);
    }
    transforms_ = std::move(transforms);
    beta_ = beta;
    if (u.sequenced && u.sequence > 0 && !m.newer)
      sequences_.applied(u.client_id, {u.sequence, u.dragging});
    if (beta_changed) ++config_version_;
    ++version_;
    {
      std::lock_guard moves(move_mutex_);  // the old frame's buffers serve a later move
      if (last_frame_ && last_frame_.use_count() == 1)
        spare_frame_ = std::const_pointer_cast<hdeform::Frame>(std::move(last_frame_));
    }
    last_frame_ = frame;
    last_frame_version_ = version_;
    update_ms_ = unix_ms_now();
    out->set_version(version_);
    if (step_made) recorded = record_locked(std::move(*step_made));
  }
  out->set_solve_ms(elapsed_ms(t0));
  if (beta_changed) broadcast_state();
  if (recorded.id() != 0) broadcast_step(recorded);
  if (observers_.watchers() > 0) {
    auto event = std::make_shared<pb::SessionEvent>();
    *event->mutable_frame() = *out;
    observers_.broadcast(std::move(event));
  }
  if (u.float64) {
    auto out64 = std::make_shared<pb::Frame>();
    copy_frame_header(*out, out64.get());
    out64->set_encoding(pb::FRAME_ENCODING_FLOAT64);
    out64->set_positions(mesh_->layout->pack_vertices64(frame->positions));
    if (frame->normals.rows() == frame->positions.rows())
      out64->set_normals(mesh_->layout->pack_vertices64(frame->normals));
    out64->set_energies(out->energies());
    return out64;
  }
  return out;
}

std::unique_ptr<Session::CoalesceTicket> Session::coalesce_ticket(std::size_t limit) {
  if (coalesce_waiting_.fetch_add(1) >= limit) {
    const std::size_t waiting = --coalesce_waiting_;
    fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
         name_ + " has " + std::to_string(waiting) +
             " coalescing updates waiting, the limit (--max-pending-updates); send the next "
             "one when an answer arrives");
  }
  return std::make_unique<CoalesceTicket>(*this, ++coalesce_newest_);
}

}  // namespace hdeform::service

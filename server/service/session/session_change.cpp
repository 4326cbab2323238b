// The one commit path of a change: execute() validates, authorizes, admits, applies, stores,
// records and broadcasts a Change; set_constraints and set_beta are its commands.
#include "service/session/session.h"

#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/session_detail.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

pb::Session Session::set_constraints(const pb::Constraints& constraints,
                                     std::int64_t expected_version,
                                     std::int64_t expected_config_version,
                                     const std::string& client_id, bool discard_timeline) {
  touch();
  {
    std::lock_guard lock(mutex_);
    check_version_locked(expected_version);
    check_config_version_locked(expected_config_version);
  }
  Change change;
  change.cs = constraint_set_of(constraints, &change.target.cs_key);
  const ConstraintSet& cs = *change.cs;
  {
    std::lock_guard lock(mutex_);
    const std::string key = std::move(change.target.cs_key);
    change.target = edit_state_locked();
    change.target.cs_key = key;
  }
  change.target.given = std::make_shared<const pb::Constraints>(constraints);
  change.target.transforms.assign(cs.num_handles(), HandleTransform{});
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_CONSTRAINTS);
  step.info.set_client_id(client_id);
  step.info.set_summary("constraints: " + std::to_string(cs.constraints().fixed.size()) +
                        " fixed vertices, " + std::to_string(cs.num_handles()) + " handle(s)");
  step.constraints = true;
  change.discard_timeline = discard_timeline;
  return execute(std::move(change));
}

pb::HistoryStep Session::record_locked(Step step) {
  step.info.set_version(version_);
  step.info.set_time_unix_ms(unix_ms_now());
  step.info.set_author(author_of(step.info.client_id()));
  step.info.set_beta_changed(step.beta);
  step.info.set_timeline_changed(step.timeline);
  if (!step.snapshot.empty()) step.info.set_snapshot(step.snapshot);
  step.info.mutable_handles()->Assign(step.handles.begin(), step.handles.end());
  return history_.record(std::move(step));
}

pb::Session Session::execute(Change change) {
  EditState& target = change.target;
  Step& step = change.step;
  std::shared_ptr<const ConstraintSet>& cs = change.cs;
  std::string current_key;
  {
    std::lock_guard lock(mutex_);
    current_key = cs_key_;
    if (!cs && target.cs_key == cs_key_) cs = cs_;
  }
  // Build and account, outside the lock: the set and the β factorization the target needs
  // (ConstraintSet::prepare is thread-safe; an automatic β keeps its pick).
  if (!cs && !target.cs_key.empty()) {
    std::string key;
    cs = constraint_set_of(*target.given, &key);
    target.cs_key = key;
  }
  if (cs && step.changes_pose()) {
    prepare_beta(*cs, target.beta);
    cache_.update_size(target.cs_key, cs->base_bytes());
  }
  const bool constraints_changed = target.cs_key != current_key;
  pb::Session out;
  pb::HistoryStep info;
  bool pose_changed = false;
  Applied applied;
  {
    std::lock_guard lock(mutex_);
    // Check: everything below must succeed once it starts.
    const bool drops_keys = constraints_changed && !step.timeline && timeline_->keys_size() > 0;
    if (drops_keys && !change.discard_timeline &&
        timeline_->client_id() != step.info.client_id())
      fail(grpc::StatusCode::ABORTED,
           "new constraints would drop the timeline's " + std::to_string(timeline_->keys_size()) +
               " key(s) set by " + timeline_->author() +
               " (a key's transforms are per handle): send discard_timeline to drop them "
               "anyway (Undo brings them back)");
    if (!step.snapshot.empty() && target.snapshot && !snapshots_.count(step.snapshot))
      check_limit(snapshots_.size() + 1, limits_.max_snapshots, "named snapshots of " + name_,
                  "--max-snapshots");

    // Apply.
    step.before = edit_state_locked(step.snapshot);
    const bool beta_changed = !beta_.same_as(target.beta);
    step.beta = step.beta || beta_changed;
    if (step.constraints || constraints_changed) {
      step.constraints = true;
      step.handles.clear();
      for (int j = 0; j < (cs ? cs->num_handles() : 0); ++j) step.handles.push_back(j);
    }
    applied = applied_locked(step.snapshot);
    pose_changed = step.changes_pose();
    if (pose_changed) {
      cs_ = cs;
      cs_key_ = target.cs_key;
      given_ = target.given;
      beta_ = target.beta;
      transforms_ = target.transforms;
      if (constraints_changed || beta_changed) ++config_version_;
      changed_locked(&out);
    } else {
      describe_locked(&out);
    }
    if (drops_keys) {
      auto cleared = std::make_shared<pb::Timeline>();
      cleared->set_version(version_);
      cleared->set_author(author_of(step.info.client_id()));
      cleared->set_client_id(step.info.client_id());
      target.timeline = std::move(cleared);
      step.timeline = true;
    }
    if (step.timeline) timeline_ = target.timeline;
    if (!step.snapshot.empty()) {
      if (target.snapshot) snapshots_[step.snapshot] = target.snapshot;
      else snapshots_.erase(step.snapshot);
    }
    step.after = std::move(target);
  }
  // Store: a refusal puts the session back as it was; nothing was recorded or told.
  if (store_gate_) store(nullptr, &applied, step.snapshot);  // applied: no lock to hold
  {
    std::lock_guard lock(mutex_);
    if (step.constraints) history_.forget_drags();
    info = record_locked(std::move(step));
  }
  // Broadcast.
  if (pose_changed) broadcast_state();
  broadcast_step(info);
  if (info.timeline_changed()) broadcast_timeline();
  if (constraints_changed && roster_.release_all()) broadcast_presence();  // renumbered
  if (change.send_frame && pose_changed) broadcast_frame(info.client_id());
  return out;
}

std::unique_lock<std::mutex> Session::store(const PendingPose* pose, Applied* applied,
                                            const std::string& snapshot) {
  try {
    return store_gate_(*this, pose);
  } catch (...) {
    std::lock_guard lock(mutex_);
    if (applied) put_back_locked(std::move(*applied), snapshot);
    // A write that timed out may still land: the refused change's version is never used
    // again, so this copy's next record (the flusher's) overrides whatever the store holds.
    ++version_;
    throw;
  }
}

Session::Applied Session::applied_locked(const std::string& snapshot) const {
  return {edit_state_locked(snapshot), cs_, version_, config_version_, update_ms_, last_frame_,
          last_frame_version_};
}

void Session::put_back_locked(Applied a, const std::string& snapshot) {
  cs_ = std::move(a.cs);
  cs_key_ = std::move(a.state.cs_key);
  given_ = std::move(a.state.given);
  beta_ = std::move(a.state.beta);
  transforms_ = std::move(a.state.transforms);
  timeline_ = std::move(a.state.timeline);
  if (!snapshot.empty()) {
    if (a.state.snapshot) snapshots_[snapshot] = std::move(a.state.snapshot);
    else snapshots_.erase(snapshot);
  }
  version_ = a.version;
  config_version_ = a.config_version;
  update_ms_ = a.update_ms;
  last_frame_ = std::move(a.last_frame);
  last_frame_version_ = a.last_frame_version;
}

pb::Session Session::set_beta(const pb::Beta& beta_msg, std::int64_t expected_version,
                              std::int64_t expected_config_version,
                              const std::string& client_id) {
  touch();
  SessionBeta beta = parse_beta(beta_msg);
  EditState target;
  std::shared_ptr<const ConstraintSet> cs;
  {
    std::lock_guard lock(mutex_);
    check_version_locked(expected_version);
    check_config_version_locked(expected_config_version);
    cs = cs_;
    target = edit_state_locked();
  }
  if (beta.automatic) {
    if (!cs)
      fail(grpc::StatusCode::FAILED_PRECONDITION,
           "automatic beta is picked at the session's handle transforms: call SetConstraints "
           "first");
    pick_beta(beta, *cs, target.transforms);
  }
  if (beta.same_as(target.beta)) {  // nothing changes: no step, no new version
    std::lock_guard lock(mutex_);
    pb::Session out;
    describe_locked(&out);
    return out;
  }
  Change change;
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_BETA);
  step.info.set_client_id(client_id);
  char buf[96];
  std::snprintf(buf, sizeof buf, "beta %.6g -> %.6g (%s)%s", target.beta.uniform.value,
                beta.uniform.value, beta.uniform.units == BetaUnits::raw ? "raw" : "area",
                beta.automatic ? ", automatic" : "");
  step.info.set_summary(buf);
  step.beta = true;
  target.beta = std::move(beta);
  change.target = std::move(target);
  change.cs = std::move(cs);
  return execute(std::move(change));
}

}  // namespace hdeform::service

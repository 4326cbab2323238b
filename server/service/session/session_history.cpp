// Undo, redo and named snapshots: the history's steps are reverted through the same
// commit path as any change; the stored history is adopted on restore.
#include "service/session/session.h"

#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/history_record.h"
#include "service/session/session_detail.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>

namespace hdeform::service {

void Session::adopt_history(const std::optional<std::string>& stored) {
  std::lock_guard lock(mutex_);
  if (!stored) {
    history_.clear("the session was restored from stored state that kept no history");
    return;
  }
  try {
    hdeform::state::StoredHistory record;
    if (!record.ParseFromString(*stored)) throw std::runtime_error("not a stored history");
    HistoryContext context{edit_state_locked(), snapshots_,
                           [this](const pb::Beta& b) { return parse_beta(b, true); }};
    history_from_record(record, context, history_);
  } catch (const std::exception& e) {
    spdlog::warn("{}: its stored history cannot be read ({}); it starts a new one", name_, e.what());
    history_.clear("the stored history could not be read after a restart: " +
                   std::string(e.what()));
  }
}

std::string Session::history_bytes(std::uint64_t* revision) const {
  // A copy under the lock (steps share their values): the conversion and serialization, up to
  // the history's byte limit, run without holding up the session's edits.
  std::optional<History> copy;
  {
    std::lock_guard lock(mutex_);
    *revision = history_.revision();
    copy.emplace(history_);
  }
  return history_to_record(*copy).SerializeAsString();
}

std::uint64_t Session::history_revision() const {
  std::lock_guard lock(mutex_);
  return history_.revision();
}

// ---- history and snapshots ----

namespace {

void check_snapshot_name(const std::string& name, const char* op) {
  const auto chars = std::count_if(name.begin(), name.end(), [](char c) {
    return (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  });
  if (name.empty() || chars > 64)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(op) + ": the snapshot name must have 1–64 characters, got " +
             std::to_string(chars));
  if (std::any_of(name.begin(), name.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return u < 0x20 || u == 0x7f;
      }))
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(op) + ": the snapshot name has control characters");
}

}  // namespace

void Session::close_drag(const std::string& client_id) {
  pb::HistoryStep info;
  {
    std::lock_guard lock(mutex_);
    auto started = history_.end_drag(client_id);
    if (started.empty()) return;
    Step step;
    step.before = edit_state_locked();
    step.after = edit_state_locked();
    std::string summary;
    for (const auto& [h, t] : started) {
      if (same_transform(t, step.after.transforms[static_cast<std::size_t>(h)])) continue;
      step.before.transforms[static_cast<std::size_t>(h)] = t;
      step.handles.push_back(h);
      summary += (summary.empty() ? "moved handle " : ", ") + std::to_string(h);
    }
    if (step.handles.empty()) return;  // back where it started: no change
    step.info.set_kind(pb::STEP_KIND_MOVE);
    step.info.set_client_id(client_id);
    step.info.set_summary(summary);
    info = record_locked(std::move(step));
  }
  broadcast_step(info);
}

pb::Session Session::undo(const pb::UndoRequest& request) {
  close_drag(request.client_id());  // an unfinished drag is the step to undo
  return revert(request, true);
}

pb::Session Session::redo(const pb::UndoRequest& request) { return revert(request, false); }

pb::Session Session::revert(const pb::UndoRequest& request, bool undo) {
  touch();
  Change change;
  Step& step = change.step;
  std::int64_t target_id = 0;
  {
    std::lock_guard lock(mutex_);
    const Step& t = undo ? history_.undo_target(request.client_id(), request.step())
                         : history_.redo_target(request.client_id(), request.step());
    // Undo goes from the step's after to its before; redo the other way.
    const EditState& from = undo ? t.after : t.before;
    const EditState& to = undo ? t.before : t.after;
    const EditState current = edit_state_locked(t.snapshot);
    history_.check_unchanged(t, current, from, undo ? "Undo" : "Redo");
    change.target = current;
    apply_side(change.target, t, to);
    step.constraints = t.constraints;
    step.beta = t.beta;
    step.handles = t.handles;
    step.timeline = t.timeline;
    step.snapshot = t.snapshot;
    step.info.set_target(t.info.id());
    step.info.set_summary(std::string(undo ? "undo" : "redo") + " step " +
                          std::to_string(t.info.id()) + " (" + t.info.author() + ": " +
                          t.info.summary() + ")");
    target_id = t.info.id();
  }
  step.info.set_kind(undo ? pb::STEP_KIND_UNDO : pb::STEP_KIND_REDO);
  step.info.set_client_id(request.client_id());
  change.send_frame = true;
  change.discard_timeline = request.discard_timeline();
  pb::Session out = execute(std::move(change));
  std::lock_guard lock(mutex_);
  if (undo) history_.mark_undone(target_id, request.client_id());
  else history_.mark_redone(target_id, request.client_id());
  return out;
}

pb::ListHistoryResponse Session::list_history(const pb::ListHistoryRequest& request) const {
  if (request.page_size() < 0 || request.page_size() > 500)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         "ListHistory: page_size must be 0 (50) to 500, got " +
             std::to_string(request.page_size()));
  std::int64_t before = 0;
  if (!request.page_token().empty()) {
    const auto& t = request.page_token();
    auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), before);
    if (ec != std::errc() || end != t.data() + t.size() || before <= 0)
      fail(grpc::StatusCode::INVALID_ARGUMENT,
           "ListHistory: page_token is not one this server gave (\"" + t.substr(0, 32) + "\")");
  }
  const std::size_t size = request.page_size() == 0 ? 50 : static_cast<std::size_t>(request.page_size());
  pb::ListHistoryResponse out;
  std::lock_guard lock(mutex_);
  auto steps = history_.page(before, size + 1);
  const bool more = steps.size() > size;
  if (more) steps.pop_back();
  for (auto& st : steps) *out.add_steps() = std::move(st);
  if (more) out.set_next_page_token(std::to_string(out.steps(out.steps_size() - 1).id()));
  out.set_total(history_.size());
  return out;
}

pb::NamedSnapshot Session::save_snapshot(const pb::SaveSnapshotRequest& request) {
  touch();
  check_snapshot_name(request.snapshot(), "SaveSnapshot");
  auto named = std::make_shared<pb::NamedSnapshot>();
  named->set_name(request.snapshot());
  named->set_author(author_of(request.client_id()));
  named->set_time_unix_ms(unix_ms_now());
  std::int64_t version = 0;
  *named->mutable_snapshot() = export_snapshot(false, &version);
  named->mutable_snapshot()->clear_timeline();  // a named snapshot is the pose, not the timeline
  named->set_version(version);
  Change change;
  {
    std::lock_guard lock(mutex_);
    change.target = edit_state_locked(request.snapshot());
  }
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_SNAPSHOT_SAVE);
  step.info.set_client_id(request.client_id());
  step.info.set_summary(std::string(change.target.snapshot ? "replaced" : "saved") +
                        " snapshot '" + request.snapshot() + "'");
  step.snapshot = request.snapshot();
  change.target.snapshot = named;
  execute(std::move(change));
  return *named;
}

pb::ListSnapshotsResponse Session::list_snapshots() const {
  pb::ListSnapshotsResponse out;
  std::lock_guard lock(mutex_);
  for (const auto& [name, snap] : snapshots_) *out.add_snapshots() = *snap;
  return out;
}

void Session::delete_snapshot(const std::string& snapshot, const std::string& client_id) {
  touch();
  Change change;
  {
    std::lock_guard lock(mutex_);
    change.target = edit_state_locked(snapshot);
  }
  if (!change.target.snapshot)
    fail(grpc::StatusCode::NOT_FOUND, "DeleteSnapshot: " + name_ + " has no snapshot named '" +
                                          snapshot.substr(0, 64) + "'");
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_SNAPSHOT_DELETE);
  step.info.set_client_id(client_id);
  step.info.set_summary("deleted snapshot '" + snapshot + "'");
  step.snapshot = snapshot;
  change.target.snapshot = nullptr;
  execute(std::move(change));
}

void Session::adopt_snapshots(
    const google::protobuf::RepeatedPtrField<pb::NamedSnapshot>& snapshots) {
  std::lock_guard lock(mutex_);
  for (const auto& s : snapshots) snapshots_[s.name()] = std::make_shared<const pb::NamedSnapshot>(s);
}

pb::Session Session::restore_snapshot(const pb::RestoreSnapshotRequest& request) {
  touch();
  pb::NamedSnapshot named;
  EditState target;
  {
    std::lock_guard lock(mutex_);
    check_config_version_locked(request.expected_config_version());
    auto it = snapshots_.find(request.snapshot());
    if (it == snapshots_.end())
      fail(grpc::StatusCode::NOT_FOUND, "RestoreSnapshot: " + name_ + " has no snapshot named '" +
                                            request.snapshot().substr(0, 64) + "'");
    named = *it->second;
    target = edit_state_locked();
  }
  const pb::Snapshot& snap = named.snapshot();
  std::shared_ptr<const ConstraintSet> cs;
  target.cs_key.clear();
  target.given.reset();
  target.transforms.clear();
  if (snap.has_constraints() &&
      (snap.constraints().fixed().selectors_size() > 0 || snap.constraints().handles_size() > 0)) {
    cs = constraint_set_of(snap.constraints(), &target.cs_key);
    target.given = std::make_shared<const pb::Constraints>(snap.constraints());
    target.transforms = snap.transforms_size() > 0
                            ? from_proto(snap.transforms(), *cs)
                            : std::vector<HandleTransform>(cs->num_handles());
  }
  target.beta = snap.has_beta() ? parse_beta(snap.beta(), true) : SessionBeta{};
  Change change;
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_RESTORE);
  step.info.set_client_id(request.client_id());
  step.info.set_snapshot(named.name());
  step.info.set_summary("restored snapshot '" + named.name() + "'");
  step.constraints = true;
  step.beta = true;
  change.target = std::move(target);
  change.cs = std::move(cs);
  change.send_frame = true;
  change.discard_timeline = request.discard_timeline();
  return execute(std::move(change));
}

}  // namespace hdeform::service

#include "service/session/history.h"

#include "service/infra/service_error.h"

#include <algorithm>

namespace hdeform::service {

bool same_transform(const HandleTransform& a, const HandleTransform& b) {
  if (a.rotation.coeffs() != b.rotation.coeffs() || a.stretch != b.stretch ||
      a.translation != b.translation)
    return false;
  if (a.pivot.has_value() == b.pivot.has_value() && (!a.pivot || *a.pivot == *b.pivot))
    return true;
  // Without rotation and stretch the pivot moves nothing (x' = x + t): the viewer's reset
  // sends its identity with the centroid as pivot, and that is no move.
  return a.rotation.coeffs() == Eigen::Quaterniond::Identity().coeffs() &&
         a.stretch == Eigen::Matrix3d::Identity();
}

namespace {

// What a step keeps alive: the values of the parts it changed (the others are shared with
// the session or other steps and are counted there).
std::size_t kept_bytes(const Step& s) {
  std::size_t n = 0;
  for (const EditState* side : {&s.before, &s.after}) {
    if (s.constraints && side->given) n += side->given->ByteSizeLong();
    if (s.timeline && side->timeline) n += side->timeline->ByteSizeLong();
    if (!s.snapshot.empty() && side->snapshot) n += side->snapshot->ByteSizeLong();
  }
  return n;
}

bool undoable_kind(pb::StepKind k) {
  return k != pb::STEP_KIND_UNSPECIFIED && k != pb::STEP_KIND_UNDO && k != pb::STEP_KIND_REDO;
}

std::string describe(const pb::HistoryStep& s) {
  return "step " + std::to_string(s.id()) + " (" + s.author() + ": " + s.summary() + ")";
}

}  // namespace

void apply_side(EditState& state, const Step& step, const EditState& side) {
  if (step.constraints) {
    state.cs_key = side.cs_key;
    state.given = side.given;
    state.transforms = side.transforms;
  } else {
    for (int h : step.handles)
      state.transforms[static_cast<std::size_t>(h)] = side.transforms[static_cast<std::size_t>(h)];
  }
  if (step.beta) state.beta = side.beta;
  if (step.timeline) state.timeline = side.timeline;
  if (!step.snapshot.empty()) state.snapshot = side.snapshot;
}

namespace {

bool beta_only(const Step& s) {
  return s.info.kind() == pb::STEP_KIND_BETA && s.beta && !s.constraints && s.handles.empty();
}

}  // namespace

const pb::HistoryStep& History::record(Step step) {
  if (!steps_.empty() && beta_only(step) && !step.info.client_id().empty()) {
    Step& last = steps_.back();
    if (beta_only(last) && last.info.client_id() == step.info.client_id() &&
        !last.info.undone() &&
        step.info.time_unix_ms() - last.info.time_unix_ms() <= kGestureMs &&
        step.info.time_unix_ms() >= last.info.time_unix_ms()) {
      // "beta A -> B (units)" + "beta B -> C (units)" = "beta A -> C (units)".
      const std::string& first = last.info.summary();
      const std::string& next = step.info.summary();
      const auto arrow_first = first.find(" -> "), arrow_next = next.find(" -> ");
      if (arrow_first != std::string::npos && arrow_next != std::string::npos)
        last.info.set_summary(first.substr(0, arrow_first) + next.substr(arrow_next));
      last.after = std::move(step.after);
      last.info.set_version(step.info.version());
      last.info.set_time_unix_ms(step.info.time_unix_ms());
      ++revision_;
      return last.info;
    }
  }
  step.info.set_id(next_id_++);
  if (step.info.kind() != pb::STEP_KIND_UNDO && step.info.kind() != pb::STEP_KIND_REDO)
    redo_.erase(step.info.client_id());
  bytes_ += kept_bytes(step);
  steps_.push_back(std::move(step));
  enforce_limits();
  ++revision_;
  return steps_.back().info;
}

void History::enforce_limits() {
  while (steps_.size() > 1 &&
         (steps_.size() > limits_.max_steps || bytes_ > limits_.max_bytes)) {
    bytes_ -= kept_bytes(steps_.front());
    steps_.pop_front();
  }
}

void History::adopt(std::deque<Step> steps, std::int64_t next_id,
                    std::map<std::string, std::vector<std::int64_t>> redo) {
  clear();
  steps_ = std::move(steps);
  for (const auto& s : steps_) bytes_ += kept_bytes(s);
  next_id_ = std::max(next_id, steps_.empty() ? 1 : steps_.back().info.id() + 1);
  redo_ = std::move(redo);
  enforce_limits();
}

void History::drag_moved(const std::string& client_id, const std::vector<int>& handles,
                         const std::vector<HandleTransform>& before) {
  auto& d = drags_[client_id];
  for (int h : handles)
    if (!d.before.count(h)) d.before.emplace(h, before[static_cast<std::size_t>(h)]);
}

std::map<int, HandleTransform> History::end_drag(const std::string& client_id) {
  auto it = drags_.find(client_id);
  if (it == drags_.end()) return {};
  auto out = std::move(it->second.before);
  drags_.erase(it);
  return out;
}

void History::forget_drags() { drags_.clear(); }

const Step* History::find(std::int64_t id) const {
  for (const auto& s : steps_)
    if (s.info.id() == id) return &s;
  return nullptr;
}

Step* History::find(std::int64_t id) {
  return const_cast<Step*>(static_cast<const History*>(this)->find(id));
}

const Step& History::undo_target(const std::string& client_id, std::int64_t step) const {
  if (step != 0) {
    const Step* s = find(step);
    if (!s)
      fail(grpc::StatusCode::NOT_FOUND,
           "Undo: no step " + std::to_string(step) + " in the history (it keeps the last " +
               std::to_string(limits_.max_steps) + " steps, --max-history)");
    if (s->info.undone())
      fail(grpc::StatusCode::FAILED_PRECONDITION, "Undo: " + describe(s->info) + " is already undone");
    return *s;
  }
  for (auto it = steps_.rbegin(); it != steps_.rend(); ++it)
    if (it->info.client_id() == client_id && undoable_kind(it->info.kind()) && !it->info.undone())
      return *it;
  fail(grpc::StatusCode::FAILED_PRECONDITION,
       "Undo: nothing to undo for client '" + client_id +
           "' (no change of its own in the history" +
           (why_empty_.empty() ? std::string() : "; " + why_empty_) + ")");
}

void History::clear(std::string why) {
  steps_.clear();
  bytes_ = 0;
  redo_.clear();
  drags_.clear();
  why_empty_ = std::move(why);
  ++revision_;
}

const Step& History::redo_target(const std::string& client_id, std::int64_t step) const {
  if (step != 0) {
    const Step* s = find(step);
    if (!s || !s->info.undone())
      fail(grpc::StatusCode::FAILED_PRECONDITION,
           "Redo: step " + std::to_string(step) + " is not an undone step in the history");
    return *s;
  }
  auto it = redo_.find(client_id);
  if (it != redo_.end())
    for (auto id = it->second.rbegin(); id != it->second.rend(); ++id)
      if (const Step* s = find(*id); s && s->info.undone()) return *s;
  fail(grpc::StatusCode::FAILED_PRECONDITION,
       "Redo: nothing to redo for client '" + client_id +
           "' (its undos were redone, or it made a new change since)");
}

const Step* History::later_change(const Step& step) const {
  for (auto it = steps_.rbegin(); it != steps_.rend() && it->info.id() > step.info.id(); ++it) {
    const bool pose = step.changes_pose() || step.timeline;
    bool touches = (pose && it->constraints) ||
                   (step.constraints && (it->changes_pose() || it->timeline)) ||
                   (step.beta && it->beta) ||
                   (step.timeline && it->timeline) ||
                   (!step.snapshot.empty() && it->snapshot == step.snapshot);
    for (int h : step.handles)
      touches = touches || std::find(it->handles.begin(), it->handles.end(), h) != it->handles.end();
    if (touches) return &*it;
  }
  return nullptr;
}

void History::check_unchanged(const Step& step, const EditState& current,
                              const EditState& expect, const char* what) const {
  std::string changed;
  // Handles and keys mean something only for the constraint set they were made for; a
  // named snapshot is self-contained.
  const bool per_handle = step.changes_pose() || step.timeline;
  if (per_handle && current.cs_key != expect.cs_key) changed = "the constraints";
  else if (step.beta && !current.beta.same_as(expect.beta)) changed = "beta";
  else if (step.constraints) {
    bool same = current.transforms.size() == expect.transforms.size();
    for (std::size_t j = 0; same && j < current.transforms.size(); ++j)
      same = same_transform(current.transforms[j], expect.transforms[j]);
    if (!same) changed = "the handles' transforms";
  } else
    for (int h : step.handles)
      if (static_cast<std::size_t>(h) >= current.transforms.size() ||
          !same_transform(current.transforms[static_cast<std::size_t>(h)],
                          expect.transforms[static_cast<std::size_t>(h)])) {
        changed = "handle " + std::to_string(h);
        break;
      }
  if (changed.empty() && step.timeline && current.timeline != expect.timeline)
    changed = "the timeline";
  if (changed.empty() && !step.snapshot.empty() && current.snapshot != expect.snapshot)
    changed = "snapshot '" + step.snapshot + "'";
  if (changed.empty()) return;
  const Step* later = later_change(step);
  fail(grpc::StatusCode::ABORTED,
       std::string(what) + " of " + describe(step.info) + " refused: " + changed +
           " changed since" + (later ? " (" + describe(later->info) + ")" : std::string()) +
           "; reverting it would lose that change");
}

void History::mark_undone(std::int64_t target, const std::string& client_id) {
  ++revision_;
  if (Step* s = find(target)) s->info.set_undone(true);
  redo_[client_id].push_back(target);
}

void History::mark_redone(std::int64_t target, const std::string& client_id) {
  ++revision_;
  if (Step* s = find(target)) s->info.set_undone(false);
  auto& r = redo_[client_id];
  r.erase(std::remove(r.begin(), r.end(), target), r.end());
}

std::vector<pb::HistoryStep> History::page(std::int64_t before, std::size_t page_size) const {
  std::vector<pb::HistoryStep> out;
  for (auto it = steps_.rbegin(); it != steps_.rend() && out.size() < page_size; ++it)
    if (before == 0 || it->info.id() < before) out.push_back(it->info);
  return out;
}

}  // namespace hdeform::service

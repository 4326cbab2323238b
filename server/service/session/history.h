// A session's history (docs/api.md "History and snapshots"): every accepted change as a step
// with its author and time, and what it changed as before / after values, so that undo and
// redo can revert exactly that change — and refuse when a later change touched the same
// thing (the handle, β, or the constraints), instead of losing it silently.
// Not thread-safe: the session guards it with its own mutex.
#pragma once

#include "engine/mesh/transform.h"
#include "service/session/session_beta.h"

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace hdeform::service {

// The parts of a session a step may change. Constraints by their cache key and as given (a
// step never pins a ConstraintSet and its factorizations in memory). Values are immutable
// and shared, so a step's before/after cost a pointer each, and "unchanged since" is
// pointer equality for the timeline and snapshots.
struct EditState {
  std::string cs_key;
  std::shared_ptr<const pb::Constraints> given;
  SessionBeta beta;
  std::vector<HandleTransform> transforms;
  std::shared_ptr<const pb::Timeline> timeline;  // keys per handle of cs_key's set
  // A step on one named snapshot (Step::snapshot): its value on this side; null: absent.
  std::shared_ptr<const pb::NamedSnapshot> snapshot;
};

// The same transform, or one that moves every point the same way because neither rotates
// nor stretches (then the pivot is irrelevant).
bool same_transform(const HandleTransform& a, const HandleTransform& b);

// One change as a command (docs/architecture.md "One path for a change"): what it touched,
// and each touched part's value before and after. Undo applies `before` over the current
// state, redo `after`, each refused when a later step touched the same part.
struct Step {
  pb::HistoryStep info;
  bool constraints = false;  // cs_key, given and every transform changed
  bool beta = false;
  std::vector<int> handles;  // transforms changed (all of them when `constraints`)
  bool timeline = false;     // the timeline changed
  std::string snapshot;      // the named snapshot it saved or deleted ("" : none)
  EditState before, after;   // only the changed parts are meaningful

  // It changes the deformed pose (a new session version), not only the timeline/snapshots.
  bool changes_pose() const { return constraints || beta || !handles.empty(); }
};

// `side` (a step's before or after) laid over `state` for what `step` touched.
void apply_side(EditState& state, const Step& step, const EditState& side);

class History {
 public:
  struct Limits {
    std::size_t max_steps = 1000;
    std::size_t max_bytes = 64u << 20;  // of constraints, timelines and snapshots kept
  };
  explicit History(Limits limits) : limits_(limits) {}

  // Appends `step` (its id, version and time set by the caller), dropping the oldest beyond
  // the limits. A new change (not UNDO / REDO) clears its author's redo list.
  // A continuous gesture is one step: a β-only step that follows the same client's β-only
  // step within kGestureMs, with no other step between and that one not undone, extends it
  // (its `before` stays, `after`, version and time are the new step's; the same id), so a
  // β slider drag is undone in one Undo. Returns the recorded (or extended) step.
  const pb::HistoryStep& record(Step step);
  static constexpr std::int64_t kGestureMs = 1000;

  // Drags: the first frame of a client's drag remembers the moved handles' transforms before
  // it; the frame that ends it (or a release) closes one MOVE step. Returns the handles and
  // their before-values (empty when no drag was open).
  void drag_moved(const std::string& client_id, const std::vector<int>& handles,
                  const std::vector<HandleTransform>& before);
  std::map<int, HandleTransform> end_drag(const std::string& client_id);
  void forget_drags();  // the constraints changed: open drags refer to other handles

  // The step Undo reverts: `step` if non-zero, else `client_id`'s latest change not undone.
  // Throws ServiceError (NOT_FOUND / FAILED_PRECONDITION) naming what is missing.
  const Step& undo_target(const std::string& client_id, std::int64_t step) const;
  // The step Redo re-applies: `step` if non-zero (it must be undone), else `client_id`'s
  // latest undone step not redone since (and no new change of its own after it).
  const Step& redo_target(const std::string& client_id, std::int64_t step) const;
  // Forgets every step; `why` (may be empty) is what Undo says when it finds nothing,
  // e.g. that the stored history could not be read after a restart.
  void clear(std::string why = {});
  // ABORTED unless `current` still has `expect`'s values for what `step` changed (nothing
  // later touched them). `what` is "undo" or "redo".
  void check_unchanged(const Step& step, const EditState& current, const EditState& expect,
                       const char* what) const;
  // `target` was reverted by an UNDO of `client_id` (or re-applied by a REDO).
  void mark_undone(std::int64_t target, const std::string& client_id);
  void mark_redone(std::int64_t target, const std::string& client_id);

  // Newest first, `page_size` from before step id `before` (0: the newest).
  std::vector<pb::HistoryStep> page(std::int64_t before, std::size_t page_size) const;
  std::int64_t size() const { return static_cast<std::int64_t>(steps_.size()); }
  std::int64_t next_id() const { return next_id_; }

  // Bumped by every change of the steps (record, undo/redo marks, clear, adopt): the store
  // writes the history again when it differs from what it wrote (history_record.h).
  std::uint64_t revision() const { return revision_; }
  const std::deque<Step>& steps() const { return steps_; }
  const std::map<std::string, std::vector<std::int64_t>>& redo_lists() const { return redo_; }
  // Takes over a stored history (history_record.h), oldest first; the limits apply.
  void adopt(std::deque<Step> steps, std::int64_t next_id,
             std::map<std::string, std::vector<std::int64_t>> redo);

 private:
  const Step* find(std::int64_t id) const;
  Step* find(std::int64_t id);
  // The latest step after `after_id` that changed what `step` changed (for messages).
  const Step* later_change(const Step& step) const;
  void enforce_limits();

  Limits limits_;
  std::uint64_t revision_ = 0;
  std::string why_empty_;  // appended to "nothing to undo" (clear's `why`)
  std::deque<Step> steps_;
  std::size_t bytes_ = 0;
  std::int64_t next_id_ = 1;
  std::map<std::string, std::vector<std::int64_t>> redo_;  // per client: undone targets
  struct OpenDrag {
    std::map<int, HandleTransform> before;
  };
  std::map<std::string, OpenDrag> drags_;
};

}  // namespace hdeform::service

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
// step never pins a ConstraintSet and its factorizations in memory).
struct EditState {
  std::string cs_key;
  std::shared_ptr<const pb::Constraints> given;
  SessionBeta beta;
  std::vector<HandleTransform> transforms;
};

bool same_transform(const HandleTransform& a, const HandleTransform& b);

struct Step {
  pb::HistoryStep info;
  bool constraints = false;  // cs_key, given and every transform changed
  bool beta = false;
  std::vector<int> handles;  // transforms changed (all of them when `constraints`)
  EditState before, after;   // only the changed parts are meaningful
};

class History {
 public:
  struct Limits {
    std::size_t max_steps = 1000;
    std::size_t max_bytes = 64u << 20;  // of constraints kept as given
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
  void clear();  // a restored session starts a new history
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

 private:
  const Step* find(std::int64_t id) const;
  Step* find(std::int64_t id);
  // The latest step after `after_id` that changed what `step` changed (for messages).
  const Step* later_change(const Step& step) const;

  Limits limits_;
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

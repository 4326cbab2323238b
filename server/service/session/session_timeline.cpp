// Session: the timeline (docs/api.md "Timeline and animation"); its export is animation_plan.h.
#include "service/session/session.h"

#include "engine/mesh/format_number.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/session_detail.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace hdeform::service {

pb::Timeline Session::set_timeline(const pb::SetTimelineRequest& request) {
  touch();
  if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
  Change change;
  std::int64_t version = 0;
  {
    std::lock_guard lock(mutex_);
    check_config_version_locked(request.expected_config_version());
    change.target = edit_state_locked();
    change.cs = cs_;
    version = version_;
  }
  auto timeline = std::make_shared<pb::Timeline>(request.timeline());
  if (timeline->keys_size() > 0) {
    if (!change.cs)
      fail(grpc::StatusCode::FAILED_PRECONDITION,
           "SetTimeline: the session has no constraints yet: call SetConstraints first");
    parse_timeline(*timeline, *change.cs);  // throws naming the key and field
  } else if (timeline->easing() != pb::EASING_LINEAR &&
             timeline->easing() != pb::EASING_SMOOTHSTEP) {
    throw InvalidInput("SetTimeline easing: unknown value " +
                       std::to_string(timeline->easing()));
  }
  // Nothing that changes nothing is a step: the same keys and easing answer what is set.
  const pb::Timeline& current = *change.target.timeline;
  if (current.easing() == timeline->easing() &&
      current.keys_size() == timeline->keys_size() &&
      std::equal(current.keys().begin(), current.keys().end(), timeline->keys().begin(),
                 [](const pb::Keyframe& a, const pb::Keyframe& b) {
                   return a.SerializeAsString() == b.SerializeAsString();
                 }))
    return current;
  timeline->set_author(author_of(request.client_id()));
  timeline->set_client_id(request.client_id());
  timeline->set_version(version);
  Step& step = change.step;
  step.info.set_kind(pb::STEP_KIND_TIMELINE);
  step.info.set_client_id(request.client_id());
  step.info.set_summary(timeline->keys_size() == 0
                            ? std::string("cleared the timeline")
                            : "timeline: " + std::to_string(timeline->keys_size()) + " key(s)");
  step.timeline = true;
  change.target.timeline = timeline;
  execute(std::move(change));
  return *timeline;
}

pb::Timeline Session::timeline() const {
  std::lock_guard lock(mutex_);
  return *timeline_;
}

void Session::broadcast_timeline() {
  if (observers_.watchers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_timeline() = timeline();
  observers_.broadcast(std::move(event));
}

pb::Keyframe Session::pose_at(double time_s) const {
  if (!std::isfinite(time_s)) throw InvalidInput("PoseAt time_s: must be finite");
  pb::Timeline timeline;
  std::shared_ptr<const ConstraintSet> cs;
  {
    std::lock_guard lock(mutex_);
    timeline = *timeline_;
    cs = cs_;
  }
  if (timeline.keys_size() == 0 || !cs) detail::no_timeline("PoseAt");
  const ParsedTimeline parsed = parse_timeline(timeline, *cs);
  pb::Keyframe out;
  out.set_time_s(time_s);
  for (const auto& t : parsed.pose_at(time_s)) to_proto(t, out.add_transforms());
  if (const auto beta = parsed.beta_at(time_s)) to_proto(*beta, out.mutable_beta());
  return out;
}

}  // namespace hdeform::service

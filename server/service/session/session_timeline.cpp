// Session: the timeline and its animated GLB export (docs/api.md "Timeline and animation").
#include "service/session/session.h"

#include "engine/mesh/format_number.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace hdeform::service {

namespace {
constexpr double kDefaultFps = 24, kMaxFps = 120;
// Beyond this many samples the count is not even computed (a double that large is no
// size_t); the frame limit refuses far fewer anyway.
constexpr double kMaxSampleSpan = 1e7;

[[noreturn]] void no_timeline(const char* op) {
  fail(grpc::StatusCode::FAILED_PRECONDITION,
       std::string(op) + ": the session has no timeline: call SetTimeline with keys first");
}
}  // namespace

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
  if (observers() == 0) return;
  auto event = std::make_shared<pb::SessionEvent>();
  *event->mutable_timeline() = timeline();
  broadcast(std::move(event));
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
  if (timeline.keys_size() == 0 || !cs) no_timeline("PoseAt");
  const ParsedTimeline parsed = parse_timeline(timeline, *cs);
  pb::Keyframe out;
  out.set_time_s(time_s);
  for (const auto& t : parsed.pose_at(time_s)) to_proto(t, out.add_transforms());
  if (const auto beta = parsed.beta_at(time_s)) to_proto(*beta, out.mutable_beta());
  return out;
}

Session::AnimationPlan Session::animation_plan(const pb::ExportAnimationRequest& request) const {
  const char* op = "ExportAnimation";
  if (closed_) fail(grpc::StatusCode::NOT_FOUND, name_ + " was deleted");
  const double fps = request.fps() == 0 ? kDefaultFps : request.fps();
  if (!std::isfinite(fps) || fps <= 0 || fps > kMaxFps)
    throw InvalidInput(std::string(op) + " fps: " + shortest(request.fps()) +
                       " is not in (0, 120]");
  if (request.up() != pb::UP_AXIS_Y && request.up() != pb::UP_AXIS_Z)
    throw InvalidInput(std::string(op) + " up: unknown up axis " + std::to_string(request.up()));
  AnimationPlan plan;
  pb::Timeline timeline;
  {
    std::lock_guard lock(mutex_);
    timeline = *timeline_;
    plan.cs = cs_;
    plan.beta = beta_;
  }
  if (timeline.keys_size() == 0 || !plan.cs) no_timeline(op);
  plan.timeline = parse_timeline(timeline, *plan.cs);
  double start = plan.timeline.start(), end = plan.timeline.end();
  if (request.start_s() != 0 || request.end_s() != 0) {
    start = request.start_s();
    end = request.end_s();
    if (!std::isfinite(start) || !std::isfinite(end) || start < 0 || end < start)
      throw InvalidInput(std::string(op) + ": start_s " + shortest(start) + " and end_s " +
                         shortest(end) + " must be finite with 0 ≤ start_s ≤ end_s");
  }
  const std::string frames_what = std::string(op) + " frames (" + shortest(fps) +
                                  " fps over " + shortest(end - start) + " s)";
  if ((end - start) * fps > kMaxSampleSpan)
    check_limit(static_cast<std::size_t>(kMaxSampleSpan), limits_.max_animation_frames,
                frames_what, "--max-animation-frames");
  const std::size_t count = sample_count(start, end, fps);
  check_limit(count, limits_.max_animation_frames, frames_what, "--max-animation-frames");
  const FrameLayout& layout = *mesh_->layout;
  check_limit(AnimationGlb::bytes_for(static_cast<std::size_t>(layout.vertex_count()),
                                      static_cast<std::size_t>(layout.triangle_count()), count,
                                      request.energies()),
              limits_.max_animation_bytes, std::string(op) + " GLB bytes",
              "--max-animation-bytes");
  plan.times = sample_times(start, end, fps);
  plan.energies = request.energies();
  plan.glb = std::make_shared<AnimationGlb>(layout.base_triangles(), layout.vertex_count(),
                                            plan.times, plan.energies,
                                            request.up() == pb::UP_AXIS_Z);
  return plan;
}

void Session::animation_frame(AnimationPlan& plan) const {
  const double t = plan.times.at(plan.next);
  SessionBeta beta = plan.beta;
  if (const auto key_beta = plan.timeline.beta_at(t)) {
    beta = SessionBeta();
    beta.uniform = *key_beta;
  }
  const UpdateOptions options{
      .energies = plan.energies, .normals = true, .measures = plan.energies};
  // A full deformation of the interpolated pose: the method's result at every sample.
  const hdeform::Frame f = solve(*plan.cs, plan.timeline.pose_at(t), beta, options);
  const FrameLayout& layout = *mesh_->layout;
  plan.glb->add_frame(layout.to_base(f.positions), layout.to_base(f.normals));
  if (plan.energies) {
    const PreparedMesh& pm = plan.cs->mesh();
    const Eigen::VectorXd e = vertex_energies(pm.mesh().F, pm.n(), f.energies);
    plan.vertex_energies.push_back(layout.to_base(e).col(0).cast<float>());
  }
  ++plan.next;
}

std::string Session::animation_finish(AnimationPlan& plan) const {
  if (plan.energies) {
    // One scale for the whole animation, so colours compare across frames.
    float scale = 0;
    for (const auto& e : plan.vertex_energies) scale = std::max(scale, e.maxCoeff());
    for (std::size_t k = 0; k < plan.vertex_energies.size(); ++k) {
      const Eigen::VectorXf& e = plan.vertex_energies[k];
      Eigen::MatrixXf C(e.size(), 3);
      for (Eigen::Index i = 0; i < e.size(); ++i) C.row(i) = energy_color(e[i], scale);
      plan.glb->set_colors(k, C);
      plan.vertex_energies[k] = Eigen::VectorXf();  // freed as it goes
    }
  }
  return plan.glb->finish();
}

}  // namespace hdeform::service

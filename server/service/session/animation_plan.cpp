#include "service/session/animation_plan.h"

#include "engine/mesh/format_number.h"
#include "service/frames/frame_encoding.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/session_detail.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace hdeform::service {

namespace {
constexpr double kDefaultFps = 24, kMaxFps = 120;
// Beyond this many samples the count is not even computed (a double that large is no
// size_t); the frame limit refuses far fewer anyway.
constexpr double kMaxSampleSpan = 1e7;
}  // namespace

AnimationPlan plan_animation(const SessionPose& pose, const RequestLimits& limits,
                             const pb::ExportAnimationRequest& request) {
  const char* op = "ExportAnimation";
  const double fps = request.fps() == 0 ? kDefaultFps : request.fps();
  if (!std::isfinite(fps) || fps <= 0 || fps > kMaxFps)
    throw InvalidInput(std::string(op) + " fps: " + shortest(request.fps()) +
                       " is not in (0, 120]");
  if (request.up() != pb::UP_AXIS_Y && request.up() != pb::UP_AXIS_Z)
    throw InvalidInput(std::string(op) + " up: unknown up axis " + std::to_string(request.up()));
  AnimationPlan plan;
  const pb::Timeline& timeline = *pose.timeline;
  plan.mesh = pose.mesh;
  plan.cs = pose.cs;
  plan.beta = pose.beta;
  if (timeline.keys_size() == 0 || !plan.cs) detail::no_timeline(op);
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
    check_limit(static_cast<std::size_t>(kMaxSampleSpan), limits.max_animation_frames,
                frames_what, "--max-animation-frames");
  const std::size_t count = sample_count(start, end, fps);
  check_limit(count, limits.max_animation_frames, frames_what, "--max-animation-frames");
  const FrameLayout& layout = *plan.mesh->layout;
  check_limit(AnimationGlb::bytes_for(static_cast<std::size_t>(layout.vertex_count()),
                                      static_cast<std::size_t>(layout.triangle_count()), count,
                                      request.energies()),
              limits.max_animation_bytes, std::string(op) + " GLB bytes",
              "--max-animation-bytes");
  plan.times = sample_times(start, end, fps);
  plan.energies = request.energies();
  plan.glb = std::make_shared<AnimationGlb>(layout.base_triangles(), layout.vertex_count(),
                                            plan.times, plan.energies,
                                            request.up() == pb::UP_AXIS_Z);
  return plan;
}

void animation_frame(AnimationPlan& plan) {
  const double t = plan.times.at(plan.next);
  SessionBeta beta = plan.beta;
  if (const auto key_beta = plan.timeline.beta_at(t)) {
    beta = SessionBeta();
    beta.uniform = *key_beta;
  }
  const UpdateOptions options{
      .energies = plan.energies, .normals = true, .measures = plan.energies};
  // A full deformation of the interpolated pose: the method's result at every sample.
  const hdeform::Frame f = solve_at(*plan.cs, plan.timeline.pose_at(t), beta, options);
  const FrameLayout& layout = *plan.mesh->layout;
  plan.glb->add_frame(layout.to_base(f.positions), layout.to_base(f.normals));
  if (plan.energies) {
    const PreparedMesh& pm = plan.cs->mesh();
    const Eigen::VectorXd e = vertex_energies(pm.mesh().F, pm.n(), f.energies);
    plan.vertex_energies.push_back(layout.to_base(e).col(0).cast<float>());
  }
  ++plan.next;
}

std::string animation_finish(AnimationPlan& plan) {
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

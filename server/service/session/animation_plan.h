// ExportAnimation in steps, like a Sweep (docs/api.md "Timeline and animation"): the plan
// checks the request and its limits and captures the session's pose; each frame() solves the
// next sample (any thread, never the strand); finish() writes the GLB.
#pragma once

#include "engine/io/animation_glb.h"
#include "hdeform/v1/deform.pb.h"
#include "service/infra/request_limits.h"
#include "service/session/session_pose.h"
#include "service/session/timeline.h"

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace hdeform::service {

struct AnimationPlan {
  std::shared_ptr<const MeshRef> mesh;
  std::shared_ptr<const ConstraintSet> cs;
  ParsedTimeline timeline;
  SessionBeta beta;  // the session's, where no key sets β
  std::vector<double> times;
  bool energies = false;
  std::shared_ptr<AnimationGlb> glb;
  std::vector<Eigen::VectorXf> vertex_energies;  // per frame (energies only)
  std::size_t next = 0;
};

// Checks fps, the span, the up axis, --max-animation-frames and --max-animation-bytes.
// FAILED_PRECONDITION when the session has no timeline. Throws InvalidInput or ServiceError.
AnimationPlan plan_animation(const SessionPose& pose, const RequestLimits& limits,
                             const pb::ExportAnimationRequest& request);
void animation_frame(AnimationPlan& plan);
std::string animation_finish(AnimationPlan& plan);

}  // namespace hdeform::service

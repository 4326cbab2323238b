// ExportRig (docs/api.md "Rig export"): Φ as skin weights, the handles as joints, the
// timeline's keys as a skeletal animation, and how far LBS is from the method's solve.
#pragma once

#include "hdeform/v1/deform.pb.h"
#include "service/infra/request_limits.h"
#include "service/session/session_pose.h"

#include <functional>
#include <string>

namespace hdeform::service {

struct RigExport {
  std::string glb;
  pb::RigReport report;
};

// The skinned GLB of `pose` and its report. Solves the current pose and each key once (at
// their β); `keep_going` is called before each solve and may throw to stop. Checks
// influences (4 or 8), the up axis, the joint count and --max-animation-bytes.
RigExport export_rig(const SessionPose& pose, const RequestLimits& limits,
                     const pb::ExportRigRequest& request,
                     const std::function<void()>& keep_going);

}  // namespace hdeform::service

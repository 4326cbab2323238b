// A Sweep in steps (docs/api.md "Sweep"), so it never holds the session's strand: edits go
// on between its βs. Both steps run on any thread.
#pragma once

#include "engine/deform/deformer.h"
#include "hdeform/v1/deform.pb.h"
#include "service/infra/request_limits.h"
#include "service/session/session_pose.h"

#include <memory>
#include <vector>

namespace hdeform::service {

struct SweepPlan {
  std::shared_ptr<const ConstraintSet> cs;
  std::vector<HandleTransform> transforms;
  std::vector<Beta> betas;
  Eigen::VectorXd local_max;  // the session's local entries in the sweep's units; empty: none
};

// Checks the request (betas, --max-sweep-betas, its transforms) against the session's pose
// and captures what the rows solve. Throws InvalidInput or ServiceError.
SweepPlan plan_sweep(const SessionPose& pose, const RequestLimits& limits,
                     const pb::SweepRequest& request);
// Solves one β transiently (no factorization enters the shared cache) into `row`'s measures.
void sweep_row(const SweepPlan& plan, const Beta& beta, pb::SweepRow* row);

}  // namespace hdeform::service

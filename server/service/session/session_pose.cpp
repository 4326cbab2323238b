#include "service/session/session_pose.h"

namespace hdeform::service {

hdeform::Frame solve_at(const ConstraintSet& cs, const std::vector<HandleTransform>& transforms,
                        const SessionBeta& beta, const UpdateOptions& options) {
  if (beta.field) return cs.update_local(transforms, *beta.field, options);
  return cs.update(transforms, beta.uniform, options);
}

}  // namespace hdeform::service

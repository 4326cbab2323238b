// Helpers shared by the files that implement Session (session_*.cpp); not for other users.
#pragma once

#include "engine/deform/deformer.h"

#include <Eigen/Core>

#include <memory>

namespace hdeform::service::detail {

inline constexpr const char* kNoConstraints =
    "the session has no constraints yet: call SetConstraints first";

// The local-β field: per vertex the larger of the regional maximum and the uniform β.
std::shared_ptr<const LocalBeta> make_field(const Eigen::VectorXd& local_max, const Beta& uniform);

}  // namespace hdeform::service::detail

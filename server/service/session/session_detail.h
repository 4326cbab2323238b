// Helpers shared by the files of the session layer (session_*.cpp and the planners); not
// for other users.
#pragma once

#include "engine/deform/deformer.h"
#include "service/infra/service_error.h"

#include <Eigen/Core>

#include <memory>
#include <string>

namespace hdeform::service::detail {

inline constexpr const char* kNoConstraints =
    "the session has no constraints yet: call SetConstraints first";

// The local-β field: per vertex the larger of the regional maximum and the uniform β.
std::shared_ptr<const LocalBeta> make_field(const Eigen::VectorXd& local_max, const Beta& uniform);

[[noreturn]] inline void no_timeline(const char* op) {
  fail(grpc::StatusCode::FAILED_PRECONDITION,
       std::string(op) + ": the session has no timeline: call SetTimeline with keys first");
}

}  // namespace hdeform::service::detail

// One consistent copy of what a session's sweeps and exports read (Session::pose()), taken
// under the session's lock so that they run on any thread, never the strand, while edits go on.
#pragma once

#include "engine/deform/deformer.h"
#include "hdeform/v1/deform.pb.h"
#include "service/session/mesh_library.h"
#include "service/session/session_beta.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

struct SessionPose {
  std::string name;  // "sessions/{id}", for messages
  std::shared_ptr<const MeshRef> mesh;
  std::shared_ptr<const ConstraintSet> cs;  // null: no constraints yet
  SessionBeta beta;
  std::vector<HandleTransform> transforms;
  std::shared_ptr<const pb::Timeline> timeline;  // never null (empty: no keys)
  std::int64_t version = 0;
};

// The deformation at `transforms` (SPEC's solve) with the session's β: the uniform value's
// factorization, or the local field's when β has local entries.
hdeform::Frame solve_at(const ConstraintSet& cs, const std::vector<HandleTransform>& transforms,
                        const SessionBeta& beta, const UpdateOptions& options);

}  // namespace hdeform::service

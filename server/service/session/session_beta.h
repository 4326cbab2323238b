// β as a session holds it (SessionBeta): shared by the session and its history.
#pragma once

#include "engine/deform/deformer.h"
#include "hdeform/v1/deform.pb.h"

#include <google/protobuf/repeated_field.h>

#include <memory>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

// β as a session holds it: the uniform value (the pick, when automatic) and the local
// regularization entries, as given (for Session/Frame/Snapshot) and resolved on the rest
// mesh to a per-triangle field.
struct SessionBeta {
  Beta uniform;
  bool automatic = false;
  google::protobuf::RepeatedPtrField<pb::LocalBeta> local;  // as given
  // Per triangle, the largest local entry covering it (in uniform.units); null: no entries.
  std::shared_ptr<const Eigen::VectorXd> local_max;
  // max(uniform.value, local_max) per triangle; null: no entries (a uniform β).
  std::shared_ptr<const LocalBeta> field;

  bool has_local() const { return local_max != nullptr; }
  bool same_as(const SessionBeta& other) const;
};

// The session's β as a proto (Session, Snapshot; with_local = false for frames: the local
// entries may carry whole .sel files and every frame would repeat them).
void beta_to_proto(const SessionBeta& b, pb::Beta* out, bool with_local = true);

}  // namespace hdeform::service

// Updates that name the handles they move (UpdateHandlesRequest.handles, DeformRequest.handles):
// the other handles keep their transforms, so editors dragging different handles never
// overwrite each other (docs/api.md "Several editors").
#pragma once

#include "hdeform/v1/deform.pb.h"
#include "service/session/convert.h"

#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

// Applies `ts` to `current` (one transform per handle of `cs`): with `handles` empty, `ts`
// replaces every transform (one per handle); otherwise ts[i] replaces handle handles[i].
// Returns the handles moved. InvalidInput naming the problem (count mismatch, an index out
// of range or repeated); `current` is unchanged then.
std::vector<int> apply_handle_update(
    const google::protobuf::RepeatedField<std::int32_t>& handles,
    const google::protobuf::RepeatedPtrField<pb::HandleTransform>& ts, const ConstraintSet& cs,
    std::vector<HandleTransform>& current);

// Deform's latest-wins with partial updates: `newer` replaces `pending`, except that the
// handles only `pending` moved keep their move and a β only `pending` set stays.
void merge_deform_requests(pb::DeformRequest& pending, pb::DeformRequest&& newer);

}  // namespace hdeform::service

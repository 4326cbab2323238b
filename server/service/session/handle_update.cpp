#include "service/session/handle_update.h"

#include <map>
#include <string>

namespace hdeform::service {

std::vector<int> apply_handle_update(
    const google::protobuf::RepeatedField<std::int32_t>& handles,
    const google::protobuf::RepeatedPtrField<pb::HandleTransform>& ts, const ConstraintSet& cs,
    std::vector<HandleTransform>& current) {
  const int n = cs.num_handles();
  std::vector<int> moved;
  if (handles.empty()) {
    current = from_proto(ts, cs);
    for (int j = 0; j < n; ++j) moved.push_back(j);
    return moved;
  }
  if (handles.size() != ts.size())
    throw InvalidInput("handles names " + std::to_string(handles.size()) +
                       " handle(s) but transforms has " + std::to_string(ts.size()) +
                       ": one transform per named handle");
  std::vector<bool> seen(static_cast<std::size_t>(n), false);
  std::vector<HandleTransform> next = current;
  for (int i = 0; i < handles.size(); ++i) {
    const int h = handles.Get(i);
    if (h < 0 || h >= n)
      throw InvalidInput("handles[" + std::to_string(i) + "] = " + std::to_string(h) +
                         " is not a handle (the session has " + std::to_string(n) + ")");
    if (seen[static_cast<std::size_t>(h)])
      throw InvalidInput("handles names handle " + std::to_string(h) + " twice");
    seen[static_cast<std::size_t>(h)] = true;
    try {
      next[static_cast<std::size_t>(h)] = from_proto(ts.Get(i), cs.centroid(h));
    } catch (const InvalidInput& e) {
      throw InvalidInput("handle " + std::to_string(h) + ": " + e.what());
    }
    moved.push_back(h);
  }
  current = std::move(next);
  return moved;
}

void merge_deform_requests(pb::DeformRequest& pending, pb::DeformRequest&& newer) {
  const bool newer_partial = newer.handles_size() > 0;
  const bool pending_moves = pending.transforms_size() > 0;
  const bool consistent = newer.handles_size() == newer.transforms_size() &&
                          (pending.handles_size() == 0 ||
                           pending.handles_size() == pending.transforms_size());
  pb::DeformRequest merged = std::move(newer);
  if (!merged.has_beta() && pending.has_beta()) *merged.mutable_beta() = pending.beta();
  if (merged.client_id().empty()) merged.set_client_id(pending.client_id());
  if (merged.transforms_size() == 0 && pending_moves) {
    // A β-only message keeps the move before it.
    *merged.mutable_transforms() = std::move(*pending.mutable_transforms());
    *merged.mutable_handles() = std::move(*pending.mutable_handles());
  } else if (newer_partial && pending_moves && consistent) {
    if (pending.handles_size() == 0) {
      // Pending moved every handle: overlay the newer moves on its list (indices checked
      // when solved; an out-of-range one leaves the newer message as sent, to be refused).
      bool in_range = true;
      for (int h : merged.handles()) in_range = in_range && h >= 0 && h < pending.transforms_size();
      if (in_range) {
        for (int i = 0; i < merged.handles_size(); ++i)
          *pending.mutable_transforms(merged.handles(i)) = merged.transforms(i);
        *merged.mutable_transforms() = std::move(*pending.mutable_transforms());
        merged.clear_handles();
      }
    } else {
      std::map<int, pb::HandleTransform> by_handle;
      for (int i = 0; i < pending.handles_size(); ++i)
        by_handle[pending.handles(i)] = pending.transforms(i);
      for (int i = 0; i < merged.handles_size(); ++i)
        by_handle[merged.handles(i)] = merged.transforms(i);
      merged.clear_handles();
      merged.clear_transforms();
      for (auto& [h, t] : by_handle) {
        merged.add_handles(h);
        *merged.add_transforms() = std::move(t);
      }
    }
  }
  pending = std::move(merged);
}

}  // namespace hdeform::service

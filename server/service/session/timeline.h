// A session's timeline as the engine takes it (docs/api.md "Timeline and animation"): the
// proto's keys checked against the session's constraint set, and β per key.
#pragma once

#include "engine/deform/deformer.h"
#include "engine/deform/keyframes.h"
#include "hdeform/v1/deform.pb.h"

#include <cstddef>
#include <optional>
#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

// Distinct β values in one timeline: each is its own factorization of K_FF.
inline constexpr std::size_t kMaxTimelineBetas = 4;

struct ParsedTimeline {
  std::vector<Keyframe> keys;
  std::vector<std::optional<Beta>> betas;  // per key: β from that key on, if it sets one
  Easing easing = Easing::linear;
  std::vector<Eigen::Vector3d> rest_pivots;  // each handle's rest centroid

  bool empty() const { return keys.empty(); }
  double start() const { return keys.front().time; }
  double end() const { return keys.back().time; }
  // β at time t: that of the last key at or before t that sets one; nullopt when there is
  // none (the session's β applies).
  std::optional<Beta> beta_at(double t) const;
  std::vector<HandleTransform> pose_at(double t) const {
    return hdeform::pose_at(keys, t, easing, rest_pivots);
  }
};

// Throws InvalidInput naming the field ("SetTimeline keys[1].beta: ...") for bad times,
// transforms (count, validity), a β that is local, automatic or out of range, more than
// kMaxTimelineBetas distinct β values, or an unknown easing.
ParsedTimeline parse_timeline(const pb::Timeline& timeline, const ConstraintSet& cs);

}  // namespace hdeform::service

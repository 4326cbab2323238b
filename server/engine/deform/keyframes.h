// Keyframed handle transforms (docs/api.md "Timeline and animation"): the pose of every
// handle at a time, interpolated between keys. Each pose is then deformed by the method
// (ConstraintSet::update): an animation's in-between frames are deformations, never an
// interpolation of positions.
#pragma once

#include "engine/mesh/transform.h"

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <span>
#include <vector>

namespace hdeform {

enum class Easing {
  linear,      // u = (t − t₀) / (t₁ − t₀)
  smoothstep,  // u² (3 − 2u): zero velocity at every key
};

struct Keyframe {
  double time = 0;                          // seconds
  std::vector<HandleTransform> transforms;  // one per handle
  // The easing from this key to the next; unset: the timeline's (pose_at's `easing`).
  std::optional<Easing> easing = std::nullopt;
};

// Limits of a timeline (each breach is an InvalidInput naming it).
inline constexpr std::size_t kMaxKeyframes = 256;

// Throws InvalidInput naming the key ("keys[2]: ...") unless: at most kMaxKeyframes keys,
// times finite, ≥ 0 and strictly increasing, `handles` transforms per key, each valid.
void check_keyframes(std::span<const Keyframe> keys, int handles);

// Every handle's transform at time t. Between keys a and b, with u eased (a.easing, else
// `easing`): rotation
// slerp(R_a, R_b, u) (shortest arc), S, t and the pivot p linear in u (an unset pivot is
// `rest_pivots[j]`, the handle's rest centroid); the result's pivot is always set. Before the
// first key the first holds, after the last the last; at a key's time, that key exactly.
// Preconditions: check_keyframes passed, keys not empty, rest_pivots has one per handle.
std::vector<HandleTransform> pose_at(std::span<const Keyframe> keys, double t, Easing easing,
                                     std::span<const Eigen::Vector3d> rest_pivots);

// The sample times of [start, end] at `fps`: start, start + 1/fps, … and end itself (the last
// sample is end exactly; a grid point within 1e-9 s of end is replaced by it). Precondition:
// finite start ≤ end, fps > 0.
std::vector<double> sample_times(double start, double end, double fps);
// Their number, without building them (limits are checked before anything is allocated).
std::size_t sample_count(double start, double end, double fps);

}  // namespace hdeform

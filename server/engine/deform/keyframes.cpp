#include "engine/deform/keyframes.h"

#include "engine/mesh/format_number.h"
#include "engine/mesh/mesh.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace hdeform {

void check_keyframes(std::span<const Keyframe> keys, int handles) {
  if (keys.size() > kMaxKeyframes)
    throw InvalidInput("timeline: " + std::to_string(keys.size()) +
                       " keys exceed the limit of " + std::to_string(kMaxKeyframes));
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const std::string where = "keys[" + std::to_string(i) + "]";
    const Keyframe& k = keys[i];
    if (!std::isfinite(k.time) || k.time < 0)
      throw InvalidInput(where + ": time " + shortest(k.time) + " s must be finite and ≥ 0");
    if (i > 0 && !(k.time > keys[i - 1].time))
      throw InvalidInput(where + ": time " + shortest(k.time) +
                         " s must be after the previous key's " + shortest(keys[i - 1].time) +
                         " s");
    if (static_cast<int>(k.transforms.size()) != handles)
      throw InvalidInput(where + ": " + std::to_string(k.transforms.size()) +
                         " transforms for " + std::to_string(handles) + " handles");
    for (std::size_t j = 0; j < k.transforms.size(); ++j) {
      try {
        k.transforms[j].validate();
      } catch (const InvalidInput& e) {
        throw InvalidInput(where + ".transforms[" + std::to_string(j) + "]: " + e.what());
      }
    }
  }
}

namespace {

HandleTransform with_pivot(const HandleTransform& h, const Eigen::Vector3d& rest_pivot) {
  HandleTransform out = h;
  if (!out.pivot) out.pivot = rest_pivot;
  return out;
}

HandleTransform blend(const HandleTransform& a, const HandleTransform& b, double u) {
  HandleTransform out;
  out.pivot = (1 - u) * *a.pivot + u * *b.pivot;
  out.rotation = a.rotation.slerp(u, b.rotation).normalized();
  // A convex combination of symmetric positive definite matrices is one too.
  out.stretch = (1 - u) * a.stretch + u * b.stretch;
  out.translation = (1 - u) * a.translation + u * b.translation;
  return out;
}

}  // namespace

std::vector<HandleTransform> pose_at(std::span<const Keyframe> keys, double t, Easing easing,
                                     std::span<const Eigen::Vector3d> rest_pivots) {
  const std::size_t handles = rest_pivots.size();
  std::vector<HandleTransform> out(handles);
  // The first key with time > t: the segment is [next − 1, next].
  const auto it = std::upper_bound(keys.begin(), keys.end(), t,
                                   [](double v, const Keyframe& k) { return v < k.time; });
  const std::size_t next = static_cast<std::size_t>(it - keys.begin());
  if (next == 0 || next == keys.size() || keys[next - 1].time == t) {
    const Keyframe& k = next == 0 ? keys.front() : keys[next - 1];
    for (std::size_t j = 0; j < handles; ++j) out[j] = with_pivot(k.transforms[j], rest_pivots[j]);
    return out;
  }
  const Keyframe& a = keys[next - 1];
  const Keyframe& b = keys[next];
  double u = (t - a.time) / (b.time - a.time);
  if (a.easing.value_or(easing) == Easing::smoothstep) u = u * u * (3 - 2 * u);
  for (std::size_t j = 0; j < handles; ++j)
    out[j] = blend(with_pivot(a.transforms[j], rest_pivots[j]),
                   with_pivot(b.transforms[j], rest_pivots[j]), u);
  return out;
}

std::size_t sample_count(double start, double end, double fps) {
  const double steps = std::floor((end - start) * fps + 1e-9 * fps);
  const std::size_t on_grid = static_cast<std::size_t>(std::max(0.0, steps)) + 1;
  const double last = start + static_cast<double>(on_grid - 1) / fps;
  return std::abs(end - last) > 1e-9 ? on_grid + 1 : on_grid;
}

std::vector<double> sample_times(double start, double end, double fps) {
  const std::size_t n = sample_count(start, end, fps);
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = start + static_cast<double>(i) / fps;
  t.back() = end;
  return t;
}

}  // namespace hdeform

// A handle transform (SPEC.md §Constraints): x' = p + R S (x − p) + t.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Geometry>

#include <optional>

namespace hdeform {

struct HandleTransform {
  // Pivot p in model units; empty means the centroid of the handle region at rest.
  std::optional<Eigen::Vector3d> pivot;
  // R, a unit quaternion. Flipped to w ≥ 0 where the quaternion field needs it.
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  // S, symmetric positive definite (uniform scale s: s·I; per axis: diag).
  Eigen::Matrix3d stretch = Eigen::Matrix3d::Identity();
  // t in model units.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Matrix3d linear() const { return rotation.toRotationMatrix() * stretch; }

  // Target of a rest position given the resolved pivot.
  Eigen::Vector3d apply(const Eigen::Vector3d& x, const Eigen::Vector3d& p) const {
    return p + linear() * (x - p) + translation;
  }

  // From a 4×4 homogeneous matrix T (targets = T·x): polar decomposition of its linear
  // part, translation re-expressed about `pivot`. Throws InvalidInput if the linear part
  // is singular or reflecting (det ≤ 0), non-finite, or the last row is not (0 0 0 1).
  static HandleTransform from_matrix(const Eigen::Matrix4d& T, const Eigen::Vector3d& pivot);

  // Throws InvalidInput naming the problem: non-finite numbers, a non-unit quaternion,
  // a stretch that is not symmetric positive definite.
  void validate() const;
};

}  // namespace hdeform

// A rig of the deformation for engines without hdeform: linear blend skinning (LBS) weights
// from the harmonic basis Φ (harmonic.h) and the LBS surface of a pose.
//
// Joint 0 is the fixed region (the rig's root), joint j + 1 is handle j. Φ_j is 1 on H_j and
// 0 on the other constrained vertices; the field that is 1 on the fixed region is 1 − Σ_j Φ_j
// (the harmonic solution is linear in its boundary values, and these boundary values sum to 1
// on every constrained vertex), so w = (1 − Σ_j Φ_j, Φ_0, …, Φ_{k−1}) is a partition of unity,
// non-negative by the maximum principle. LBS of the handle transforms is not the harmonic
// deformation (which solves for the surface whose gradients follow the rotated field): the
// distance between the two is what skin_error reports.
#pragma once

#include "engine/mesh/mesh.h"
#include "engine/mesh/transform.h"

#include <Eigen/Core>

#include <cstdint>
#include <span>
#include <vector>

namespace hdeform {

// The `influences` (4 or 8) largest weights per vertex, renormalized to sum 1 and quantized as
// glTF's normalized unsigned short WEIGHTS (value q / 65535): the q of a vertex sum to exactly
// 65535 (largest remainders), so the weights sum to 1 and a vertex with a single influence
// (every vertex of a handle or of the fixed region) has weight exactly 1. Unused slots have
// joint 0 and weight 0. Ties go to the lower joint.
struct SkinWeights {
  int influences = 4;
  int joints = 1;                      // 1 + handles
  std::vector<std::uint8_t> joint;     // vertex v's slot s: joint[v * influences + s]
  std::vector<std::uint16_t> weight;   // the same layout
  Eigen::Index vertices() const { return static_cast<Eigen::Index>(joint.size()) / influences; }
  double w(Eigen::Index v, int slot) const {
    return weight[static_cast<std::size_t>(v * influences + slot)] / 65535.0;
  }
};

// Limits of a rig: glTF JOINTS as unsigned byte.
inline constexpr int kMaxRigJoints = 256;

// From Φ (n × k, rows in the order the weights are wanted; entries outside [0, 1] by rounding
// are clamped). Throws std::invalid_argument unless influences is 4 or 8 and 1 + k ≤ 256.
SkinWeights skin_weights(const Eigen::MatrixXd& phi, int influences);

// A joint's motion as glTF TRS about its bind position b (the handle's rest pivot): the
// joint's matrix T(translation) · R(rotation) · diag(scale), times the inverse bind matrix
// T(−b), is the handle's x ↦ p + R S (x − p) + t. Only an axis-aligned stretch S (diagonal)
// has such a form: `axis_aligned` is false otherwise (scale is then S's diagonal).
struct JointPose {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  bool axis_aligned = true;
};
// `pivot`: the transform's resolved pivot p; `bind`: the joint's bind position b. Off-diagonal
// entries of S up to kAxisAlignedTolerance × its largest diagonal entry count as axis-aligned
// and are dropped (a 4×4 matrix given to 6 digits, like the benchmark's .def files, leaves
// ~1e-6 after its polar decomposition); what that costs shows in the LBS error of the pose.
inline constexpr double kAxisAlignedTolerance = 1e-3;
JointPose joint_pose(const HandleTransform& t, const Eigen::Vector3d& pivot,
                     const Eigen::Vector3d& bind);
// The handle transform a joint's TRS stands for (pivot b): what engines play.
HandleTransform as_transform(const JointPose& pose, const Eigen::Vector3d& bind);

// The LBS surface: x'_v = Σ_s w_vs A_{joint vs} x_v, with A_0 the identity (the fixed root)
// and A_{j+1} handle j's affine map x ↦ p_j + R_j S_j (x − p_j) + t_j. `V`: the rest positions
// in the weights' row order; `pivots`: each transform's resolved pivot.
Vertices skin_positions(const Vertices& V, const SkinWeights& w,
                        std::span<const HandleTransform> transforms,
                        std::span<const Eigen::Vector3d> pivots);

// Distance of the LBS surface to the exact one, per vertex, as max and root mean square.
struct SkinError {
  double max = 0;
  double rms = 0;
};
SkinError skin_error(const Vertices& lbs, const Vertices& exact);

}  // namespace hdeform

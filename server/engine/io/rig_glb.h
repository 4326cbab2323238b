// A skinned GLB (glTF 2.0 `skin`): the rest mesh, one joint per handle under a root joint for
// the fixed region, per-vertex JOINTS_0/WEIGHTS_0 (and _1 for 8 influences), and optionally
// one animation of the handle joints' TRS at key times. Joint j + 1 (handle j) binds at its
// rest pivot b_j: inverseBindMatrices T(−b_j), the root's identity. The buffers keep model
// coordinates; a z-up model's skeleton hangs under a node turning z-up to glTF's y-up (the
// skinned mesh node itself stays a scene root: glTF ignores a skinned mesh node's parents).
// docs/api.md "Rig export"; checked with the Khronos validator and three.js in tests/browser.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace hdeform {

// A joint's local translation, rotation (unit) and scale: matrix T · R · diag(s).
struct JointTrs {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
};

struct RigGlbInput {
  Vertices V;   // rest positions (n × 3, model units): the bind pose
  Vertices N;   // rest unit normals (n × 3)
  Triangles F;
  int influences = 4;                     // 4 or 8: JOINTS_0/WEIGHTS_0 (and _1)
  std::span<const std::uint8_t> joints;   // n × influences, joint 0 the root
  std::span<const std::uint16_t> weights; // n × influences, normalized unsigned short
  std::vector<Eigen::Vector3d> bind;      // per handle: b_j, the joint's rest position
  std::vector<JointTrs> pose;             // per handle: the joints' node TRS (a still pose)
  std::vector<double> key_times;          // seconds, increasing; empty: no animation
  std::vector<std::vector<JointTrs>> keys;  // per key time: per handle
  bool up_z = false;
};

// The GLB's size in bytes (limits are checked with it before anything is built); the JSON
// overhead is bounded by a constant per joint and per key.
std::size_t rig_glb_bytes(std::size_t vertices, std::size_t triangles, int influences,
                          std::size_t handles, std::size_t keys);

// Throws std::invalid_argument on inconsistent sizes, std::runtime_error beyond 4 GiB.
std::string rig_glb(const RigGlbInput& in);

}  // namespace hdeform

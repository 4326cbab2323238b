// See skin_weights.h.

#include "engine/deform/skin_weights.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace hdeform {

SkinWeights skin_weights(const Eigen::MatrixXd& phi, int influences) {
  if (influences != 4 && influences != 8)
    throw std::invalid_argument("skin weights: influences must be 4 or 8, not " +
                                std::to_string(influences));
  const int joints = 1 + static_cast<int>(phi.cols());
  if (joints > kMaxRigJoints)
    throw std::invalid_argument("skin weights: " + std::to_string(joints) +
                                " joints, glTF's unsigned byte JOINTS hold at most 256");
  const Eigen::Index n = phi.rows();
  const int slots = std::min(influences, joints);
  SkinWeights out;
  out.influences = influences;
  out.joints = joints;
  out.joint.assign(static_cast<std::size_t>(n * influences), 0);
  out.weight.assign(static_cast<std::size_t>(n * influences), 0);
  std::vector<double> w(static_cast<std::size_t>(joints));
  std::vector<int> order(static_cast<std::size_t>(joints));
  std::vector<double> share(static_cast<std::size_t>(slots));
  std::vector<int> by_remainder(static_cast<std::size_t>(slots));
  for (Eigen::Index v = 0; v < n; ++v) {
    double handles = 0;
    for (int j = 1; j < joints; ++j) {
      w[j] = std::clamp(phi(v, j - 1), 0.0, 1.0);
      handles += w[j];
    }
    w[0] = std::max(0.0, 1.0 - handles);
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + slots, order.end(),
                      [&](int a, int b) { return w[a] > w[b] || (w[a] == w[b] && a < b); });
    double kept = 0;
    for (int s = 0; s < slots; ++s) kept += w[order[s]];
    if (!(kept > 0)) {  // Φ all zero and Σ ≥ 1 cannot both hold; guard NaN input anyway
      order[0] = 0;
      w[0] = kept = 1;
    }
    // Largest remainders: floor every share of 65535, give the units left to the largest
    // fractional parts, so the quantized weights sum to 65535 exactly.
    int given = 0;
    for (int s = 0; s < slots; ++s) {
      share[s] = w[order[s]] / kept * 65535.0;
      given += static_cast<int>(std::floor(share[s]));
    }
    std::iota(by_remainder.begin(), by_remainder.end(), 0);
    std::sort(by_remainder.begin(), by_remainder.end(), [&](int a, int b) {
      const double ra = share[a] - std::floor(share[a]), rb = share[b] - std::floor(share[b]);
      return ra > rb || (ra == rb && a < b);
    });
    const std::size_t base = static_cast<std::size_t>(v * influences);
    for (int s = 0; s < slots; ++s)
      out.weight[base + s] = static_cast<std::uint16_t>(std::floor(share[s]));
    for (int r = 0; r < 65535 - given; ++r) ++out.weight[base + by_remainder[r % slots]];
    for (int s = 0; s < slots; ++s)
      out.joint[base + s] = out.weight[base + s] > 0 ? static_cast<std::uint8_t>(order[s]) : 0;
  }
  return out;
}

JointPose joint_pose(const HandleTransform& t, const Eigen::Vector3d& pivot,
                     const Eigen::Vector3d& bind) {
  JointPose out;
  const Eigen::Matrix3d& S = t.stretch;
  const double off = std::max({std::abs(S(0, 1)), std::abs(S(0, 2)), std::abs(S(1, 2)),
                               std::abs(S(1, 0)), std::abs(S(2, 0)), std::abs(S(2, 1))});
  out.axis_aligned = off <= kAxisAlignedTolerance * S.diagonal().cwiseAbs().maxCoeff();
  out.rotation = t.rotation.normalized();
  out.scale = S.diagonal();
  // T(τ) R S T(−b) x = τ + R S (x − b) must equal p + R S (x − p) + t for every x.
  out.translation = pivot + t.translation + t.linear() * (bind - pivot);
  return out;
}

HandleTransform as_transform(const JointPose& pose, const Eigen::Vector3d& bind) {
  HandleTransform t;
  t.pivot = bind;
  t.rotation = pose.rotation;
  t.stretch = pose.scale.asDiagonal();
  t.translation = pose.translation - bind;
  return t;
}

Vertices skin_positions(const Vertices& V, const SkinWeights& w,
                        std::span<const HandleTransform> transforms,
                        std::span<const Eigen::Vector3d> pivots) {
  if (static_cast<int>(transforms.size()) + 1 != w.joints || pivots.size() != transforms.size())
    throw std::invalid_argument("skin positions: one transform and pivot per handle joint");
  if (V.rows() != w.vertices()) throw std::invalid_argument("skin positions: vertex count");
  std::vector<Eigen::Matrix3d> A(static_cast<std::size_t>(w.joints), Eigen::Matrix3d::Identity());
  std::vector<Eigen::Vector3d> b(static_cast<std::size_t>(w.joints), Eigen::Vector3d::Zero());
  for (std::size_t j = 0; j < transforms.size(); ++j) {
    A[j + 1] = transforms[j].linear();
    b[j + 1] = pivots[j] + transforms[j].translation - A[j + 1] * pivots[j];
  }
  Vertices out(V.rows(), 3);
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const Eigen::Vector3d x = V.row(v).transpose();
    Eigen::Vector3d y = Eigen::Vector3d::Zero();
    for (int s = 0; s < w.influences; ++s) {
      const double ws = w.w(v, s);
      if (ws == 0) continue;
      const int j = w.joint[static_cast<std::size_t>(v * w.influences + s)];
      y += ws * (A[j] * x + b[j]);
    }
    out.row(v) = y.transpose();
  }
  return out;
}

SkinError skin_error(const Vertices& lbs, const Vertices& exact) {
  SkinError e;
  if (lbs.rows() == 0) return e;
  const Eigen::VectorXd d = (lbs - exact).rowwise().norm();
  e.max = d.maxCoeff();
  e.rms = std::sqrt(d.squaredNorm() / static_cast<double>(d.size()));
  return e;
}

}  // namespace hdeform

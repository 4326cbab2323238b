// The rig (skin_weights.h, rig_glb.h): LBS weights from the harmonic basis are a partition of
// unity, exact on the constrained regions, reproduce the rest pose and move a rigid handle
// exactly; joint TRS reproduce the handle transform; the skinned GLB reads back with tinygltf.
#include "engine/deform/deformer.h"
#include "engine/deform/skin_weights.h"
#include "engine/io/rig_glb.h"
#include "engine/io/mesh_io.h"
#include "fixtures.h"

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <random>

namespace hdeform {
namespace {

using test::load_benchmark;

// The cactus with its handle split in two by x (two handle joints, so top-k and partition
// of unity are exercised beyond one handle).
struct TwoHandles {
  std::shared_ptr<const PreparedMesh> mesh;
  std::shared_ptr<ConstraintSet> cs;
};

const TwoHandles& cactus_two_handles() {
  static const TwoHandles t = [] {
    const auto b = load_benchmark("cactus");
    Constraints c;
    c.fixed = b.constraints.fixed;
    const auto& V = b.mesh->mesh().V;
    double mid = 0;
    for (int v : b.constraints.handles[0]) mid += V(v, 0);
    mid /= static_cast<double>(b.constraints.handles[0].size());
    c.handles.resize(2);
    for (int v : b.constraints.handles[0]) c.handles[V(v, 0) < mid ? 0 : 1].push_back(v);
    return TwoHandles{b.mesh, std::make_shared<ConstraintSet>(b.mesh, c)};
  }();
  return t;
}

TEST(SkinWeights, APartitionOfUnityExactOnEveryConstrainedRegion) {
  const auto& t = cactus_two_handles();
  for (int influences : {4, 8}) {
    const SkinWeights w = skin_weights(t.cs->harmonic_basis(), influences);
    ASSERT_EQ(w.joints, 3);
    ASSERT_EQ(w.vertices(), t.mesh->n());
    for (Eigen::Index v = 0; v < w.vertices(); ++v) {
      int sum = 0;
      for (int s = 0; s < influences; ++s) {
        const std::size_t i = static_cast<std::size_t>(v * influences + s);
        sum += w.weight[i];
        EXPECT_LT(w.joint[i], w.joints);
        if (w.weight[i] == 0) {
          EXPECT_EQ(w.joint[i], 0);  // unused slots: joint 0
        }
      }
      ASSERT_EQ(sum, 65535) << "vertex " << v;
    }
    auto only = [&](int v, int joint) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(influences);
      EXPECT_EQ(w.joint[i], joint) << "vertex " << v;
      EXPECT_EQ(w.weight[i], 65535) << "vertex " << v;
    };
    for (int v : t.cs->constraints().fixed) only(v, 0);
    for (int h = 0; h < 2; ++h)
      for (int v : t.cs->constraints().handles[static_cast<std::size_t>(h)]) only(v, h + 1);
  }
  // Some free vertex really blends: the weights are not a segmentation.
  const SkinWeights w = skin_weights(t.cs->harmonic_basis(), 4);
  int blended = 0;
  for (Eigen::Index v = 0; v < w.vertices(); ++v) blended += w.weight[static_cast<std::size_t>(4 * v)] < 60000;
  EXPECT_GT(blended, 100);
}

TEST(SkinWeights, TheTopWeightsAreTheLargestFieldsRenormalized) {
  // Six joints, four kept: the two smallest go and the rest is scaled to sum 1. Values exact
  // in binary, so the ties are ties: they go to the lower joint.
  Eigen::MatrixXd phi(1, 5);
  phi << 0.25, 0.125, 0.25, 0.0625, 0.125;  // root: 1 − 0.8125 = 0.1875
  const SkinWeights w = skin_weights(phi, 4);
  const double kept = 0.25 + 0.25 + 0.1875 + 0.125;
  const int joints[4] = {1, 3, 0, 2};
  const double expect[4] = {0.25 / kept, 0.25 / kept, 0.1875 / kept, 0.125 / kept};
  for (int s = 0; s < 4; ++s) {
    EXPECT_EQ(w.joint[s], joints[s]) << s;
    EXPECT_NEAR(w.w(0, s), expect[s], 1.0 / 65535) << s;
  }
  EXPECT_THROW(skin_weights(phi, 5), std::invalid_argument);
  EXPECT_THROW(skin_weights(Eigen::MatrixXd::Zero(1, 256), 4), std::invalid_argument);
}

TEST(SkinWeights, RestPoseIsTheInputAndARigidHandleTranslatesExactly) {
  const auto& t = cactus_two_handles();
  const SkinWeights w = skin_weights(t.cs->harmonic_basis(), 4);
  const Vertices& V = t.mesh->mesh().V;
  std::vector<HandleTransform> rest(2);
  std::vector<Eigen::Vector3d> pivots = {t.cs->centroid(0), t.cs->centroid(1)};
  EXPECT_LT((skin_positions(V, w, rest, pivots) - V).cwiseAbs().maxCoeff(), 1e-12);

  std::vector<HandleTransform> moved(2);
  moved[1].translation = Eigen::Vector3d(0.3, -0.2, 0.5);
  const Vertices X = skin_positions(V, w, moved, pivots);
  // Φ = 1 there: x + t to the rounding of one addition.
  for (int v : t.cs->constraints().handles[1])
    EXPECT_LT((X.row(v) - V.row(v) - moved[1].translation.transpose()).norm(), 1e-14) << v;
  for (int v : t.cs->constraints().fixed) EXPECT_EQ(X.row(v), V.row(v)) << v;
  // Everywhere: x' = x + w_h t, with w_h ∈ [0, 1].
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const Eigen::Vector3d d = (X.row(v) - V.row(v)).transpose();
    const double s = d.dot(moved[1].translation) / moved[1].translation.squaredNorm();
    EXPECT_GE(s, -1e-12);
    EXPECT_LE(s, 1 + 1e-12);
    EXPECT_LT((d - s * moved[1].translation).norm(), 1e-12);
  }
}

TEST(SkinWeights, JointTrsAboutTheBindPositionIsTheHandleTransform) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 20; ++trial) {
    HandleTransform h;
    h.rotation = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    h.stretch = Eigen::Vector3d(1.5 + u(rng), 1.2 + u(rng) * 0.5, 0.8).asDiagonal();
    h.translation = Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Vector3d p(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng));
    const JointPose j = joint_pose(h, p, b);
    ASSERT_TRUE(j.axis_aligned);
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector3d x(u(rng), u(rng), u(rng));
      const Eigen::Vector3d y =
          j.translation + j.rotation.toRotationMatrix() * j.scale.asDiagonal() * (x - b);
      EXPECT_LT((y - h.apply(x, p)).norm(), 1e-12);
    }
  }
  HandleTransform shear;
  shear.stretch(0, 1) = shear.stretch(1, 0) = 0.2;
  EXPECT_FALSE(joint_pose(shear, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()).axis_aligned);
}

TEST(RigGlb, ReadsBackAsASkinWithItsJointsWeightsAndAnimation) {
  const auto& t = cactus_two_handles();
  const SkinWeights w = skin_weights(t.cs->harmonic_basis(), 8);
  RigGlbInput in;
  in.V = t.mesh->mesh().V;
  in.N = vertex_normals(in.V, t.mesh->mesh().F);
  in.F = t.mesh->mesh().F;
  in.influences = 8;
  in.joints = w.joint;
  in.weights = w.weight;
  in.bind = {t.cs->centroid(0), t.cs->centroid(1)};
  in.pose.resize(2);
  in.key_times = {0.0, 1.5};
  JointTrs moved;
  moved.translation = Eigen::Vector3d(1, 2, 3);
  in.keys = {{JointTrs{}, JointTrs{}}, {moved, moved}};
  in.up_z = true;
  const std::string glb = rig_glb(in);
  EXPECT_LE(glb.size(), rig_glb_bytes(static_cast<std::size_t>(in.V.rows()),
                                      static_cast<std::size_t>(in.F.rows()), 8, 2, 2));

  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromMemory(&model, &err, &warn,
                                          reinterpret_cast<const unsigned char*>(glb.data()),
                                          static_cast<unsigned>(glb.size())))
      << err;
  ASSERT_EQ(model.skins.size(), 1u);
  EXPECT_EQ(model.skins[0].joints, (std::vector<int>{1, 2, 3}));
  const auto& prim = model.meshes.at(0).primitives.at(0);
  for (const char* a : {"POSITION", "NORMAL", "JOINTS_0", "WEIGHTS_0", "JOINTS_1", "WEIGHTS_1"})
    EXPECT_EQ(prim.attributes.count(a), 1u) << a;
  // Joint and weight bytes as given, slot s of set k at 4k + s.
  const auto& wa = model.accessors.at(static_cast<std::size_t>(prim.attributes.at("WEIGHTS_1")));
  EXPECT_TRUE(wa.normalized);
  const auto& view = model.bufferViews.at(static_cast<std::size_t>(wa.bufferView));
  const auto* q = reinterpret_cast<const std::uint16_t*>(
      model.buffers[0].data.data() + view.byteOffset + wa.byteOffset);
  for (Eigen::Index v = 0; v < in.V.rows(); v += 97)
    for (int s = 0; s < 4; ++s) EXPECT_EQ(q[4 * v + s], w.weight[static_cast<std::size_t>(8 * v + 4 + s)]);
  ASSERT_EQ(model.animations.size(), 1u);
  EXPECT_EQ(model.animations[0].channels.size(), 6u);  // T, R, S per handle joint
  // The skinned mesh node is a scene root; the skeleton hangs under the z-up rotation.
  const auto& roots = model.scenes.at(0).nodes;
  EXPECT_EQ(roots.at(0), 0);
  EXPECT_EQ(model.nodes.at(static_cast<std::size_t>(roots.at(1))).children, std::vector<int>{1});
}

}  // namespace
}  // namespace hdeform

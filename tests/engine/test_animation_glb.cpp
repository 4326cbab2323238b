// The animated GLB (animation_glb.h), read back with tinygltf: the base is frame 0, base +
// target k − 1 is frame k (to float32), the weights are one-hot at the sample times, every
// POSITION accessor has its bounds, and the size stays within bytes_for(). The Khronos
// validator and three.js playback are checked in tests/browser (they need node).
#include "engine/io/animation_glb.h"
#include "engine/io/mesh_io.h"

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>

namespace hdeform {
namespace {

struct Sequence {
  Triangles F;
  std::vector<Vertices> V, N;
  std::vector<Eigen::MatrixXf> C;
};

// A strip of 2×k quads bending a little more in every frame.
Sequence bending_strip(int frames) {
  const int k = 6;
  Vertices rest(2 * (k + 1), 3);
  for (int i = 0; i <= k; ++i) {
    rest.row(2 * i) << i, 0, 0;
    rest.row(2 * i + 1) << i, 1, 0;
  }
  Sequence s;
  s.F.resize(2 * k, 3);
  for (int i = 0; i < k; ++i) {
    s.F.row(2 * i) << 2 * i, 2 * i + 2, 2 * i + 1;
    s.F.row(2 * i + 1) << 2 * i + 1, 2 * i + 2, 2 * i + 3;
  }
  for (int f = 0; f < frames; ++f) {
    Vertices V = rest;
    for (Eigen::Index r = 0; r < V.rows(); ++r) V(r, 2) = 0.1 * f * V(r, 0) * V(r, 0) + 1e3;
    s.N.push_back(vertex_normals(V, s.F));
    s.V.push_back(V);
    Eigen::MatrixXf C(V.rows(), 3);
    for (Eigen::Index r = 0; r < V.rows(); ++r)
      C.row(r) = energy_color(static_cast<double>(f) * static_cast<double>(r), 40.0);
    s.C.push_back(C);
  }
  return s;
}

const float* floats(const tinygltf::Model& m, int accessor) {
  const auto& a = m.accessors[static_cast<std::size_t>(accessor)];
  const auto& v = m.bufferViews[static_cast<std::size_t>(a.bufferView)];
  return reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
}

tinygltf::Model load(const std::string& glb) {
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  EXPECT_TRUE(loader.LoadBinaryFromMemory(&model, &err, &warn,
                                          reinterpret_cast<const unsigned char*>(glb.data()),
                                          static_cast<unsigned int>(glb.size())))
      << err;
  return model;
}

TEST(AnimationGlb, TargetsReproduceEveryFrameAndWeightsAreOneHot) {
  const int K = 4;
  const auto s = bending_strip(K);
  const std::vector<double> times = {0, 0.25, 0.5, 0.6};
  AnimationGlb glb(s.F, s.V[0].rows(), times, true, false);
  for (int f = 0; f < K; ++f) glb.add_frame(s.V[f], s.N[f]);
  EXPECT_THROW(glb.finish(), std::logic_error);  // colours missing
  EXPECT_THROW(glb.set_colors(1, s.C[1]), std::logic_error);  // out of order
  for (int f = 0; f < K; ++f) glb.set_colors(static_cast<std::size_t>(f), s.C[f]);
  const std::string bytes = glb.finish();
  EXPECT_LE(bytes.size(), AnimationGlb::bytes_for(14, 12, K, true));
  const auto model = load(bytes);
  ASSERT_EQ(model.meshes.size(), 1u);
  const auto& prim = model.meshes[0].primitives[0];
  ASSERT_EQ(prim.targets.size(), static_cast<std::size_t>(K - 1));
  EXPECT_EQ(model.meshes[0].weights, std::vector<double>(K - 1, 0.0));
  const float* base = floats(model, prim.attributes.at("POSITION"));
  const float* cbase = floats(model, prim.attributes.at("COLOR_0"));
  const auto n = s.V[0].rows();
  for (int f = 0; f < K; ++f) {
    const float* d = f == 0 ? nullptr : floats(model, prim.targets[f - 1].at("POSITION"));
    const float* cd = f == 0 ? nullptr : floats(model, prim.targets[f - 1].at("COLOR_0"));
    double worst = 0, worst_c = 0;
    for (Eigen::Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        const double p = double{base[3 * i + c]} + (d ? double{d[3 * i + c]} : 0.0);
        worst = std::max(worst, std::abs(p - s.V[f](i, c)));
        const double col = double{cbase[3 * i + c]} + (cd ? double{cd[3 * i + c]} : 0.0);
        worst_c = std::max(worst_c, std::abs(col - double{s.C[f](i, c)}));
      }
    // Coordinates near 1e3: float32's spacing there is 6e-5; the delta adds its own rounding.
    EXPECT_LT(worst, 1.3e-4) << "frame " << f;
    EXPECT_LT(worst_c, 1e-6) << "frame " << f;
    // Bounds of each POSITION accessor are those of its values.
    const auto& acc = model.accessors[static_cast<std::size_t>(
        f == 0 ? prim.attributes.at("POSITION") : prim.targets[f - 1].at("POSITION"))];
    ASSERT_EQ(acc.minValues.size(), 3u);
    ASSERT_EQ(acc.maxValues.size(), 3u);
    const float* v = f == 0 ? base : d;
    for (int c = 0; c < 3; ++c) {
      float lo = v[c], hi = v[c];
      for (Eigen::Index i = 0; i < n; ++i) {
        lo = std::min(lo, v[3 * i + c]);
        hi = std::max(hi, v[3 * i + c]);
      }
      EXPECT_EQ(acc.minValues[c], lo);
      EXPECT_EQ(acc.maxValues[c], hi);
    }
  }
  ASSERT_EQ(model.animations.size(), 1u);
  const auto& sampler = model.animations[0].samplers[0];
  EXPECT_EQ(sampler.interpolation, "LINEAR");
  EXPECT_EQ(model.animations[0].channels[0].target_path, "weights");
  const float* t = floats(model, sampler.input);
  const float* w = floats(model, sampler.output);
  for (int k = 0; k < K; ++k) {
    EXPECT_EQ(t[k], static_cast<float>(times[static_cast<std::size_t>(k)]));
    for (int j = 0; j < K - 1; ++j) EXPECT_EQ(w[k * (K - 1) + j], k >= 1 && j == k - 1 ? 1.f : 0.f);
  }
}

TEST(AnimationGlb, OneSampleIsAStillWithoutAnimation) {
  const auto s = bending_strip(1);
  AnimationGlb glb(s.F, s.V[0].rows(), {0.0}, false, true);
  glb.add_frame(s.V[0], s.N[0]);
  const auto model = load(glb.finish());
  EXPECT_TRUE(model.animations.empty());
  EXPECT_TRUE(model.meshes[0].primitives[0].targets.empty());
  EXPECT_EQ(model.meshes[0].primitives[0].attributes.count("COLOR_0"), 0u);
  ASSERT_EQ(model.nodes.size(), 2u);  // the mesh and the z-up parent
  EXPECT_EQ(model.scenes[0].nodes, std::vector<int>{1});
}

TEST(AnimationGlb, MisuseIsALogicError) {
  const auto s = bending_strip(2);
  AnimationGlb glb(s.F, s.V[0].rows(), {0.0, 1.0}, false, false);
  glb.add_frame(s.V[0], s.N[0]);
  EXPECT_THROW(glb.finish(), std::logic_error);  // a frame missing
  EXPECT_THROW(glb.add_frame(s.V[0].topRows(3), s.N[0]), std::logic_error);
  glb.add_frame(s.V[1], s.N[1]);
  EXPECT_THROW(glb.add_frame(s.V[1], s.N[1]), std::logic_error);  // one too many
}

TEST(AnimationGlb, EnergyRampAndVertexEnergies) {
  EXPECT_EQ(energy_color(0, 1), Eigen::Vector3f(0.0f, 0.1f, 0.9f));
  EXPECT_EQ(energy_color(5, 1), Eigen::Vector3f(0.9f, 0.05f, 0.0f));
  EXPECT_EQ(energy_color(std::nan(""), 1), energy_color(0, 1));
  Triangles F(2, 3);
  F << 0, 1, 2, 1, 3, 2;
  Eigen::VectorXf e(2);
  e << 1, 3;
  const Eigen::VectorXd v = vertex_energies(F, 5, e);
  EXPECT_DOUBLE_EQ(v[0], 1);
  EXPECT_DOUBLE_EQ(v[1], 2);
  EXPECT_DOUBLE_EQ(v[3], 3);
  EXPECT_DOUBLE_EQ(v[4], 0);  // no triangle
}

}  // namespace
}  // namespace hdeform

// See rig_glb.h.

#include "engine/io/rig_glb.h"

#include "engine/io/glb_builder.h"

#include <cstring>
#include <limits>
#include <stdexcept>

namespace hdeform {

namespace {

using json = nlohmann::json;
// JSON bytes, generously: a document's fixed part, and per joint its node, its animation's
// samplers, channels, accessors and views.
constexpr std::size_t kJsonBase = 4096, kJsonPerJoint = 2048;

json trs_json(const JointTrs& p, json node) {
  node["translation"] = {p.translation.x(), p.translation.y(), p.translation.z()};
  const Eigen::Quaterniond q = p.rotation.normalized();
  node["rotation"] = {q.x(), q.y(), q.z(), q.w()};
  node["scale"] = {p.scale.x(), p.scale.y(), p.scale.z()};
  return node;
}

// n rows of 3 doubles as float32 in the BIN chunk; returns the accessor, with min/max.
int vec3_accessor(detail::GlbBuilder& glb, const Vertices& X, int target, bool bounds) {
  const std::size_t n = static_cast<std::size_t>(X.rows());
  const std::size_t at = glb.grow(n * 12);
  auto* f = reinterpret_cast<float*>(glb.data() + at);
  std::vector<double> lo(3, std::numeric_limits<double>::infinity()), hi(3, -lo[0]);
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      f[3 * i + c] = static_cast<float>(X(static_cast<Eigen::Index>(i), c));
      lo[c] = std::min(lo[c], static_cast<double>(f[3 * i + c]));
      hi[c] = std::max(hi[c], static_cast<double>(f[3 * i + c]));
    }
  const bool with = bounds && n > 0;
  return glb.add_accessor(glb.add_view(at, n * 12, target), detail::kComponentFloat, n, "VEC3",
                          with ? json(lo) : json(nullptr), with ? json(hi) : json(nullptr));
}

}  // namespace

std::size_t rig_glb_bytes(std::size_t vertices, std::size_t triangles, int influences,
                          std::size_t handles, std::size_t keys) {
  // Per vertex: float32 POSITION and NORMAL, a u8 joint and a u16 weight per influence.
  const std::size_t per_vertex = 24 + static_cast<std::size_t>(influences) * 3;
  // Per key: its time, and per handle T, R, S as float32 (10 numbers).
  const std::size_t per_key = 4 + handles * 40;
  return kJsonBase + vertices * per_vertex + triangles * 12 + (handles + 1) * (64 + kJsonPerJoint) +
         keys * per_key + (8 + 3 * handles) * 4;  // + the views' 4-byte padding
}

std::string rig_glb(const RigGlbInput& in) {
  const std::size_t n = static_cast<std::size_t>(in.V.rows());
  const std::size_t handles = in.bind.size();
  const std::size_t k = in.influences == 8 ? 8 : 4;
  if ((in.influences != 4 && in.influences != 8) || in.N.rows() != in.V.rows() ||
      in.joints.size() != n * k || in.weights.size() != n * k || in.pose.size() != handles ||
      in.keys.size() != in.key_times.size())
    throw std::invalid_argument("rig GLB: inconsistent sizes");
  for (const auto& key : in.keys)
    if (key.size() != handles) throw std::invalid_argument("rig GLB: a key without every handle");

  detail::GlbBuilder glb(detail::GlbBuilder::ZeroOffset::omitted);
  json attributes;
  attributes["POSITION"] = vec3_accessor(glb, in.V, detail::kTargetArrayBuffer, true);
  attributes["NORMAL"] = vec3_accessor(glb, in.N, detail::kTargetArrayBuffer, false);
  for (std::size_t set = 0; set < k / 4; ++set) {
    const std::size_t j_at = glb.grow(n * 4);
    const std::size_t w_at = glb.grow(n * 8);
    auto* j = reinterpret_cast<std::uint8_t*>(glb.data() + j_at);
    auto* w = reinterpret_cast<std::uint16_t*>(glb.data() + w_at);
    for (std::size_t v = 0; v < n; ++v)
      for (std::size_t s = 0; s < 4; ++s) {
        j[4 * v + s] = in.joints[v * k + 4 * set + s];
        w[4 * v + s] = in.weights[v * k + 4 * set + s];
      }
    const char* const names[2][2] = {{"JOINTS_0", "WEIGHTS_0"}, {"JOINTS_1", "WEIGHTS_1"}};
    attributes[names[set][0]] =
        glb.add_accessor(glb.add_view(j_at, n * 4, detail::kTargetArrayBuffer),
                         detail::kComponentUnsignedByte, n, "VEC4");
    const int wa = glb.add_accessor(glb.add_view(w_at, n * 8, detail::kTargetArrayBuffer),
                                    detail::kComponentUnsignedShort, n, "VEC4");
    glb.accessor(wa)["normalized"] = true;
    attributes[names[set][1]] = wa;
  }
  const std::size_t m = static_cast<std::size_t>(in.F.rows());
  const std::size_t index_at = glb.grow(m * 12);
  auto* ind = reinterpret_cast<std::uint32_t*>(glb.data() + index_at);
  for (std::size_t t = 0; t < m; ++t)
    for (int c = 0; c < 3; ++c)
      ind[3 * t + static_cast<std::size_t>(c)] =
          static_cast<std::uint32_t>(in.F(static_cast<Eigen::Index>(t), c));
  json primitive = detail::triangles(
      std::move(attributes),
      glb.add_accessor(glb.add_view(index_at, m * 12, detail::kTargetElementArrayBuffer),
                       detail::kComponentUnsignedInt, 3 * m, "SCALAR"));
  // Node 0: the skinned mesh (a scene root); node 1 the root joint; 2 + j handle j's joint.
  glb.set_mesh(std::move(primitive), false, {{"name", "rig"}}, {{"name", "skinned"}, {"skin", 0}});
  json& nodes = glb.doc()["nodes"];
  json root = {{"name", "fixed"}};
  if (handles > 0) {
    root["children"] = json::array();
    for (std::size_t j = 0; j < handles; ++j) root["children"].push_back(2 + j);
  }
  nodes.push_back(std::move(root));
  for (std::size_t j = 0; j < handles; ++j)
    nodes.push_back(trs_json(in.pose[j], {{"name", "handle " + std::to_string(j)}}));
  int top = 1;
  if (in.up_z) {
    nodes.push_back({{"name", "z-up to y-up"},
                     {"rotation", detail::kZUpToYUp},
                     {"children", json::array({1})}});
    top = static_cast<int>(nodes.size()) - 1;
  }
  glb.doc()["scenes"][0]["nodes"] = json::array({0, top});

  // inverseBindMatrices (column-major): the root's identity, handle j's T(−b_j).
  const std::size_t joints = handles + 1;
  const std::size_t ibm_at = glb.grow(joints * 64);
  auto* ibm = reinterpret_cast<float*>(glb.data() + ibm_at);
  json joint_ids = json::array();
  for (std::size_t j = 0; j < joints; ++j) {
    float* M = ibm + 16 * j;
    for (int d = 0; d < 4; ++d) M[5 * d] = 1.0f;
    if (j > 0)
      for (int c = 0; c < 3; ++c) M[12 + c] = static_cast<float>(-in.bind[j - 1][c]);
    joint_ids.push_back(1 + j);
  }
  const int ibm_accessor = glb.add_accessor(glb.add_view(ibm_at, joints * 64, 0),
                                            detail::kComponentFloat, joints, "MAT4");
  glb.doc()["skins"] = json::array(
      {json{{"name", "handles"}, {"joints", joint_ids}, {"skeleton", 1},
            {"inverseBindMatrices", ibm_accessor}}});

  const std::size_t K = in.key_times.size();
  if (K > 0 && handles > 0) {
    const std::size_t times_at = glb.grow(K * 4);
    auto* tf = reinterpret_cast<float*>(glb.data() + times_at);
    for (std::size_t i = 0; i < K; ++i) tf[i] = static_cast<float>(in.key_times[i]);
    const int input = glb.add_accessor(glb.add_view(times_at, K * 4, 0), detail::kComponentFloat, K,
                                       "SCALAR", json::array({static_cast<double>(tf[0])}),
                                       json::array({static_cast<double>(tf[K - 1])}));
    json samplers = json::array(), channels = json::array();
    for (std::size_t j = 0; j < handles; ++j) {
      // Per path: translation, rotation (kept on one hemisphere key to key, so LINEAR's slerp
      // takes the same arc as the timeline's), scale.
      const char* paths[3] = {"translation", "rotation", "scale"};
      for (int p = 0; p < 3; ++p) {
        const std::size_t width = p == 1 ? 4 : 3;
        const std::size_t at = glb.grow(K * width * 4);
        auto* f = reinterpret_cast<float*>(glb.data() + at);
        Eigen::Quaterniond previous = Eigen::Quaterniond::Identity();
        for (std::size_t i = 0; i < K; ++i) {
          const JointTrs& trs = in.keys[i][j];
          float* o = f + i * width;
          if (p == 1) {
            Eigen::Quaterniond q = trs.rotation.normalized();
            if (i > 0 && q.dot(previous) < 0) q.coeffs() = -q.coeffs();
            previous = q;
            o[0] = static_cast<float>(q.x());
            o[1] = static_cast<float>(q.y());
            o[2] = static_cast<float>(q.z());
            o[3] = static_cast<float>(q.w());
          } else {
            const Eigen::Vector3d& x = p == 0 ? trs.translation : trs.scale;
            for (int c = 0; c < 3; ++c) o[c] = static_cast<float>(x[c]);
          }
        }
        const int output = glb.add_accessor(glb.add_view(at, K * width * 4, 0),
                                            detail::kComponentFloat, K, p == 1 ? "VEC4" : "VEC3");
        samplers.push_back({{"input", input}, {"interpolation", "LINEAR"}, {"output", output}});
        channels.push_back({{"sampler", samplers.size() - 1},
                            {"target", {{"node", 2 + j}, {"path", paths[p]}}}});
      }
    }
    glb.doc()["animations"] = json::array(
        {json{{"name", "timeline"}, {"channels", channels}, {"samplers", samplers}}});
  }
  return glb.finish("rig GLB");
}

}  // namespace hdeform

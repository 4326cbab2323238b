#include "engine/io/animation_glb.h"

#include "engine/io/mesh_writers.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace hdeform {

namespace {
constexpr std::size_t kJsonBound = 64 * 1024;  // the JSON chunk, generous for ≤ 1000 accessors
}

std::size_t AnimationGlb::bytes_for(std::size_t n, std::size_t m, std::size_t frames,
                                    bool colors) {
  const std::size_t per_frame = n * 12 * (colors ? 3 : 2);
  const std::size_t weights = frames * (frames > 0 ? frames - 1 : 0) * 4;
  return frames * per_frame + m * 12 + frames * 4 + weights + kJsonBound +
         frames * 600;  // accessor and view entries per frame
}

AnimationGlb::AnimationGlb(Triangles F, Eigen::Index vertices, std::vector<double> times,
                           bool colors, bool up_z)
    : F_(std::move(F)),
      n_(static_cast<std::size_t>(vertices)),
      times_(std::move(times)),
      colors_(colors),
      up_z_(up_z) {
  if (times_.empty()) throw std::logic_error("AnimationGlb: no sample times");
  data_.resize(times_.size() * n_ * 12 * static_cast<std::size_t>(attributes()));
  lo_.assign(times_.size(), std::vector<double>(3, std::numeric_limits<double>::infinity()));
  hi_.assign(times_.size(), std::vector<double>(3, -std::numeric_limits<double>::infinity()));
}

float* AnimationGlb::block(std::size_t frame, int attribute) {
  const std::size_t offset =
      (frame * static_cast<std::size_t>(attributes()) + static_cast<std::size_t>(attribute)) *
      n_ * 12;
  return reinterpret_cast<float*>(data_.data() + offset);
}

void AnimationGlb::write(std::size_t k, int a, const Eigen::Ref<const Eigen::MatrixXd>& X) {
  float* out = block(k, a);
  const float* base = block(0, a);
  const auto n = static_cast<Eigen::Index>(n_);
  for (Eigen::Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const std::size_t at = static_cast<std::size_t>(3 * i + c);
      // Frame 0 is the base; later frames are deltas against its float32 values, so
      // base + delta is the frame to float32 rounding of the delta alone.
      const float f = k == 0 ? static_cast<float>(X(i, c))
                             : static_cast<float>(X(i, c) - static_cast<double>(base[at]));
      out[at] = f;
      if (a == 0) {
        auto& lo = lo_[k][static_cast<std::size_t>(c)];
        auto& hi = hi_[k][static_cast<std::size_t>(c)];
        lo = std::min(lo, double{f});
        hi = std::max(hi, double{f});
      }
    }
}

void AnimationGlb::add_frame(const Vertices& V, const Vertices& N) {
  if (added_ >= times_.size()) throw std::logic_error("AnimationGlb: more frames than times");
  const auto n = static_cast<Eigen::Index>(n_);
  if (V.rows() != n || N.rows() != n || V.cols() != 3 || N.cols() != 3)
    throw std::logic_error("AnimationGlb: frame of the wrong shape");
  write(added_, 0, V);
  write(added_, 1, N);
  ++added_;
}

void AnimationGlb::set_colors(std::size_t frame, const Eigen::MatrixXf& C) {
  if (!colors_ || frame != colored_ || frame >= added_)
    throw std::logic_error("AnimationGlb: colours out of order");
  if (C.rows() != static_cast<Eigen::Index>(n_) || C.cols() != 3)
    throw std::logic_error("AnimationGlb: colours of the wrong shape");
  write(frame, 2, C.cast<double>());
  ++colored_;
}

std::string AnimationGlb::finish() {
  if (added_ != times_.size() || (colors_ && colored_ != added_))
    throw std::logic_error("AnimationGlb: frames or colours missing");
  const std::size_t K = times_.size(), m = static_cast<std::size_t>(F_.rows());
  const std::size_t frames_bytes = data_.size();
  const std::size_t index_offset = frames_bytes;
  const std::size_t times_offset = index_offset + m * 12;
  const std::size_t weights_offset = times_offset + K * 4;
  data_.resize(weights_offset + K * (K - 1) * 4);
  auto* ind = reinterpret_cast<std::uint32_t*>(data_.data() + index_offset);
  for (std::size_t t = 0; t < m; ++t)
    for (int c = 0; c < 3; ++c)
      ind[3 * t + static_cast<std::size_t>(c)] =
          static_cast<std::uint32_t>(F_(static_cast<Eigen::Index>(t), c));
  auto* tf = reinterpret_cast<float*>(data_.data() + times_offset);
  for (std::size_t k = 0; k < K; ++k) tf[k] = static_cast<float>(times_[k]);
  // Sample k shows frame k: all weights 0 at k = 0, target k − 1 alone after.
  auto* w = reinterpret_cast<float*>(data_.data() + weights_offset);
  std::fill(w, w + K * (K - 1), 0.0f);
  for (std::size_t k = 1; k < K; ++k) w[k * (K - 1) + (k - 1)] = 1.0f;

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "hdeform";
  auto view = [&](std::size_t offset, std::size_t length, int target) {
    tinygltf::BufferView bv;
    bv.buffer = 0;
    bv.byteOffset = offset;
    bv.byteLength = length;
    bv.target = target;
    model.bufferViews.push_back(bv);
    return static_cast<int>(model.bufferViews.size() - 1);
  };
  auto accessor = [&](int view_index, std::size_t count, int type, int component) {
    tinygltf::Accessor a;
    a.bufferView = view_index;
    a.componentType = component;
    a.count = count;
    a.type = type;
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size() - 1);
  };
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  static const char* const names[] = {"POSITION", "NORMAL", "COLOR_0"};
  for (std::size_t k = 0; k < K; ++k) {
    std::map<std::string, int> attrs;
    for (int a = 0; a < attributes(); ++a) {
      const std::size_t offset =
          reinterpret_cast<unsigned char*>(block(k, a)) - data_.data();
      const int v = view(offset, n_ * 12, TINYGLTF_TARGET_ARRAY_BUFFER);
      const int acc = accessor(v, n_, TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_FLOAT);
      if (a == 0 && n_ > 0) {
        model.accessors[static_cast<std::size_t>(acc)].minValues = lo_[k];
        model.accessors[static_cast<std::size_t>(acc)].maxValues = hi_[k];
      }
      attrs[names[a]] = acc;
    }
    if (k == 0)
      prim.attributes = attrs;
    else
      prim.targets.push_back(attrs);
  }
  prim.indices = accessor(view(index_offset, m * 12, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER), 3 * m,
                          TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
  tinygltf::Mesh mesh;
  mesh.name = "deformation";
  mesh.primitives.push_back(prim);
  mesh.weights.assign(K - 1, 0.0);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.name = "deformed";
  node.mesh = 0;
  model.nodes.push_back(node);
  detail::add_scene(model, up_z_);

  if (K > 1) {
    const int input = accessor(view(times_offset, K * 4, 0), K, TINYGLTF_TYPE_SCALAR,
                               TINYGLTF_COMPONENT_TYPE_FLOAT);
    model.accessors[static_cast<std::size_t>(input)].minValues = {static_cast<double>(tf[0])};
    model.accessors[static_cast<std::size_t>(input)].maxValues = {static_cast<double>(tf[K - 1])};
    const int output = accessor(view(weights_offset, K * (K - 1) * 4, 0), K * (K - 1),
                                TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_FLOAT);
    tinygltf::Animation anim;
    anim.name = "timeline";
    tinygltf::AnimationSampler sampler;
    sampler.input = input;
    sampler.output = output;
    sampler.interpolation = "LINEAR";
    anim.samplers.push_back(sampler);
    tinygltf::AnimationChannel channel;
    channel.sampler = 0;
    channel.target_node = 0;
    channel.target_path = "weights";
    anim.channels.push_back(channel);
    model.animations.push_back(anim);
  } else {
    data_.resize(times_offset);  // a still: no animation data
  }

  tinygltf::Buffer buffer;
  buffer.data = std::move(data_);
  model.buffers.push_back(std::move(buffer));
  return detail::serialise_glb(model, "AnimationGlb");
}

Eigen::Vector3f energy_color(double e, double scale) {
  static const float stops[5][3] = {
      {0.0f, 0.1f, 0.9f}, {0.0f, 0.8f, 0.9f}, {0.1f, 0.8f, 0.1f}, {0.95f, 0.85f, 0.0f},
      {0.9f, 0.05f, 0.0f}};
  double u = scale > 0 && std::isfinite(e) ? std::clamp(e / scale, 0.0, 1.0) : 0.0;
  const double x = u * 4;
  const int i = std::min(3, static_cast<int>(x));
  const float f = static_cast<float>(x - i);
  Eigen::Vector3f c;
  for (int k = 0; k < 3; ++k) c[k] = (1 - f) * stops[i][k] + f * stops[i + 1][k];
  return c;
}

Eigen::VectorXd vertex_energies(const Triangles& F, Eigen::Index vertices,
                                const Eigen::VectorXf& triangle_energies) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(vertices);
  Eigen::VectorXi count = Eigen::VectorXi::Zero(vertices);
  for (Eigen::Index t = 0; t < F.rows(); ++t)
    for (int c = 0; c < 3; ++c) {
      sum[F(t, c)] += triangle_energies[t];
      ++count[F(t, c)];
    }
  for (Eigen::Index i = 0; i < vertices; ++i)
    if (count[i] > 0) sum[i] /= count[i];
  return sum;
}

}  // namespace hdeform

#include "engine/io/animation_glb.h"

#include "engine/io/glb_builder.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
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

std::size_t AnimationGlb::offset(std::size_t frame, int attribute) const {
  return (frame * static_cast<std::size_t>(attributes()) + static_cast<std::size_t>(attribute)) *
         n_ * 12;
}

float* AnimationGlb::block(std::size_t frame, int attribute) {
  return reinterpret_cast<float*>(data_.data() + offset(frame, attribute));
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
  using detail::GlbBuilder;
  using json = GlbBuilder::json;
  const std::size_t K = times_.size(), m = static_cast<std::size_t>(F_.rows());
  // Buffer 0: the frames as add_frame laid them out, the indices, then (animated) the sample
  // times and the weights.
  GlbBuilder glb(GlbBuilder::ZeroOffset::omitted, std::move(data_));
  static const char* const names[] = {"POSITION", "NORMAL", "COLOR_0"};
  json base, targets = json::array();  // frame 0's attributes, the others'
  for (std::size_t k = 0; k < K; ++k) {
    json attrs = json::object();
    for (int a = 0; a < attributes(); ++a) {
      const bool bounds = a == 0 && n_ > 0;
      attrs[names[a]] = glb.add_accessor(
          glb.add_view(offset(k, a), n_ * 12, detail::kTargetArrayBuffer), detail::kComponentFloat,
          n_, "VEC3", bounds ? json(lo_[k]) : nullptr, bounds ? json(hi_[k]) : nullptr);
    }
    if (k == 0)
      base = std::move(attrs);
    else
      targets.push_back(std::move(attrs));
  }
  const std::size_t index_at = glb.grow(m * 12);
  auto* ind = reinterpret_cast<std::uint32_t*>(glb.data() + index_at);
  for (std::size_t t = 0; t < m; ++t)
    for (int c = 0; c < 3; ++c)
      ind[3 * t + static_cast<std::size_t>(c)] =
          static_cast<std::uint32_t>(F_(static_cast<Eigen::Index>(t), c));
  json primitive = detail::triangles(
      std::move(base),
      glb.add_accessor(glb.add_view(index_at, m * 12, detail::kTargetElementArrayBuffer),
                       detail::kComponentUnsignedInt, 3 * m, "SCALAR"));
  json mesh = {{"name", "deformation"}};
  if (K > 1) {
    primitive["targets"] = std::move(targets);
    mesh["weights"] = std::vector<double>(K - 1, 0.0);
  }
  glb.set_mesh(std::move(primitive), up_z_, std::move(mesh), {{"name", "deformed"}});
  if (K == 1) return glb.finish("AnimationGlb");  // a still: no animation

  const std::size_t times_at = glb.grow(K * 4);
  auto* tf = reinterpret_cast<float*>(glb.data() + times_at);
  for (std::size_t k = 0; k < K; ++k) tf[k] = static_cast<float>(times_[k]);
  const int input = glb.add_accessor(glb.add_view(times_at, K * 4, 0), detail::kComponentFloat, K,
                                     "SCALAR", json::array({static_cast<double>(tf[0])}),
                                     json::array({static_cast<double>(tf[K - 1])}));
  // Sample k shows frame k: all weights 0 at k = 0, target k − 1 alone after.
  const std::size_t weights_at = glb.grow(K * (K - 1) * 4);
  auto* w = reinterpret_cast<float*>(glb.data() + weights_at);
  for (std::size_t k = 1; k < K; ++k) w[k * (K - 1) + (k - 1)] = 1.0f;
  const int output = glb.add_accessor(glb.add_view(weights_at, K * (K - 1) * 4, 0),
                                      detail::kComponentFloat, K * (K - 1), "SCALAR");
  const json sampler = {{"input", input}, {"interpolation", "LINEAR"}, {"output", output}};
  const json channel = {{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}};
  glb.doc()["animations"] = json::array({json{{"name", "timeline"},
                                              {"channels", json::array({channel})},
                                              {"samplers", json::array({sampler})}}});
  return glb.finish("AnimationGlb");
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

// An animated GLB of a deformation sequence (docs/api.md "Timeline and animation"): the first
// sampled frame is the base mesh, frame k ≥ 1 is morph target k − 1 (POSITION and NORMAL
// deltas, and COLOR_0 deltas when colours are written), and one animation's LINEAR sampler
// drives the weights one-hot at each sample time. Positions between two samples are their
// linear blend (exact at the samples, to float32). glTF 2.0; checked with the Khronos
// validator in tests/browser.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <vector>

namespace hdeform {

class AnimationGlb {
 public:
  // The GLB's size in bytes for n vertices, m triangles and `frames` samples (limits are
  // checked with it before any frame is solved); JSON overhead is bounded by a constant.
  static std::size_t bytes_for(std::size_t n, std::size_t m, std::size_t frames, bool colors);

  // `times`: the sample times in seconds (increasing, at least one). colors: every frame
  // brings per-vertex linear RGB in [0, 1] (COLOR_0). up_z: as WriteOptions::up_z.
  AnimationGlb(Triangles F, Eigen::Index vertices, std::vector<double> times, bool colors,
               bool up_z);

  // Frames in order, exactly times.size() of them. V, N: n×3 model units / unit normals.
  // Throws std::logic_error on a wrong count or shape.
  void add_frame(const Vertices& V, const Vertices& N);
  // With colours: each frame's n×3 colours, in frame order, once that frame was added (a
  // caller that scales colours by every frame's energy sets them after the last frame).
  void set_colors(std::size_t frame, const Eigen::MatrixXf& C);
  std::size_t frames_added() const { return added_; }

  // The GLB, after the last frame and its colours (throws std::logic_error before).
  std::string finish();

 private:
  std::size_t offset(std::size_t frame, int attribute) const;  // of a block in data_
  float* block(std::size_t frame, int attribute);
  void write(std::size_t frame, int attribute, const Eigen::Ref<const Eigen::MatrixXd>& X);  // attribute: 0 POSITION, 1 NORMAL, 2 COLOR_0
  int attributes() const { return colors_ ? 3 : 2; }

  Triangles F_;
  std::size_t n_;
  std::vector<double> times_;
  bool colors_, up_z_;
  std::size_t added_ = 0, colored_ = 0;
  std::string data_;  // [frame 0 | frame 1 | …], a frame's attributes in turn, n×12 B each
  std::vector<std::vector<double>> lo_, hi_;  // per frame: POSITION min/max (deltas for k ≥ 1)
};

// A vertex colour for energy e in [0, scale]: a blue → cyan → green → yellow → red ramp,
// linear RGB. e ≤ 0 (or scale ≤ 0) is blue, e ≥ scale red.
Eigen::Vector3f energy_color(double e, double scale);

// Per-vertex energy from per-triangle e_f²: the mean over the vertex's triangles (0 if none).
Eigen::VectorXd vertex_energies(const Triangles& F, Eigen::Index vertices,
                                const Eigen::VectorXf& triangle_energies);

}  // namespace hdeform

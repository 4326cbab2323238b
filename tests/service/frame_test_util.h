// Shared by the frame encoding tests: synthetic float32 frames and the error bounds
// deform.proto states for QUANTIZED (and so for MESHOPT and MESHOPT_DELTA).
#pragma once

#include "frame_decode.h"
#include "service_fixture.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace hdeform::testing {

using cli::decode_frame;

inline double angle_deg(const float a[3], const float b[3]) {
  const double d = std::clamp(double(a[0]) * b[0] + double(a[1]) * b[1] + double(a[2]) * b[2],
                              -1.0, 1.0);
  return std::acos(d) * 180.0 / M_PI;
}

inline std::string float_bytes(const std::vector<float>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float));
}

// The inverse of float_bytes: a frame buffer's float32 values.
inline std::vector<float> floats_of(const std::string& bytes) {
  std::vector<float> v(bytes.size() / sizeof(float));
  if (!v.empty()) std::memcpy(v.data(), bytes.data(), v.size() * sizeof(float));  // null if empty
  return v;
}

// A float32 frame of n random points in a skewed box, random unit normals, energies.
inline pb::Frame random_frame(std::size_t n, std::size_t t, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> p(3 * n), nr(3 * n), e(t);
  for (std::size_t i = 0; i < n; ++i) {
    p[3 * i] = 100 + 7 * u(rng);
    p[3 * i + 1] = -3 + 0.01f * u(rng);
    p[3 * i + 2] = 5e3f * u(rng);
    float v[3];
    double l = 0;
    do {
      for (float& x : v) x = u(rng);
      l = std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]);
    } while (l < 1e-3 || l > 1);
    for (int k = 0; k < 3; ++k) nr[3 * i + k] = static_cast<float>(v[k] / l);
  }
  for (auto& x : e) x = 4 * (u(rng) + 1);
  pb::Frame f;
  f.set_positions(float_bytes(p));
  f.set_normals(float_bytes(nr));
  f.set_energies(float_bytes(e));
  f.set_exact(false);
  return f;
}

// Every encoded value within the bounds deform.proto states for QUANTIZED.
inline void expect_within_stated_bounds(const pb::Frame& f32, const cli::DecodedFrame& q,
                                 const pb::Box& box, float energies_max) {
  const auto ref = decode_frame(f32, q.positions.size() / 3, q.energies.size());
  const double lo[3] = {box.min().x(), box.min().y(), box.min().z()};
  const double hi[3] = {box.max().x(), box.max().y(), box.max().z()};
  double worst_pos = 0, worst_angle = 0, worst_e = 0;
  for (std::size_t i = 0; i < ref.positions.size() / 3; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double x = ref.positions[3 * i + k];
      EXPECT_LE(lo[k], x);
      EXPECT_GE(hi[k], x);
      const double bound = (hi[k] - lo[k]) / 131070 + 1e-6 * std::max(std::abs(lo[k]), std::abs(hi[k]));
      const double err = std::abs(q.positions[3 * i + k] - x);
      worst_pos = std::max(worst_pos, err / std::max(bound, 1e-300));
      ASSERT_LE(err, bound) << "vertex " << i << " axis " << k;
    }
    worst_angle = std::max(worst_angle, angle_deg(&ref.normals[3 * i], &q.normals[3 * i]));
  }
  for (std::size_t l = 0; l < ref.energies.size(); ++l)
    worst_e = std::max(worst_e, std::abs(double(q.energies[l]) - ref.energies[l]));
  EXPECT_LE(worst_angle, 1.2) << "octahedral int8 normals";
  // The stated bound plus float32 rounding at both ends (2^-24 relative each, twice over).
  EXPECT_LE(worst_e, energies_max / 131070.0 + 2.5e-7 * energies_max);
  std::printf("[ measured ] position error ≤ %.3f of the stated bound, normals ≤ %.3f°, "
              "energies ≤ %.3g (max %.3g)\n",
              worst_pos, worst_angle, worst_e, double(energies_max));
}

}  // namespace hdeform::testing

#include "render.h"

#include <Eigen/Geometry>

#include "write_if_changed.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace hdeform::report {

Eigen::Vector3f energy_colour(double value, double truncate) {
  const float t = truncate > 0 ? static_cast<float>(std::clamp(value / truncate, 0.0, 1.0)) : 0.f;
  return Eigen::Vector3f(1.0f, 1.0f - 0.85f * t, 1.0f - 0.85f * t);
}

void render_png(const std::string& path, const Vertices& V, const Triangles& F,
                const Eigen::MatrixX3f& colours, const View& view) {
  // Camera frame: w towards the viewer, u right, v up.
  const Eigen::Vector3d w = view.direction.normalized();
  const Eigen::Vector3d u = view.up.cross(w).normalized();
  const Eigen::Vector3d v = w.cross(u);
  Eigen::Matrix3d P;
  P << u.transpose(), v.transpose(), w.transpose();
  const Eigen::MatrixX3d Q = V * P.transpose();  // camera coordinates
  const Eigen::RowVector3d lo = Q.colwise().minCoeff(), hi = Q.colwise().maxCoeff();
  const int N = view.size;
  const double margin = 0.05 * N;
  const double scale = (N - 2 * margin) / std::max(hi[0] - lo[0], hi[1] - lo[1]);
  const double ox = 0.5 * (N - scale * (hi[0] - lo[0])), oy = 0.5 * (N - scale * (hi[1] - lo[1]));

  std::vector<float> depth(static_cast<std::size_t>(N) * N, -std::numeric_limits<float>::infinity());
  std::vector<unsigned char> rgb(static_cast<std::size_t>(N) * N * 3, 255);
  const Eigen::Vector3d light = Eigen::Vector3d(0.3, 0.5, 1.0).normalized();  // camera frame

  for (Eigen::Index l = 0; l < F.rows(); ++l) {
    Eigen::Vector3d p[3];
    for (int c = 0; c < 3; ++c) {
      const Eigen::RowVector3d q = Q.row(F(l, c));
      p[c] = Eigen::Vector3d(ox + scale * (q[0] - lo[0]), N - (oy + scale * (q[1] - lo[1])), q[2]);
    }
    const Eigen::Vector3d n = (Q.row(F(l, 1)) - Q.row(F(l, 0)))
                                  .transpose()
                                  .cross((Q.row(F(l, 2)) - Q.row(F(l, 0))).transpose())
                                  .normalized();
    const float shade = static_cast<float>(0.35 + 0.65 * std::abs(n.dot(light)));  // two-sided
    const Eigen::Vector3f colour = colours.row(l).transpose() * shade;
    const double area = (p[1].x() - p[0].x()) * (p[2].y() - p[0].y()) -
                        (p[2].x() - p[0].x()) * (p[1].y() - p[0].y());
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({p[0].x(), p[1].x(), p[2].x()}))));
    const int x1 = std::min(N - 1, static_cast<int>(std::ceil(std::max({p[0].x(), p[1].x(), p[2].x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({p[0].y(), p[1].y(), p[2].y()}))));
    const int y1 = std::min(N - 1, static_cast<int>(std::ceil(std::max({p[0].y(), p[1].y(), p[2].y()}))));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        const double b0 = ((p[1].x() - px) * (p[2].y() - py) - (p[2].x() - px) * (p[1].y() - py)) / area;
        const double b1 = ((p[2].x() - px) * (p[0].y() - py) - (p[0].x() - px) * (p[2].y() - py)) / area;
        const double b2 = 1.0 - b0 - b1;
        if (b0 < 0 || b1 < 0 || b2 < 0) continue;
        const float z = static_cast<float>(b0 * p[0].z() + b1 * p[1].z() + b2 * p[2].z());
        const std::size_t i = static_cast<std::size_t>(y) * N + x;
        if (z <= depth[i]) continue;
        depth[i] = z;
        for (int c = 0; c < 3; ++c)
          rgb[3 * i + c] = static_cast<unsigned char>(std::clamp(colour[c], 0.f, 1.f) * 255.f + 0.5f);
      }
  }
  write_png_if_changed(path, N, N, rgb.data());
}

}  // namespace hdeform::report

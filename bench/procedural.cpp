#include "procedural.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace hdeform::procedural {

TriMesh capsule(int segments, int rings, double radius, double body) {
  if (segments < 3 || rings < 1 || !(radius > 0) || !(body >= 0))
    throw std::invalid_argument("capsule: need segments >= 3, rings >= 1, radius > 0, body >= 0");
  const double pi = std::numbers::pi;
  const double quarter = 0.5 * pi * radius;     // arc length of one hemisphere's meridian
  const double length = 2 * quarter + body;     // meridian length, pole to pole
  const int n = rings * segments + 2;
  TriMesh mesh;
  mesh.V.resize(n, 3);
  mesh.F.resize(2 * static_cast<Eigen::Index>(rings) * segments, 3);

  const int south = 0, north = n - 1;
  mesh.V.row(south) << 0, 0, -radius;
  mesh.V.row(north) << 0, 0, body + radius;
  for (int i = 0; i < rings; ++i) {
    // Meridian profile at arc length t: (ρ, z).
    const double t = length * (i + 1) / (rings + 1);
    double rho, z;
    if (t < quarter) {
      const double phi = t / radius;
      rho = radius * std::sin(phi);
      z = -radius * std::cos(phi);
    } else if (t <= quarter + body) {
      rho = radius;
      z = t - quarter;
    } else {
      const double phi = (t - quarter - body) / radius;
      rho = radius * std::cos(phi);
      z = body + radius * std::sin(phi);
    }
    const double offset = 0.5 * (i % 2);
    for (int j = 0; j < segments; ++j) {
      const double theta = 2 * pi * (j + offset) / segments;
      mesh.V.row(1 + i * segments + j) << rho * std::cos(theta), rho * std::sin(theta), z;
    }
  }

  auto ring = [&](int i, int j) { return 1 + i * segments + (j % segments); };
  Eigen::Index f = 0;
  // Pole fans (CCW from outside: seen from below, the south fan runs clockwise in θ).
  for (int j = 0; j < segments; ++j) mesh.F.row(f++) << south, ring(0, j + 1), ring(0, j);
  for (int j = 0; j < segments; ++j)
    mesh.F.row(f++) << ring(rings - 1, j), ring(rings - 1, j + 1), north;
  // Bands between ring i (below) and i + 1 (above).
  for (int i = 0; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      if (i % 2 == 0) {  // upper ring shifted by +½ segment
        mesh.F.row(f++) << ring(i, j), ring(i, j + 1), ring(i + 1, j);
        mesh.F.row(f++) << ring(i + 1, j), ring(i, j + 1), ring(i + 1, j + 1);
      } else {           // lower ring shifted by +½ segment
        mesh.F.row(f++) << ring(i, j), ring(i + 1, j + 1), ring(i + 1, j);
        mesh.F.row(f++) << ring(i, j), ring(i, j + 1), ring(i + 1, j + 1);
      }
    }
  return mesh;
}

CapsuleSize capsule_size(int target_vertices, double radius, double body) {
  // rings ≈ length / (√3/2 · 2πr/s), n ≈ s · rings  ⇒  s² ≈ n · √3/2 · 2πr / length.
  const double pi = std::numbers::pi;
  const double length = pi * radius + body;
  const double k = length / (std::sqrt(3.0) / 2.0 * 2.0 * pi * radius);  // rings per segment
  CapsuleSize size;
  size.segments = std::max(3, static_cast<int>(std::lround(std::sqrt(target_vertices / k))));
  size.rings = std::max(1, static_cast<int>(std::lround(k * size.segments)));
  return size;
}

CapsuleCase capsule_case(int target_vertices, double fraction) {
  const CapsuleSize size = capsule_size(target_vertices);
  CapsuleCase c;
  c.mesh = capsule(size.segments, size.rings);
  const double lo = c.mesh.V.col(2).minCoeff(), hi = c.mesh.V.col(2).maxCoeff();
  const double band = fraction * (hi - lo);
  for (int v = 0; v < c.mesh.num_vertices(); ++v) {
    const double z = c.mesh.V(v, 2);
    if (z <= lo + band) c.base.push_back(v);
    else if (z >= hi - band) c.cap.push_back(v);
  }
  return c;
}

}  // namespace hdeform::procedural

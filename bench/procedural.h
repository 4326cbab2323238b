// Procedural test meshes: a closed capsule (tube with hemispherical ends) of any size,
// with a fixed base and a cap handle chosen by height. Used by the benchmarks; small
// enough to reuse in tests.
#pragma once

#include "mesh.h"

#include <vector>

namespace hdeform::procedural {

// Closed capsule around the z axis: radius r, cylindrical body of height `body` (from
// z = 0 to z = body), hemispheres below and above, so z spans [−r, body + r].
// `segments` vertices per ring, `rings` rings (alternate rings rotated by half a segment,
// so triangles are near-equilateral when the ring spacing is ≈ √3/2 · 2πr/segments), plus
// one pole vertex at each end. n = rings · segments + 2, m = 2 · rings · segments
// (genus 0: n − m/2 = 2). Triangles are counter-clockwise seen from outside.
// Vertex order: south pole, rings bottom to top (each by angle), north pole.
TriMesh capsule(int segments, int rings, double radius = 1.0, double body = 8.0);

// Segments and rings giving about `target_vertices` vertices with near-equilateral
// triangles for the given proportions.
struct CapsuleSize {
  int segments = 0, rings = 0;
};
CapsuleSize capsule_size(int target_vertices, double radius = 1.0, double body = 8.0);

// A capsule with its constraint regions: `base` = vertices in the bottom `fraction` of the
// height, `cap` = the top `fraction` (both ascending vertex ids).
struct CapsuleCase {
  TriMesh mesh;
  std::vector<int> base, cap;
};
CapsuleCase capsule_case(int target_vertices, double fraction = 0.05);

}  // namespace hdeform::procedural

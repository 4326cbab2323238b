// Area-weighted unit vertex normals of a deformed mesh, computed by gathering instead of
// scattering, so both cores share the work with no atomics. Bitwise equal
// to mesh_io's serial vertex_normals(): each vertex sums its triangles' weights in ascending
// triangle order, then normalizes.
#pragma once

#include "engine/mesh/mesh.h"

#include <vector>

namespace hdeform {

// The triangles around each vertex, ascending (CSR): triangles of v are
// triangles[offsets[v] … offsets[v+1]). Built once per mesh.
struct VertexTriangles {
  std::vector<int> offsets, triangles;
  static VertexTriangles build(int n, const Triangles& F);
  std::size_t memory_bytes() const { return (offsets.size() + triangles.size()) * sizeof(int); }
};

// N (n×3) from positions X; `face_w` is scratch (m×3, reused: no allocation once sized).
// Vertices without triangles get zero.
void vertex_normals(const Vertices& X, const Triangles& F, const VertexTriangles& vt,
                    Vertices& face_w, Vertices& N);

// The gathering half alone, from face_w = (x₁ − x₀) × (x₂ − x₀) per triangle already
// computed (measure() writes them when asked: an exact frame's one pass over the triangles).
void vertex_normals_from_faces(const VertexTriangles& vt, const Vertices& face_w, Vertices& N);

}  // namespace hdeform

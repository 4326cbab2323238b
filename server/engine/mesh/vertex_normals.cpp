#include "engine/mesh/vertex_normals.h"

#include "engine/runtime/two_threads.h"
#include "engine/simd/cpu_features.h"
#include "engine/simd/vertex_normals_kernels.h"

#include <Eigen/Geometry>

#include <algorithm>

namespace hdeform {

VertexTriangles VertexTriangles::build(int n, const Triangles& F) {
  VertexTriangles vt;
  vt.offsets.assign(static_cast<std::size_t>(n) + 1, 0);
  for (Eigen::Index t = 0; t < F.rows(); ++t)
    for (int k = 0; k < 3; ++k) ++vt.offsets[static_cast<std::size_t>(F(t, k)) + 1];
  for (std::size_t v = 0; v < static_cast<std::size_t>(n); ++v)
    vt.offsets[v + 1] += vt.offsets[v];
  vt.triangles.resize(static_cast<std::size_t>(vt.offsets.back()));
  std::vector<int> fill(vt.offsets.begin(), vt.offsets.end() - 1);
  for (Eigen::Index t = 0; t < F.rows(); ++t)  // ascending t: each list comes out sorted
    for (int k = 0; k < 3; ++k) vt.triangles[static_cast<std::size_t>(fill[F(t, k)]++)] = static_cast<int>(t);
  return vt;
}

namespace {

// N_v: the sum of v's triangles' weights in ascending triangle order, normalized.
inline void gather(const VertexTriangles& vt, const Vertices& face_w, Eigen::Index v, Vertices& N) {
  Eigen::RowVector3d s = Eigen::RowVector3d::Zero();
  for (int i = vt.offsets[static_cast<std::size_t>(v)]; i < vt.offsets[static_cast<std::size_t>(v) + 1]; ++i)
    s += face_w.row(vt.triangles[static_cast<std::size_t>(i)]);
  const double len = s.norm();
  if (len > 0) s /= len;
  N.row(v) = s;
}

// Both passes in chunks on two threads (two_threads.h for_chunks), each by the AVX2 kernels
// (vertex_normals_kernels.h) or the scalar loops.
void face_weights(const Vertices& X, const Triangles& F, Eigen::Index t0, Eigen::Index t1,
                  Vertices& face_w, bool vector_isa) {
  if (vector_isa) return detail::face_weights_avx2(F.data(), X.data(), t0, t1, face_w.data());
  for (Eigen::Index t = t0; t < t1; ++t) {
    const Eigen::RowVector3d a = X.row(F(t, 0)), b = X.row(F(t, 1)), c = X.row(F(t, 2));
    face_w.row(t) = (b - a).cross(c - a);  // |w| = 2 · area: area weighting
  }
}

void gather_block(const VertexTriangles& vt, const Vertices& face_w, Eigen::Index v0,
                  Eigen::Index v1, Vertices& N, bool vector_isa) {
  if (vector_isa)
    return detail::gather_normals_avx2(vt.offsets.data(), vt.triangles.data(), face_w.data(),
                                       v0, v1, N.data());
  for (Eigen::Index v = v0; v < v1; ++v) gather(vt, face_w, v, N);
}

}  // namespace

void vertex_normals(const Vertices& X, const Triangles& F, const VertexTriangles& vt,
                    Vertices& face_w, Vertices& N) {
  const Eigen::Index m = F.rows(), n = X.rows();
  face_w.resize(m, 3);
  N.resize(n, 3);
  const bool vector_isa = kernel_isa() == Isa::avx2;
  for_chunks(m, [&](Eigen::Index t0, Eigen::Index t1, int) {
    face_weights(X, F, t0, t1, face_w, vector_isa);
  });
  for_chunks(n, [&](Eigen::Index v0, Eigen::Index v1, int) {
    gather_block(vt, face_w, v0, v1, N, vector_isa);
  });
}

void vertex_normals_from_faces(const VertexTriangles& vt, const Vertices& face_w, Vertices& N) {
  const auto n = static_cast<Eigen::Index>(vt.offsets.size()) - 1;
  N.resize(n, 3);
  const bool vector_isa = kernel_isa() == Isa::avx2;
  for_chunks(n, [&](Eigen::Index v0, Eigen::Index v1, int) {
    gather_block(vt, face_w, v0, v1, N, vector_isa);
  });
}

}  // namespace hdeform

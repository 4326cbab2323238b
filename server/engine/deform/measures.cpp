#include "engine/deform/measures.h"

#include "engine/deform/deformer.h"
#include "engine/runtime/two_threads.h"
#include "engine/simd/cpu_features.h"
#include "engine/simd/measure_triangles.h"

#include <algorithm>
#include <cmath>

namespace hdeform {

namespace {

// Triangles l0 ≤ l < l1 the scalar way (the generic build, and the few triangles left of a
// thread's blocks of four), added to `sums`.
void measure_triangles(const PreparedMesh& pm, const Vertices& X, const GuidanceField& g,
                       const Vertices& Rn, Eigen::Index l0, Eigen::Index l1,
                       Eigen::VectorXf* ef2, Vertices* face_w, detail::MeasureSums& sums) {
  const Triangles& F = pm.mesh().F;
  const TriangleGradients& grads = pm.gradients();
  detail::MeasureSums s = sums;  // a local copy the compiler keeps in registers
  for (Eigen::Index l = l0; l < l1; ++l) {
    const double a = pm.areas()[l];
    // Y'_l = Σ_i ∇φ_i x'_iᵀ, block l of G X' without forming G X'.
    const Eigen::Vector3d x0 = X.row(F(l, 0)).transpose();
    const Eigen::Vector3d x1 = X.row(F(l, 1)).transpose();
    const Eigen::Vector3d x2 = X.row(F(l, 2)).transpose();
    const Eigen::Matrix3d Yl = grads.row(l).segment<3>(0).transpose() * x0.transpose() +
                               grads.row(l).segment<3>(3).transpose() * x1.transpose() +
                               grads.row(l).segment<3>(6).transpose() * x2.transpose();
    const double r2 = (Yl - g.middleRows<3>(3 * l)).squaredNorm();
    s.E += a * r2;
    s.max_ef2 = std::max(s.max_ef2, r2);
    if (ef2) (*ef2)[l] = static_cast<float>(r2);

    const Eigen::Vector3d c = (x1 - x0).cross(x2 - x0);
    if (face_w) face_w->row(l) = c.transpose();
    const double a_def = 0.5 * c.norm();
    s.area_deformed += a_def;

    // Y'_l has rank 2: σ₁² + σ₂² = ‖Y'_l‖²_F and σ₁σ₂ = a'_l / a_l (area ratio).
    const double sum_sq = Yl.squaredNorm();
    const double prod = a_def / a;
    const double sum = std::sqrt(std::max(0.0, sum_sq + 2 * prod));
    const double e_iso = sum_sq - 2 * sum + 2;                    // (σ₁−1)² + (σ₂−1)²
    const double e_conf = 0.5 * std::max(0.0, sum_sq - 2 * prod);  // ½(σ₁−σ₂)²
    s.iso += a * e_iso;
    s.conf += a * e_conf;
    s.max_iso = std::max(s.max_iso, e_iso);
    s.max_conf = std::max(s.max_conf, e_conf);

    if (c.dot(Rn.row(l).transpose()) < 0) ++s.flips;
  }
  sums = s;
}

}  // namespace

Measures measure(const PreparedMesh& pm, const Vertices& X, const GuidanceField& g,
                 const Vertices& Rn, Eigen::VectorXf* ef2, Vertices* face_w) {
  const Triangles& F = pm.mesh().F;
  const Eigen::Index m = F.rows();
  if (ef2) ef2->resize(m);
  if (face_w) face_w->resize(m, 3);
  const bool vector_isa = kernel_isa() == Isa::avx2;

  // Independent per triangle: chunks run on the caller and the solve's helper (for_chunks: no
  // OpenMP wake, no allocation); the chunks' sums are added in chunk order, so the measures
  // are the same bits whichever thread ran which chunk, or one thread all.
  detail::MeasureSums part[kChunks];
  for_chunks(m, [&](Eigen::Index begin, Eigen::Index end, int c) {
    detail::MeasureSums& s = part[c];
    Eigen::Index l = begin;
    if (vector_isa)
      l = detail::measure_triangles_avx2(F.data(), X.data(), pm.gradients().data(), g.data(),
                                         pm.areas().data(), Rn.data(), begin, end,
                                         ef2 ? ef2->data() : nullptr,
                                         face_w ? face_w->data() : nullptr, s);
    measure_triangles(pm, X, g, Rn, l, end, ef2, face_w, s);
  });
  detail::MeasureSums sum;
  for (const detail::MeasureSums& s : part) {
    sum.E += s.E;
    sum.iso += s.iso;
    sum.conf += s.conf;
    sum.area_deformed += s.area_deformed;
    sum.max_ef2 = std::max(sum.max_ef2, s.max_ef2);
    sum.max_iso = std::max(sum.max_iso, s.max_iso);
    sum.max_conf = std::max(sum.max_conf, s.max_conf);
    sum.flips += s.flips;
  }
  Measures out;
  out.E = sum.E;
  out.max_ef2 = sum.max_ef2;
  out.max_e_iso = sum.max_iso;
  out.max_e_conf = sum.max_conf;
  out.flips = static_cast<int>(sum.flips);
  const double total = pm.total_area();
  out.E_iso_N = sum.iso / total;
  out.E_conf_N = sum.conf / total;
  out.E_area_pct = 100.0 * (sum.area_deformed - total) / total;
  return out;
}

}  // namespace hdeform

// The seven measures of the thesis's tables (§3.5, §7.1) plus flips — SPEC.md §Measures.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Geometry>

#include <vector>

namespace hdeform {

struct Measures {
  double E = 0;           // Σ a_l ‖r_l‖²_F, un-regularized energy (units²)
  double E_iso_N = 0;     // area-weighted mean of (σ₁−1)² + (σ₂−1)²
  double E_conf_N = 0;    // area-weighted mean of ½(σ₁−σ₂)²
  double E_area_pct = 0;  // 100 · (area(S') − area(S)) / area(S)
  double max_e_iso = 0;
  double max_e_conf = 0;
  double max_ef2 = 0;     // max ‖r_l‖²_F
  int flips = 0;          // triangles with n'_l · (R_l n_l) < 0
};

class PreparedMesh;

// Measures of deformed positions X' against guidance g (3m×3, block l = g_l) with Rn the
// rest normals turned by the guidance rotations (m×3, row l = R_l n_l; guidance_field
// writes it). `ef2` (optional) receives ‖r_l‖²_F per triangle; `face_w` (optional, m×3)
// the deformed (x₁ − x₀) × (x₂ − x₀), the vertex normals' weights. With AVX2 (cpu_features.h)
// four triangles at a time (measure_triangles.h): the same terms, summed in another order.
Measures measure(const PreparedMesh& pm, const Vertices& X_deformed,
                 const GuidanceField& g, const Vertices& Rn,
                 Eigen::VectorXf* ef2 = nullptr, Vertices* face_w = nullptr);

}  // namespace hdeform

// Guidance field g (SPEC.md §Harmonic guidance field; thesis §6.5–6.6): per-triangle
// rotation R_l and stretch S_l blended by the harmonic basis, g_l = Y_l M_lᵀ, M_l = R_l S_l.
#pragma once

#include "engine/mesh/mesh.h"
#include "engine/mesh/transform.h"

#include <Eigen/Geometry>

#include <complex>
#include <span>
#include <vector>

namespace hdeform {

// Scratch of guidance_field, reused across calls (one per caller; n entries).
struct GuidanceScratch {
  std::vector<std::complex<double>> turn;  // one handle: e^{i φ_v θ/6} per vertex
};

// `Phi` (n × k) is the harmonic basis, `normals` the rest normals n_l (Y_l = I − n_l n_lᵀ).
// One handle: R_l = slerp(I, R₁, h_l), S_l = (1 − h_l) I + h_l S₁, h_l the mean of Φ over
// triangle l. Several: the per-vertex quaternion field (q_j flipped to w ≥ 0, identity on
// F₀) averaged per triangle and normalized; S entries blended the same way.
// Output: g (3m × 3), block l = rows 3l..3l+2; and, unless `Rn` is null, R_l n_l per
// triangle (m × 3, row l): the rest normal turned by the guidance rotation, the one thing of
// R_l the measures read (their flip test, SPEC §Measures).
void guidance_field(const Triangles& F, const Vertices& normals, const Eigen::MatrixXd& Phi,
                    std::span<const HandleTransform> transforms, GuidanceField& g, Vertices* Rn,
                    GuidanceScratch& scratch);

}  // namespace hdeform

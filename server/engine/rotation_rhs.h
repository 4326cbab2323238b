// The right-hand side (Gᵀ W_β)_F g of SPEC.md §Solve for one handle without stretch, without
// forming g (issue 10, item 3). With g_l = Y_l R_lᵀ (Y_l = I − n_l n_lᵀ) and
// a_{v,l} = ((Gᵀ W_β)_F(v, 3l), (…)(v, 3l+1), (…)(v, 3l+2)):
//
//   ((Gᵀ W_β)_F g)_v = Σ_l a_{v,l}ᵀ Y_l R_lᵀ = Σ_l (R_l Y_l a_{v,l})ᵀ,
//
// so the per-triangle 3×3 blocks of g (9 doubles written, then read back) are replaced by
// (cos α_l, sin α_l) of R_l (guidance_angles) and a rotation about the handle's axis per
// (row, triangle) pair. Any β: the sum runs over the triangles a row's entries name.
#pragma once

#include "mesh.h"
#include "operators.h"

#include <Eigen/Core>

namespace hdeform {

// rhs (rows × 3, column-major; resized, no allocation once sized) = GtW_F · g for the
// g = guidance_field(one handle, no stretch) whose R_l turns by α_l about `axis`:
// cs[2l] = cos α_l, cs[2l+1] = sin α_l (guidance_angles). GtW_F: row-major, columns 3l + d
// (d = 0, 1, 2) over the m triangles; normals: the rest normals n_l (m × 3). Both cores.
void rotation_rhs(const SparseMatrixR& GtW_F, const Vertices& normals,
                  const Eigen::Vector3d& axis, const double* cs, Eigen::MatrixXd& rhs);

}  // namespace hdeform

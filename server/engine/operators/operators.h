// Differential operators of SPEC.md §Operators, built once per mesh from the rest pose.
// All in the mesh's own units ("raw"); area-unit β is mapped onto them by the BetaUnits
// conversion in deformer.h.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Sparse>

#include <vector>

namespace hdeform {

using SparseMatrix = Eigen::SparseMatrix<double>;  // column-major, int indices
using SparseMatrixR = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// Per-triangle area a_l (units²). Precondition: no zero-area triangle.
Eigen::VectorXd triangle_areas(const Vertices& V, const Triangles& F);

// Per-triangle unit normal n_l (m×3), counter-clockwise orientation.
Vertices triangle_normals(const Vertices& V, const Triangles& F);

// Hat-function gradients per triangle (m × 9): ∇φ_i, ∇φ_j, ∇φ_k of triangle (i, j, k),
// each ∇φ_i = n_l × (x_k − x_j) / (2 a_l) (units⁻¹). The blocks G is assembled from.
using TriangleGradients = Eigen::Matrix<double, Eigen::Dynamic, 9, Eigen::RowMajor>;
TriangleGradients hat_gradients(const Vertices& V, const Triangles& F);

// G (3m × n): rows 3l+0..2 hold the x, y, z components of the hat-function gradients
// ∇φ_i = n_l × (x_k − x_j) / (2 a_l) of triangle l (units⁻¹). SPEC: on the rest mesh the
// 3×3 block l of G·X equals I − n_l n_lᵀ.
SparseMatrix grad(const Vertices& V, const Triangles& F);

// Interior edges: exactly two incident triangles. `tri[0]` gets +1 and `tri[1]` −1 in D.
struct InteriorEdge {
  int tri[2];
  double length;  // |x_a − x_b| in the mesh's units
};
std::vector<InteriorEdge> interior_edges(const Vertices& V, const Triangles& F);

// D (|E_int| × m): +1 / −1 on the two triangles of each interior edge.
SparseMatrix energy_differences(const std::vector<InteriorEdge>& edges, int num_triangles);

// D₃ G (3|E_int| × n): the jump of the per-triangle gradient across each interior edge.
SparseMatrix gradient_jumps(const SparseMatrix& G, const std::vector<InteriorEdge>& edges);

// W_β = (1 − β) A + β D₃ᵀ B₃ D₃ (3m × 3m), with A = diag(a_l ⊗ 1₃). Used by tests and
// by reference computations; the solver assembles K = Gᵀ W_β G without forming W_β.
SparseMatrix W_beta(const Eigen::VectorXd& areas, const std::vector<InteriorEdge>& edges,
                    double beta);

}  // namespace hdeform

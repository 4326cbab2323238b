// The (free, ·) blocks of the deformation system (SPEC.md §Solve): K_FF, K_FC and (Gᵀ W)_F,
// cut straight out of compressed storage without triplets. The blocks'
// values are copies of the operators' entries, so they match the triplet build bit for bit.
#pragma once

#include "engine/mesh/vertex_normals.h"
#include "engine/operators/operators.h"

#include <vector>

namespace hdeform {

// Where each vertex goes: region_of[v] < 0 free, ≥ 0 constrained; block_index[v] its
// position within its block (ascending vertex id), nF + nC = n.
struct BlockLayout {
  const std::vector<int>& region_of;
  const std::vector<int>& block_index;
  Eigen::Index nF, nC;
};

struct Blocks {
  SparseMatrix FF, FC;  // K_FF (full symmetric), K_FC
  SparseMatrixR GtW_F;  // (Gᵀ W)_F, row-major: the right-hand side is one product
};

// The blocks of a symmetric K (n × n) and GtW (n × 3m), both column-major. With GtW null
// only FF and FC are filled.
Blocks split(const SparseMatrix& K, const SparseMatrix* GtW, const BlockLayout& layout);

// The blocks of two systems on the union of their patterns, each with explicit zeros where
// only the other has an entry (so K₁ and K₂ blocks share one structure and combine value by
// value). Values as Eigen's `K₁ + 0.0 * K₂` and `K₂ + 0.0 * K₁` give them. With GtW1 and
// GtW2 null only FF and FC are filled (assemble_wide_free_rows builds the GtW_F of β > 0).
void split_union(const SparseMatrix& K1, const SparseMatrix& K2, const SparseMatrix* GtW1,
                 const SparseMatrix* GtW2, const BlockLayout& layout, Blocks& out1, Blocks& out2);

// (Gᵀ A)_F straight from the per-triangle gradients (no n × 3m Gᵀ A): row v of Gᵀ A holds
// a_l ∇φ_v of each triangle l around v. Preconditions as operator_assembly.h.
SparseMatrixR free_rows_gta(const Triangles& F, const TriangleGradients& grads,
                            const Eigen::VectorXd& areas, const VertexTriangles& vt,
                            const std::vector<int>& free_);

}  // namespace hdeform

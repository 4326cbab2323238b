// The rest-pose operators of SPEC.md §Operators built straight into compressed storage from
// the per-triangle gradients, in parallel. Each equals, bit for bit, the
// straightforward build in operators.cpp (triplets and sparse products), which stays as the
// reference: tests/engine/test_operator_assembly.cpp compares the two and checks that one
// and two OpenMP threads give the same bits.
//
// Preconditions for all: a mesh that passed validate_mesh (indices in range, no triangle
// repeating a vertex, manifold edges); `grads` = hat_gradients(V, F); `vt` =
// VertexTriangles::build(n, F); `edges` = interior_edges(…) of the same mesh.
#pragma once

#include "engine/mesh/vertex_normals.h"
#include "engine/operators/operators.h"

#include <array>
#include <vector>

namespace hdeform {

// interior_edges(V, F) from the vertex→triangle table: the same edges in the same order
// (ascending (min, max) vertex pair; tri[0] < tri[1]), without a hash map.
std::vector<InteriorEdge> interior_edges(const Vertices& V, const Triangles& F,
                                         const VertexTriangles& vt);

// The interior edges of each triangle, ascending edge id, −1 where a side is a boundary.
std::vector<std::array<int, 3>> triangle_edges(const std::vector<InteriorEdge>& edges,
                                               Eigen::Index num_triangles);

// G (3m × n) = grad(V, F).
SparseMatrix assemble_gradient(const Triangles& F, const TriangleGradients& grads,
                               const VertexTriangles& vt);

// Gᵀ A (n × 3m), A = diag(a_l ⊗ 1₃).
SparseMatrix assemble_gta(const Triangles& F, const TriangleGradients& grads,
                          const Eigen::VectorXd& areas, int n);

// L = Gᵀ A G (n × n) with exact zeros dropped, as (GtA · G).pruned(0, 0).
SparseMatrix assemble_laplacian(const Triangles& F, const TriangleGradients& grads,
                                const Eigen::VectorXd& areas, const VertexTriangles& vt);

// Gᵀ D₃ᵀ B₃ D₃ (n × 3m), as SparseMatrix(gradient_jumps(G, edges)ᵀ) · B₃D₃.
SparseMatrix assemble_gtdbd(const Triangles& F, const TriangleGradients& grads,
                            const std::vector<InteriorEdge>& edges, int n);

// Reg = Gᵀ D₃ᵀ B₃ D₃ G (n × n), as GtDBD · G (explicit zeros kept). Column v is summed
// from the few columns of GtDBD that v's triangles own, computed on the fly: GtDBD itself
// (the largest operator, ≈ 36 nonzeros per vertex) is never stored.
SparseMatrix assemble_regularizer(const Triangles& F, const TriangleGradients& grads,
                                  const std::vector<InteriorEdge>& edges,
                                  const VertexTriangles& vt);

// The free rows of Gᵀ A and Gᵀ D₃ᵀ B₃ D₃ on the union of their patterns (row-major, the
// β > 0 right-hand side's two parts; the reference form of the weighted sum below): the same values as splitting `GtA + 0.0 * GtDBD` and
// `GtDBD + 0.0 * GtA`, built per free vertex without either n × 3m matrix. Row v holds the
// triangles around v and those across the far edge of each of them.
void assemble_wide_free_rows(const Triangles& F, const TriangleGradients& grads,
                             const Eigen::VectorXd& areas, const std::vector<InteriorEdge>& edges,
                             const VertexTriangles& vt, const std::vector<int>& free_,
                             SparseMatrixR& area, SparseMatrixR& reg);

// (Gᵀ W_β)_F = w_area · area + w_reg · reg of the two parts above, in one pass (the same
// bits as combining them value by value): a β > 0 system's right-hand side matrix, built
// for each β instead of keeping both parts (≈ 0.9 GB at 1M).
SparseMatrixR assemble_wide_free_rows(const Triangles& F, const TriangleGradients& grads,
                                      const Eigen::VectorXd& areas,
                                      const std::vector<InteriorEdge>& edges,
                                      const VertexTriangles& vt, const std::vector<int>& free_,
                                      double w_area, double w_reg);

}  // namespace hdeform

// Sparse × (n × 3) products of the move's hot path (SPEC.md §Solve: the right-hand side
// (Gᵀ W_β)_F g − K_FC x_C and the drag refinement's residual b − K_FF x), one pass over the
// matrix for all three columns, rows split in chunks on two threads (two_threads.h for_chunks).
//
// Why not Eigen's product: with a row-major g it runs on one thread, and with a column-major
// x it reads the matrix once per column (three passes). Bench: Phase/100000/rhs vs
// Phase/100000/rhs_fused and Phase/100000/residual vs residual_fused (bench/engine_bench.cpp;
// docs/benchmarks.md). Each row sums in Eigen's order (0 + a₀x₀ + a₁x₁ + …), so the results
// are bit-identical to Eigen's and do not depend on the thread count.
#pragma once

#include "engine/mesh/mesh.h"
#include "engine/operators/operators.h"

namespace hdeform {

// Y = A·X. A row-major (rows × c), X c × 3 row-major (the guidance field's layout).
// Y is resized to rows × 3 (no allocation once sized).
void sparse_times3(const SparseMatrixR& A, const GuidanceField& X, Eigen::MatrixXd& Y);

// Y = B − K·X for a symmetric column-major K (n × n: its columns are its rows), X and B n × 3.
// Y is resized to n × 3 (no allocation once sized); Y must not alias X. The same bits for
// either layout of Y.
void symmetric_residual3(const SparseMatrix& K, const Eigen::MatrixXd& X,
                         const Eigen::MatrixXd& B, Eigen::MatrixXd& Y);
void symmetric_residual3(const SparseMatrix& K, const Eigen::MatrixXd& X,
                         const Eigen::MatrixXd& B, Rows3& Y);

}  // namespace hdeform

// Harmonic basis fields (SPEC.md §Harmonic guidance field, decision "Speed"; thesis §6.5).
#pragma once

#include "engine/solve/solver.h"

#include <vector>

namespace hdeform {

// Φ (n × k): column j is 1 on region j+1, 0 on every other constrained vertex, and
// harmonic (L Φ = 0) on the free vertices. `region_of[v]`: −1 free, 0 fixed, j+1 handle j.
// `L_FF` must be the factorization of the free block of L; `free_`/`constrained` list the
// vertex ids of each block and `block_index` each vertex's position within its block.
Eigen::MatrixXd harmonic_basis(const SparseMatrix& L, const Factorization& L_FF,
                               const std::vector<int>& free_, const std::vector<int>& constrained,
                               const std::vector<int>& block_index,
                               const std::vector<int>& region_of, int num_handles);

}  // namespace hdeform

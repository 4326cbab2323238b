// The K_FF solve of SPEC.md §Solve (three right-hand sides, x/y/z) done by hand over
// CHOLMOD's own supernodal LLᵀ factor, instead of cholmod_solve (issue 10, item 1).
//
// Why: cholmod_solve spends ≈ 45 % of a 3-column solve in OpenBLAS copying each
// supernode's block into its own layout before tiny GEMM/TRSM calls, plus a lock per call.
// Here the three right-hand sides are interleaved (row-major n×3) so every factor entry
// read updates three contiguous values, the fill-reducing permutation is folded into the
// packing and unpacking, and nothing is allocated per call.
//
// Preconditions (checked by supernodal_solvable(); supernodal_solve3 assumes them):
//   L is a numeric supernodal LLᵀ factor of A (P A Pᵀ = L Lᵀ): L->is_super, L->is_ll,
//   L->xtype == CHOLMOD_REAL, L->dtype == CHOLMOD_DOUBLE, L->itype == CHOLMOD_INT (the
//   `cholmod_` int interface Eigen's CholmodSupport uses), L->Perm present.
// The factor is only read: any number of threads may solve with one factor at once, each
// with its own workspace.
#pragma once

#include <cholmod.h>

#include <cstddef>
#include <vector>

namespace hdeform {

// Scratch memory of one solver thread: the interleaved n×3 work array. It grows to the
// largest n it has seen and never shrinks, so reusing one workspace makes every call after
// the first allocation-free (across factors of any size up to that n).
class SupernodalWorkspace {
 public:
  void reserve(std::size_t n, std::size_t below_rows = 0) {
    if (y_.size() < 3 * n) y_.resize(3 * n);
    if (w_.size() < 3 * below_rows) w_.resize(3 * below_rows);
  }
  double* data() { return y_.data(); }
  double* below() { return w_.data(); }
  // Supernodes with at least this many columns go through BLAS (dtrsm + dgemm); the
  // others through the in-house loops. 0 = never BLAS, the default: no cutoff measured
  // faster (supernodal_solve.cpp cites the numbers).
  int blas_min_cols = 0;
  std::size_t capacity_rows() const { return y_.size() / 3; }

 private:
  std::vector<double> y_;
  std::vector<double> w_;  // 3 × (rows below a supernode's diagonal block), BLAS path only
};

// True when L satisfies the preconditions above (a null L is not solvable).
bool supernodal_solvable(const cholmod_factor* L);

// X = A⁻¹ B for three right-hand sides, A = Pᵀ L Lᵀ P. B and X are column-major n×3 with
// leading dimensions ldb, ldx ≥ n (Eigen's MatrixXd: ld = rows); X may alias B. n = L->n;
// n = 0 is a no-op. Grows `ws` if it is too small (only then does it allocate).
void supernodal_solve3(const cholmod_factor& L, const double* B, std::ptrdiff_t ldb, double* X,
                       std::ptrdiff_t ldx, SupernodalWorkspace& ws);

}  // namespace hdeform

// The K_FF solve of SPEC.md §Solve (three right-hand sides, x/y/z) done by hand over
// CHOLMOD's own supernodal LLᵀ factor, instead of cholmod_solve.
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

// Scratch memory of one solve call: the interleaved n×3 work array, followed (scheduled
// solves) by the parts' 3 × top_rows() update buffers; the threads of one call write
// disjoint regions of it. It grows to the largest size it has seen and never shrinks, so
// reusing one workspace makes every call after the first allocation-free (across factors
// of any size up to that).
class SupernodalWorkspace {
 public:
  void reserve(std::size_t n) {
    if (y_.size() < 3 * n) y_.resize(3 * n);
  }
  double* data() { return y_.data(); }
  std::size_t capacity_rows() const { return y_.size() / 3; }

 private:
  std::vector<double> y_;
};

// Where an n×3 dense block keeps entry (r, c): data[r * row + c * col].
struct Stride3 {
  std::ptrdiff_t row, col;
  static Stride3 columns(std::ptrdiff_t ld) { return {1, ld}; }  // column-major, ld ≥ n
  static constexpr Stride3 rows() { return {3, 1}; }              // row-major, interleaved
};

// A split of the supernodal elimination tree (parent of s = the supernode holding s's first
// off-diagonal row), built once per factor for two threads: up to kMaxParts "parts", each a
// set of disjoint subtrees, and the "top", every other supernode (the ancestors of the
// parts). Forward: the parts, then the top; backward: the top, then the parts. The parts
// are claimed, heaviest first, by whichever thread is free (a preempted thread does not
// hold the other up). Each part scatters its updates to top rows into its own buffer,
// which the top adds in part order, so the result does not depend on the number of
// threads nor on which thread ran which part. A default-constructed schedule (or one whose
// factor was too small or too unbalanced to split) solves sequentially, in supernode order.
class SupernodalSchedule {
 public:
  static constexpr int kMaxParts = 8;
  SupernodalSchedule() = default;
  // Precondition: supernodal_solvable(&L). Factors with fewer than min_rows rows are not
  // split, nor are those whose best split leaves a two-thread critical path above 80 % of
  // the work.
  explicit SupernodalSchedule(const cholmod_factor& L, std::size_t min_rows = 20000);

  bool split() const { return !parts_.empty(); }
  int parts() const { return static_cast<int>(parts_.size()); }
  // Rows belonging to top supernodes (each part's buffer holds 3 per row).
  int top_rows() const { return static_cast<int>(top_cols_.size()); }
  // Factor entries of part i < parts(), or of the top for i = parts(). Precondition: split().
  double work(int i) const { return work_[static_cast<std::size_t>(i)]; }
  // Factor entries on the two-thread critical path (parts list-scheduled, then the top).
  double critical_path() const { return critical_; }
  std::size_t memory_bytes() const;

 private:
  template <class T>
  friend void supernodal_solve3(const cholmod_factor&, const T*, const SupernodalSchedule&,
                                const double*, Stride3, double*, Stride3, SupernodalWorkspace&,
                                int);
  std::vector<std::vector<int>> parts_;  // supernodes of each part, ascending
  std::vector<int> top_;                 // the top's supernodes, ascending
  std::vector<int> rows_;      // L->s with the parts' top rows renumbered into their buffers
  std::vector<int> top_cols_;  // the factor column of each top row (buffer order)
  std::vector<double> work_;   // parts…, top
  double critical_ = 0;
};

// True when L satisfies the preconditions above (a null L is not solvable).
bool supernodal_solvable(const cholmod_factor* L);

// X = A⁻¹ B for three right-hand sides, A = Pᵀ L Lᵀ P. B and X are column-major n×3 with
// leading dimensions ldb, ldx ≥ n (Eigen's MatrixXd: ld = rows); X may alias B. n = L->n;
// n = 0 is a no-op. Grows `ws` if it is too small (only then does it allocate).
void supernodal_solve3(const cholmod_factor& L, const double* B, std::ptrdiff_t ldb, double* X,
                       std::ptrdiff_t ldx, SupernodalWorkspace& ws);

// The same, scheduled, with the factor's values read from Lx as T (double: L.x itself;
// float: a copy of L.x's L.xsize values rounded to float, half the bytes). Accumulation is
// in double either way. `sched` must be default-constructed or built from L. threads ∈
// {1, 2}: 2 runs a split schedule on the caller and the process's one helper thread
// (started on first use; a call that finds it busy with another solve runs alone); the
// result is bitwise the same for both. B and X in any layout (`sb`, `sx`): a row-major B
// is read one row (24 bytes) per permuted index instead of three scattered doubles.
template <class T>
void supernodal_solve3(const cholmod_factor& L, const T* Lx, const SupernodalSchedule& sched,
                       const double* B, Stride3 sb, double* X, Stride3 sx,
                       SupernodalWorkspace& ws, int threads);

// L.x rounded to float (L.xsize values). Precondition: supernodal_solvable(&L).
std::vector<float> factor_values_float(const cholmod_factor& L);

}  // namespace hdeform

// The numeric factorization of K_FF (SPEC.md §Solve) over CHOLMOD's own supernodal symbolic
// analysis, on two cores: a β change costs this factorization and nothing else.
//
// Why not cholmod_factorize: CHOLMOD 3 (Debian 12) factors the supernodes one after another
// on one core; a β change at 100K is ≈ 3 GFlop of it. The supernodal elimination tree's
// parts (supernodal_tree.h) are independent, so two threads factor them side by side; then
// the top (their ancestors), one supernode after another, each big one by both threads (its
// columns in two halves, then a blocked dpotrf/dtrsm/dsyrk of its panel in halves). The
// arithmetic is CHOLMOD's left-looking supernodal algorithm (t_cholmod_super_numeric): each
// supernode gathers its columns of P A Pᵀ, subtracts each descendant's update (dsyrk + dgemm,
// or the kernel's own loop for small ones, scattered through a relative map), then dpotrf on
// its diagonal block and dtrsm below it. Every split is fixed by the plan, so the values do
// not depend on the number of threads nor on which thread ran which part (they differ from
// CHOLMOD's in the last bits: the order of the sums differs).
// Measured (bench Factorize/100000, docs/benchmarks.md "Two-core factorization"): 2.6–3×
// faster than cholmod_factorize on one core at β = 0.5 on two threads.
//
// Preconditions: L is a supernodal factor (int indices) from CHOLMOD's analysis of A's
// pattern with L.Perm, L.x allocated for L.xsize doubles (cholmod_change_factor to numeric
// supernodal LLᵀ); A is square with stype ≠ 0 (its lower triangle for stype < 0, upper for
// stype > 0, as CHOLMOD reads it), real double, int indices.
#pragma once

#include "engine/solve/supernodal_tree.h"

#include <cholmod.h>

#include <cstddef>
#include <vector>

namespace hdeform {

// What a factorization of one symbolic analysis needs besides the values, built once per
// analysis: the tree split by floating-point work, the supernode of every column, and the
// sizes of the per-thread scratch.
class SupernodalFactorPlan {
 public:
  // A top supernode with at least this much work (flop) is factored by both threads: below
  // it, the barriers between them cost more than they save.
  static constexpr double kTwoLaneFlops = 4e6;
  SupernodalFactorPlan() = default;
  // Factors with fewer than min_rows columns are factored on one thread.
  explicit SupernodalFactorPlan(const cholmod_factor& L, std::size_t min_rows = 20000);
  // Floating-point operations of one factorization (dsyrk/dgemm updates, dpotrf, dtrsm).
  double flops() const { return flops_; }
  const TreeSplit& split() const { return split_; }
  // The top's supernodes factored by both threads, ascending.
  const std::vector<int>& two_lane() const { return two_lane_; }
  // Descendant updates of at most this many multiply-adds (ndcol × ndrow1 × ndrow2) run in
  // the kernel's own loop instead of dsyrk + dgemm (bench FactorizeCutoff measures it).
  static constexpr double kSmallUpdate = 16384;
  double small_update() const { return small_update_; }
  void set_small_update(double multiply_adds) { small_update_ = multiply_adds; }
  std::size_t memory_bytes() const;

 private:
  friend int supernodal_factorize(cholmod_factor&, const cholmod_sparse&,
                                  const SupernodalFactorPlan&, int);
  TreeSplit split_;
  std::vector<int> super_of_;
  std::vector<int> part_of_;  // the part of each supernode, −1 for the top
  std::size_t max_update_ = 0;  // largest descendant update (ndrow2 × ndrow1)
  std::size_t max_rows_ = 0;    // most rows of a supernode
  std::vector<int> two_lane_;   // the top's supernodes factored by both threads, ascending
  double flops_ = 0;
  double small_update_ = kSmallUpdate;
};

// Fills L.x with the supernodal Cholesky factor of P A Pᵀ (P from L.Perm). threads ∈ {1, 2}
// (2 uses the process's helper thread when it is free; the same bits either way, for one
// OpenBLAS thread setting: the service runs OpenBLAS on one thread, worker_pool.cpp). Returns
// −1 on success, else a column (in L's order) whose pivot is not positive (the first one on
// one thread): A is not positive definite, and L.x holds no factor. Sets L.minor as CHOLMOD
// does (n on success). Throws std::logic_error if A has an entry outside L's pattern.
int supernodal_factorize(cholmod_factor& L, const cholmod_sparse& A,
                         const SupernodalFactorPlan& plan, int threads = 2);

}  // namespace hdeform

// The CPU implementation of the solver seam (solver.h): CHOLMOD's METIS ordering and
// symbolic analysis through Eigen's CholmodSupport, the numeric factorization by
// supernodal_factorize on two threads, the fused solves of supernodal_solve3. The symbolic
// analysis is shareable across β (SPEC.md §Solve).
#pragma once

#include "engine/operators/operators.h"
#include "engine/solve/solver.h"
#include "engine/solve/supernodal_factorize.h"
#include "engine/solve/supernodal_solve.h"

#include <Eigen/CholmodSupport>

#include <atomic>
#include <memory>
#include <mutex>
#include <vector>

namespace hdeform {

// Eigen's CholmodSupernodalLLT plus one capability it lacks: starting a numeric
// factorization from another object's symbolic analysis (cholmod_copy_factor), so a β
// change costs one numeric factorization and never a new METIS analysis.
class CholmodLLT : public Eigen::CholmodBase<SparseMatrix, Eigen::Lower, CholmodLLT> {
  using Base = Eigen::CholmodBase<SparseMatrix, Eigen::Lower, CholmodLLT>;

 public:
  CholmodLLT();
  // Adopts a copy of `other`'s factor, which must be a symbolic analysis of the same
  // pattern (no numeric values: copying those would cost as much as reading the factor).
  void adopt_analysis(const CholmodLLT& other);
  // Symbolic analysis with a given fill-reducing permutation (perm[k] = the row eliminated
  // k-th; CHOLMOD still postorders it) instead of a METIS call: vertex_ordering.h.
  void analyze_given(const SparseMatrix& A, const std::vector<int>& perm);
  // Numeric factorization of A (same pattern as the analysis) by supernodal_factorize on
  // `threads` threads instead of cholmod_factorize; info() reports NumericalIssue when A is
  // not positive definite.
  void factorize_supernodal(const SparseMatrix& A, const SupernodalFactorPlan& plan,
                            int threads = 2);
  // Nonzeros stored in the factor L.
  std::size_t factor_nnz() const;
  // X = A⁻¹ B with a CHOLMOD workspace of the caller's own: the factor is only read, so
  // several threads may solve with one factorization at once (Eigen's solve() shares the
  // object's workspace).
  Eigen::MatrixXd solve_concurrently(const Eigen::MatrixXd& B) const;
  // CHOLMOD's factor (null before analysis), for solve kernels that read it directly.
  const cholmod_factor* factor() const { return m_cholmodFactor; }

 private:
  using Base::m_cholmod;
  using Base::m_cholmodFactor;
};

// One factorization of K_FF, symmetric positive definite. solve() is thread-safe.
class SupernodalFactorization final : public Factorization {
 public:
  // Analyse and factorize. Throws InvalidInput if K_FF is not positive definite
  // (the constraint set leaves a part of the mesh unconstrained). A 0×0 K_FF (no free
  // vertex) is valid: nothing is factored and solve() returns an empty matrix.
  // keep_analysis: keep a copy of the symbolic analysis (the factor's integer structure) so
  // later β can start from it; a factorization no other one will seed passes false.
  // order: a fill-reducing permutation of K_FF's rows (restrict_order of the mesh's
  // nested dissection); null runs METIS on K_FF itself.
  explicit SupernodalFactorization(const SparseMatrix& K_FF, bool keep_analysis = true,
                                   const std::vector<int>* order = nullptr);
  // Numeric factorization of K_FF reusing `analysis`'s symbolic factor (same pattern);
  // `analysis` must have been built with keep_analysis.
  SupernodalFactorization(const SupernodalFactorization& analysis, const SparseMatrix& K_FF);
  // The same through the seam: `this` must have been built with keep_analysis.
  std::shared_ptr<const Factorization> refactor(const SparseMatrix& K_FF) const override;

  // X = K_FF⁻¹ B for n×3 column-major B and X (ld = size()); X may alias B. threads ∈
  // {1, 2}, the same bits for both: the factor's schedule (built at construction) runs on
  // the caller alone or with supernodal_solve3's helper thread. The workspace is
  // thread_local: no allocation after the first call on a thread (for this size or
  // smaller), except that the first float32 call on this factorization builds its float
  // copy of the factor (once, thread-safe; counted in memory_bytes()).
  void solve3(const double* B, double* X, SolvePrecision precision = SolvePrecision::float64,
              int threads = 2) const override;
  // The same for n×3 row-major B and X (three doubles a row): the drag refinement's layout,
  // read and written a row at a time through the permutation. The same bits as solve3.
  void solve3_rows(const double* B, double* X,
                   SolvePrecision precision = SolvePrecision::float64,
                   int threads = 2) const override;
  // X = K_FF⁻¹ B. Three columns: solve3 (float64, two threads); other column counts
  // through cholmod_solve.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const override;
  // X = K_FF⁻¹ B through cholmod_solve always (the reference and the fallback).
  Eigen::MatrixXd solve_cholmod(const Eigen::MatrixXd& B) const;
  // CHOLMOD's factor of K_FF (null when size() == 0).
  const cholmod_factor* factor() const { return size_ == 0 ? nullptr : llt_.factor(); }
  int size() const override { return size_; }
  const SupernodalSchedule& schedule() const { return schedule_; }
  std::size_t memory_bytes() const override;
  const Timings& timings() const override { return timings_; }

 private:
  void check(const char* what) const;
  void factorize_numeric(const SparseMatrix& K_FF);
  void finish();  // after the numeric factorization: the solve schedule
  const float* values_float() const;
  void solve3(const double* B, Stride3 sb, double* X, Stride3 sx, SolvePrecision precision,
              int threads) const;
  CholmodLLT llt_;
  CholmodLLT analysis_;  // the symbolic analysis alone, kept to seed later β; never modified
  int size_ = 0;
  // The factorization's tree split, built from the symbolic analysis and shared with every
  // Factorization seeded by this one (same analysis).
  std::shared_ptr<const SupernodalFactorPlan> plan_;
  bool plan_owner_ = false;  // memory_bytes() counts the plan once, in its builder
  SupernodalSchedule schedule_;
  Timings timings_;
  mutable std::once_flag float_once_;
  mutable std::vector<float> float_values_;  // L->x as float, built on the first float32 solve
  mutable std::atomic<bool> float_ready_{false};
};

}  // namespace hdeform

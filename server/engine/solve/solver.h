// The solver seam (SPEC.md §Solve): the deformation factors K_FF and solves with it through
// this interface only. SupernodalFactorization (supernodal_factorization.h, CHOLMOD's
// analysis + the supernodal CPU kernels) is the implementation factorize() returns; another
// one (a GPU solver, CHOLMOD's own factorize/solve for comparison) is added beside it
// without touching engine/deform.
#pragma once

#include "engine/operators/operators.h"

#include <Eigen/Dense>

#include <cstddef>
#include <memory>
#include <vector>

namespace hdeform {

// float32: the factor's values are read as float (half the bytes), accumulation in double.
enum class SolvePrecision { float64, float32 };

// One factorization of a symmetric positive definite K_FF (n × n). Immutable once built;
// every const method may be called from several threads at once.
class Factorization {
 public:
  // Where the construction's time went (ms, wall): ordering + symbolic analysis (the copy's
  // time when an analysis was reused), the numeric factorization, the solve schedule.
  struct Timings {
    double analysis_ms = 0, factor_ms = 0, schedule_ms = 0;
  };

  virtual ~Factorization() = default;
  // n, the number of free vertices (0: nothing was factored, every solve is empty).
  virtual int size() const = 0;
  // Bytes held (factor values and indices, schedules, copies), what a cache charges.
  virtual std::size_t memory_bytes() const = 0;
  virtual const Timings& timings() const = 0;
  // X = K_FF⁻¹ B for n×3 column-major B and X (ld = n); X may alias B. threads ∈ {1, 2},
  // the same bits for both.
  virtual void solve3(const double* B, double* X,
                      SolvePrecision precision = SolvePrecision::float64,
                      int threads = 2) const = 0;
  // The same for n×3 row-major B and X (three doubles a row); the same bits as solve3.
  virtual void solve3_rows(const double* B, double* X,
                           SolvePrecision precision = SolvePrecision::float64,
                           int threads = 2) const = 0;
  // X = K_FF⁻¹ B for any number of columns.
  virtual Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const = 0;
  // A factorization of K_FF, which has this one's sparsity pattern (another β), reusing
  // this one's symbolic analysis; this one must have been built with keep_analysis.
  virtual std::shared_ptr<const Factorization> refactor(const SparseMatrix& K_FF) const = 0;
};

struct FactorizeOptions {
  // Keep the symbolic analysis so refactor() can start from it; a factorization no other
  // one will seed passes false (it saves the analysis's integer copy).
  bool keep_analysis = true;
  // A fill-reducing permutation of K_FF's rows (restrict_order of the mesh's nested
  // dissection, vertex_ordering.h); null orders K_FF itself (METIS).
  const std::vector<int>* order = nullptr;
};

// Analyses and factors K_FF with the default implementation (SupernodalFactorization).
// Throws InvalidInput if K_FF is not positive definite (some part of the mesh has no
// constrained vertex). A 0×0 K_FF (no free vertex) is valid.
std::shared_ptr<const Factorization> factorize(const SparseMatrix& K_FF,
                                               const FactorizeOptions& options = {});

}  // namespace hdeform

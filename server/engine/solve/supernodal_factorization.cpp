#include "engine/solve/supernodal_factorization.h"

#include "engine/mesh/mesh.h"
#include "engine/runtime/elapsed_ms.h"
#include "engine/runtime/serial_openmp.h"
#include "engine/solve/supernodal_solve.h"

#include <chrono>
#include <stdexcept>
#include <string>

namespace hdeform {

CholmodLLT::CholmodLLT() {
  m_cholmod.final_asis = 1;
  m_cholmod.supernodal = CHOLMOD_SUPERNODAL;
  // METIS alone: the smallest factors on these meshes (measured when the toolchain was set
  // up: 3.9M vs 4.8M nnz with AMD at 100K, β = 0; 9.9M vs 16.4M at β = 0.5).
  m_cholmod.nmethods = 1;
  m_cholmod.method[0].ordering = CHOLMOD_METIS;
  m_cholmod.postorder = 1;
}

void CholmodLLT::adopt_analysis(const CholmodLLT& other) {
  if (m_cholmodFactor) cholmod_free_factor(&m_cholmodFactor, &m_cholmod);
  m_cholmodFactor = cholmod_copy_factor(other.m_cholmodFactor, &m_cholmod);
  this->m_isInitialized = true;
  this->m_info = Eigen::Success;
  this->m_analysisIsOk = true;
  this->m_factorizationIsOk = false;
}

void CholmodLLT::analyze_given(const SparseMatrix& A, const std::vector<int>& perm) {
  if (perm.size() != static_cast<std::size_t>(A.rows()))
    throw std::logic_error("CholmodLLT: the permutation does not match the matrix");
  if (m_cholmodFactor) cholmod_free_factor(&m_cholmodFactor, &m_cholmod);
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  m_cholmod.method[0].ordering = CHOLMOD_GIVEN;
  m_cholmodFactor = cholmod_analyze_p(&a, const_cast<int*>(perm.data()), nullptr, 0, &m_cholmod);
  m_cholmod.method[0].ordering = CHOLMOD_METIS;
  this->m_isInitialized = true;
  this->m_info = m_cholmodFactor ? Eigen::Success : Eigen::NumericalIssue;
  this->m_analysisIsOk = m_cholmodFactor != nullptr;
  this->m_factorizationIsOk = false;
}

Eigen::MatrixXd CholmodLLT::solve_concurrently(const Eigen::MatrixXd& B) const {
  if (!m_cholmodFactor) throw std::logic_error("CholmodLLT: solve before factorization");
  cholmod_common common;
  cholmod_start(&common);
  common.final_asis = m_cholmod.final_asis;
  cholmod_dense b;
  b.nrow = static_cast<std::size_t>(B.rows());
  b.ncol = static_cast<std::size_t>(B.cols());
  b.nzmax = b.nrow * b.ncol;
  b.d = b.nrow;
  b.x = const_cast<double*>(B.data());  // cholmod_solve only reads B
  b.z = nullptr;
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* x = [&] {
    SerialOpenMP serial;  // CHOLMOD's own loops: four threads on two cores (serial_openmp.h)
    return cholmod_solve(CHOLMOD_A, m_cholmodFactor, &b, &common);
  }();
  if (!x) {
    cholmod_finish(&common);
    throw std::runtime_error("CHOLMOD solve failed (status " + std::to_string(common.status) + ")");
  }
  Eigen::MatrixXd X = Eigen::Map<const Eigen::MatrixXd>(static_cast<const double*>(x->x),
                                                       B.rows(), B.cols());
  cholmod_free_dense(&x, &common);
  cholmod_finish(&common);
  return X;
}

void CholmodLLT::factorize_supernodal(const SparseMatrix& A, const SupernodalFactorPlan& plan,
                                      int threads) {
  this->m_info = Eigen::NumericalIssue;
  this->m_factorizationIsOk = false;
  if (!m_cholmodFactor || !m_cholmodFactor->is_super) return;
  // The symbolic factor gets its values array (L.xsize doubles; a numeric one keeps its own).
  if (!cholmod_change_factor(CHOLMOD_REAL, 1, 1, 1, 1, m_cholmodFactor, &m_cholmod)) return;
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  if (supernodal_factorize(*m_cholmodFactor, a, plan, threads) >= 0) return;
  this->m_info = Eigen::Success;
  this->m_factorizationIsOk = true;
}

std::size_t CholmodLLT::factor_nnz() const {
  if (!m_cholmodFactor) return 0;
  if (m_cholmodFactor->is_super) return static_cast<std::size_t>(m_cholmodFactor->xsize);
  return static_cast<std::size_t>(m_cholmodFactor->nzmax);
}

// An empty K_FF (every vertex constrained) is legal: the answer is the targets. CHOLMOD
// is never called with it (it returns a null factor that a later solve dereferences).

SupernodalFactorization::SupernodalFactorization(const SparseMatrix& K_FF, bool keep_analysis,
                                                 const std::vector<int>* order)
    : size_(static_cast<int>(K_FF.rows())) {
  if (size_ == 0) return;
  SerialOpenMP serial;  // CHOLMOD's own loops: four threads on two cores (serial_openmp.h)
  const auto t0 = std::chrono::steady_clock::now();
  if (order)
    llt_.analyze_given(K_FF, *order);
  else
    llt_.analyzePattern(K_FF);
  check("analysis");
  // Before the numeric factorization fills in values.
  if (keep_analysis) analysis_.adopt_analysis(llt_);
  if (llt_.factor()->is_super)
    plan_ = std::make_shared<const SupernodalFactorPlan>(*llt_.factor());
  plan_owner_ = plan_ != nullptr;
  timings_.analysis_ms = elapsed_ms(t0);
  factorize_numeric(K_FF);
  finish();
}

SupernodalFactorization::SupernodalFactorization(const SupernodalFactorization& analysis,
                                                 const SparseMatrix& K_FF)
    : size_(static_cast<int>(K_FF.rows())) {
  if (size_ == 0) return;
  SerialOpenMP serial;  // as above
  const auto t0 = std::chrono::steady_clock::now();
  if (!analysis.analysis_.factor())
    throw std::logic_error("SupernodalFactorization: the analysis was built without keep_analysis");
  llt_.adopt_analysis(analysis.analysis_);  // analysis_ is immutable: no lock needed
  plan_ = analysis.plan_;
  timings_.analysis_ms = elapsed_ms(t0);  // the copy of the symbolic factor
  factorize_numeric(K_FF);
  finish();
}

std::shared_ptr<const Factorization> SupernodalFactorization::refactor(
    const SparseMatrix& K_FF) const {
  return std::make_shared<const SupernodalFactorization>(*this, K_FF);
}

std::shared_ptr<const Factorization> factorize(const SparseMatrix& K_FF,
                                               const FactorizeOptions& options) {
  return std::make_shared<const SupernodalFactorization>(K_FF, options.keep_analysis,
                                                         options.order);
}

void SupernodalFactorization::factorize_numeric(const SparseMatrix& K_FF) {
  const auto t0 = std::chrono::steady_clock::now();
  if (plan_)
    llt_.factorize_supernodal(K_FF, *plan_);
  else
    llt_.factorize(K_FF);  // CHOLMOD chose a simplicial factor (tiny systems)
  check("factorization");
  timings_.factor_ms = elapsed_ms(t0);
}

void SupernodalFactorization::finish() {
  const auto t0 = std::chrono::steady_clock::now();
  if (supernodal_solvable(llt_.factor())) schedule_ = SupernodalSchedule(*llt_.factor());
  timings_.schedule_ms = elapsed_ms(t0);
}

const float* SupernodalFactorization::values_float() const {
  std::call_once(float_once_, [this] {
    float_values_ = factor_values_float(*llt_.factor());
    float_ready_.store(true, std::memory_order_release);
  });
  return float_values_.data();
}

void SupernodalFactorization::check(const char* what) const {
  if (llt_.info() != Eigen::Success)
    throw InvalidInput(std::string("the constrained system is singular (CHOLMOD ") + what +
                       " failed): some part of the mesh has no constrained vertex");
}

void SupernodalFactorization::solve3(const double* B, double* X, SolvePrecision precision,
                           int threads) const {
  solve3(B, Stride3::columns(size_), X, Stride3::columns(size_), precision, threads);
}

void SupernodalFactorization::solve3_rows(const double* B, double* X, SolvePrecision precision,
                                int threads) const {
  solve3(B, Stride3::rows(), X, Stride3::rows(), precision, threads);
}

void SupernodalFactorization::solve3(const double* B, Stride3 sb, double* X, Stride3 sx,
                           SolvePrecision precision, int threads) const {
  if (size_ == 0) return;
  const cholmod_factor* L = llt_.factor();
  if (!supernodal_solvable(L)) {  // not with this CholmodLLT; allocates
    using Strided = Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>;
    const Eigen::MatrixXd Xc = llt_.solve_concurrently(
        Eigen::Map<const Eigen::MatrixXd, 0, Strided>(B, size_, 3, Strided(sb.col, sb.row)));
    Eigen::Map<Eigen::MatrixXd, 0, Strided>(X, size_, 3, Strided(sx.col, sx.row)) = Xc;
    return;
  }
  // One workspace per thread: solves run concurrently on one factor from several threads,
  // and the workspace grows to the largest K_FF the thread has solved.
  thread_local SupernodalWorkspace ws;
  if (precision == SolvePrecision::float32)
    supernodal_solve3(*L, values_float(), schedule_, B, sb, X, sx, ws, threads);
  else
    supernodal_solve3(*L, static_cast<const double*>(L->x), schedule_, B, sb, X, sx, ws, threads);
}

Eigen::MatrixXd SupernodalFactorization::solve(const Eigen::MatrixXd& B) const {
  if (size_ == 0 || B.rows() == 0) return Eigen::MatrixXd(B.rows(), B.cols());
  if (B.cols() == 3 && B.rows() == size_) {
    Eigen::MatrixXd X(B.rows(), 3);
    solve3(B.data(), X.data());
    return X;
  }
  return llt_.solve_concurrently(B);
}

Eigen::MatrixXd SupernodalFactorization::solve_cholmod(const Eigen::MatrixXd& B) const {
  if (size_ == 0 || B.rows() == 0) return Eigen::MatrixXd(B.rows(), B.cols());
  return llt_.solve_concurrently(B);
}

std::size_t SupernodalFactorization::memory_bytes() const {
  // Values (double) plus row indices (int) of the factor, roughly.
  // The symbolic copy holds row indices only.
  const std::size_t floats =
      float_ready_.load(std::memory_order_acquire) ? float_values_.size() * sizeof(float) : 0;
  return llt_.factor_nnz() * (sizeof(double) + sizeof(int)) + analysis_.factor_nnz() * sizeof(int) +
         schedule_.memory_bytes() + floats + sizeof(*this) +
         (plan_owner_ ? plan_->memory_bytes() : 0);
}

}  // namespace hdeform

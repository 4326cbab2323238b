#include "engine/solve/vertex_ordering.h"

#include <Eigen/CholmodSupport>

#include <mutex>
#include <stdexcept>
#include <string>

namespace hdeform {

namespace {

// One cholmod_common for a call; METIS alone, as the factorizations use it (solver.cpp).
struct Common {
  cholmod_common c;
  Common() { cholmod_start(&c); }
  ~Common() { cholmod_finish(&c); }
  Common(const Common&) = delete;
  Common& operator=(const Common&) = delete;
};

// METIS 5.1 keeps its random generator in global state (GKlib's): one call at a time, so a
// mesh gets the same order whichever other meshes are being ordered meanwhile (the
// factorizations never call METIS: they are given these orders).
std::mutex metis_mutex;

std::vector<int> metis_order(cholmod_sparse* A, cholmod_common* c) {
  std::vector<int> order(A->nrow);
  if (order.empty()) return order;
  std::lock_guard lock(metis_mutex);
  // postorder 0: each constraint set's analysis postorders its own elimination tree.
  if (!cholmod_metis(A, nullptr, 0, /*postorder=*/0, order.data(), c))
    throw std::runtime_error("METIS ordering failed (CHOLMOD status " + std::to_string(c->status) +
                             ")");
  return order;
}

}  // namespace

std::vector<int> nested_dissection(const SparseMatrix& A) {
  Common common;
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  return metis_order(&a, &common.c);
}

std::vector<int> nested_dissection(const SparseMatrix& A, const SparseMatrix& B) {
  if (A.rows() != B.rows() || A.cols() != B.cols())
    throw std::logic_error("nested_dissection: the two patterns differ in size");
  Common common;
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  cholmod_sparse b = Eigen::viewAsCholmod(B.selfadjointView<Eigen::Lower>());
  double one[2] = {1, 0};
  // Pattern only (values = FALSE): the union costs integers, never a sum of values.
  cholmod_sparse* u = cholmod_add(&a, &b, one, one, /*values=*/0, /*sorted=*/1, &common.c);
  if (!u) throw std::runtime_error("CHOLMOD could not form the union pattern");
  try {
    auto order = metis_order(u, &common.c);
    cholmod_free_sparse(&u, &common.c);
    return order;
  } catch (...) {
    cholmod_free_sparse(&u, &common.c);
    throw;
  }
}

std::vector<int> restrict_order(const std::vector<int>& order, const std::vector<int>& free) {
  std::vector<int> index_of(order.size(), -1);
  for (std::size_t i = 0; i < free.size(); ++i) index_of.at(free[i]) = static_cast<int>(i);
  std::vector<int> perm;
  perm.reserve(free.size());
  for (int v : order)
    if (int& i = index_of.at(v); i >= 0) {
      perm.push_back(i);
      i = -1;  // a repeated vertex is not a permutation: caught by the size check below
    }
  if (perm.size() != free.size())
    throw std::logic_error("restrict_order: order is not a permutation of the vertices");
  return perm;
}

}  // namespace hdeform

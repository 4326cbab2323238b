#include "engine/deform/harmonic.h"

namespace hdeform {

Eigen::MatrixXd harmonic_basis(const SparseMatrix& L, const Factorization& L_FF,
                               const std::vector<int>& free_, const std::vector<int>& constrained,
                               const std::vector<int>& block_index,
                               const std::vector<int>& region_of, int num_handles) {
  const Eigen::Index n = L.rows(), k = num_handles;
  Eigen::MatrixXd Phi = Eigen::MatrixXd::Zero(n, k);
  for (int v : constrained)
    if (region_of[v] > 0) Phi(v, region_of[v] - 1) = 1.0;
  if (k == 0 || free_.empty()) return Phi;

  // Dirichlet problem: L_FF Φ_F = −L_FC Φ_C. L is symmetric, so walking column c of a
  // constrained vertex visits the entries L(r, c) of every row r.
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(free_.size()), k);
  for (int c : constrained) {
    const int j = region_of[c] - 1;
    if (j < 0) continue;
    for (SparseMatrix::InnerIterator it(L, c); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (region_of[r] < 0) rhs(block_index[r], j) -= it.value();
    }
  }
  const Eigen::MatrixXd Phi_F = L_FF.solve(rhs);
  for (std::size_t i = 0; i < free_.size(); ++i) Phi.row(free_[i]) = Phi_F.row(i);
  return Phi;
}

}  // namespace hdeform

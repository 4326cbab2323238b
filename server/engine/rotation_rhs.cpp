#include "rotation_rhs.h"

namespace hdeform {

void rotation_rhs(const SparseMatrixR& GtW_F, const Vertices& normals,
                  const Eigen::Vector3d& axis, const double* cs, Eigen::MatrixXd& rhs) {
  const Eigen::Index rows = GtW_F.rows();
  rhs.resize(rows, 3);
  const auto* outer = GtW_F.outerIndexPtr();
  const auto* inner = GtW_F.innerIndexPtr();
  const double* val = GtW_F.valuePtr();
  const auto* nnz = GtW_F.innerNonZeroPtr();  // null when compressed
  const double* N = normals.data();           // row-major m × 3
  const double k0 = axis.x(), k1 = axis.y(), k2 = axis.z();
  double* out = rhs.data();
#pragma omp parallel for schedule(static)
  for (Eigen::Index v = 0; v < rows; ++v) {
    double r0 = 0, r1 = 0, r2 = 0;
    // R_l Y_l a for the pending triangle l, added to r.
    auto add = [&](Eigen::Index l, double a0, double a1, double a2) {
      const double* n = N + 3 * l;
      const double na = n[0] * a0 + n[1] * a1 + n[2] * a2;
      const double b0 = a0 - na * n[0], b1 = a1 - na * n[1], b2 = a2 - na * n[2];  // Y_l a
      // Rodrigues: R b = c b + s (k × b) + (1 − c)(k·b) k
      const double c = cs[2 * l], s = cs[2 * l + 1];
      const double kb = (1 - c) * (k0 * b0 + k1 * b1 + k2 * b2);
      r0 += c * b0 + s * (k1 * b2 - k2 * b1) + kb * k0;
      r1 += c * b1 + s * (k2 * b0 - k0 * b2) + kb * k1;
      r2 += c * b2 + s * (k0 * b1 - k1 * b0) + kb * k2;
    };
    const auto begin = outer[v], end = nnz ? begin + nnz[v] : outer[v + 1];
    Eigen::Index pending = -1;
    double a[3] = {0, 0, 0};
    for (auto p = begin; p < end; ++p) {
      const Eigen::Index col = inner[p], l = col / 3;
      if (l != pending) {
        if (pending >= 0) add(pending, a[0], a[1], a[2]);
        pending = l;
        a[0] = a[1] = a[2] = 0;
      }
      a[col - 3 * l] = val[p];
    }
    if (pending >= 0) add(pending, a[0], a[1], a[2]);
    out[v] = r0;
    out[v + rows] = r1;
    out[v + 2 * rows] = r2;
  }
}

}  // namespace hdeform

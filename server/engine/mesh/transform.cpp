#include "engine/mesh/transform.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <cmath>
#include <cstdio>
#include <string>

namespace hdeform {

HandleTransform HandleTransform::from_matrix(const Eigen::Matrix4d& T,
                                             const Eigen::Vector3d& pivot) {
  if (!T.allFinite()) throw InvalidInput("transform matrix has non-finite entries");
  if (!T.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-12))
    throw InvalidInput("transform matrix: last row must be 0 0 0 1 (affine transforms only)");
  const Eigen::Matrix3d M = T.topLeftCorner<3, 3>();
  // Polar decomposition M = R S from the SVD M = U Σ Vᵀ: R = U Vᵀ, S = V Σ Vᵀ.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  // Judge by the singular values, not by det against ‖M‖³: a strong shear has det = 1
  // and is invertible, and "det = 1.000000" would explain nothing.
  const Eigen::Vector3d sv = svd.singularValues();  // descending
  char buf[200];
  if (M.determinant() < 0) {
    std::snprintf(buf, sizeof buf, "transform linear part is a reflection (det = %g < 0)",
                  M.determinant());
    throw InvalidInput(buf);
  }
  if (!(sv[2] > 1e-12 * sv[0])) {
    std::snprintf(buf, sizeof buf,
                  "transform linear part is singular: singular values %g, %g, %g (the smallest "
                  "must exceed 1e-12 x the largest)",
                  sv[0], sv[1], sv[2]);
    throw InvalidInput(buf);
  }
  const Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  HandleTransform h;
  h.pivot = pivot;
  h.rotation = Eigen::Quaterniond(R).normalized();
  h.stretch = svd.matrixV() * svd.singularValues().asDiagonal() * svd.matrixV().transpose();
  h.stretch = 0.5 * (h.stretch + h.stretch.transpose()).eval();
  // T x = M x + b = p + M (x − p) + t  ⇒  t = M p + b − p.
  h.translation = M * pivot + T.topRightCorner<3, 1>() - pivot;
  return h;
}

void HandleTransform::validate() const {
  if (pivot && !pivot->allFinite()) throw InvalidInput("handle pivot has non-finite coordinates");
  if (!rotation.coeffs().allFinite()) throw InvalidInput("handle rotation has non-finite numbers");
  if (std::abs(rotation.norm() - 1.0) > 1e-6)
    throw InvalidInput("handle rotation quaternion is not unit length (norm " +
                       std::to_string(rotation.norm()) + ")");
  if (!stretch.allFinite()) throw InvalidInput("handle scale has non-finite numbers");
  if (!stretch.isApprox(stretch.transpose(), 1e-9))
    throw InvalidInput("handle scale matrix is not symmetric");
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(stretch, Eigen::EigenvaluesOnly);
  if (!(eig.eigenvalues().minCoeff() > 0))
    throw InvalidInput("handle scale is not positive definite (smallest eigenvalue " +
                       std::to_string(eig.eigenvalues().minCoeff()) + ")");
  if (!translation.allFinite()) throw InvalidInput("handle translation has non-finite numbers");
}

}  // namespace hdeform

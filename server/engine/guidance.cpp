#include "guidance.h"

namespace hdeform {

void guidance_field(const Triangles& F, const Vertices& normals, const Eigen::MatrixXd& Phi,
                    std::span<const HandleTransform> transforms, Eigen::MatrixX3d& g,
                    std::vector<Eigen::Quaterniond>& R_l) {
  const Eigen::Index m = F.rows();
  const int k = static_cast<int>(transforms.size());
  g.resize(3 * m, 3);
  R_l.resize(static_cast<std::size_t>(m));

  std::vector<Eigen::Quaterniond> q(static_cast<std::size_t>(k));
  for (int j = 0; j < k; ++j) {
    q[j] = transforms[j].rotation.normalized();
    if (q[j].w() < 0) q[j].coeffs() *= -1.0;
  }
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();

  for (Eigen::Index l = 0; l < m; ++l) {
    Eigen::Quaterniond R;
    Eigen::Matrix3d S;
    if (k == 1) {
      const double h = (Phi(F(l, 0), 0) + Phi(F(l, 1), 0) + Phi(F(l, 2), 0)) / 3.0;
      R = Eigen::Quaterniond::Identity().slerp(h, q[0]);
      S = (1.0 - h) * I + h * transforms[0].stretch;
    } else {
      Eigen::Vector4d qc = Eigen::Vector4d::Zero();  // (x, y, z, w) as Eigen stores it
      S.setZero();
      double rest = 1.0;  // weight of the identity on F₀: 1 − Σ_j h_lj
      for (int j = 0; j < k; ++j) {
        const double h = (Phi(F(l, 0), j) + Phi(F(l, 1), j) + Phi(F(l, 2), j)) / 3.0;
        qc += h * q[j].coeffs();
        S += h * transforms[j].stretch;
        rest -= h;
      }
      qc[3] += rest;
      S += rest * I;
      R.coeffs() = qc.normalized();
    }
    R_l[l] = R;
    const Eigen::Matrix3d M = R.toRotationMatrix() * S;
    const Eigen::Vector3d n = normals.row(l).transpose();
    // g_l = Y_l Mᵀ with Y_l = I − n nᵀ (the rest gradient block, SPEC's check).
    g.middleRows<3>(3 * l) = M.transpose() - n * (M * n).transpose();
  }
}

}  // namespace hdeform

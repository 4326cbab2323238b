#include "engine/deform/guidance.h"

#include "engine/runtime/two_threads.h"
#include "engine/simd/cpu_features.h"
#include "engine/simd/guidance_rotation.h"

#include <algorithm>
#include <cmath>

namespace hdeform {

void guidance_field(const Triangles& F, const Vertices& normals, const Eigen::MatrixXd& Phi,
                    std::span<const HandleTransform> transforms, GuidanceField& g, Vertices* Rn,
                    GuidanceScratch& scratch) {
  const Eigen::Index m = F.rows();
  const Eigen::Index n = Phi.rows();
  const int k = static_cast<int>(transforms.size());
  g.resize(3 * m, 3);
  if (Rn) Rn->resize(m, 3);

  std::vector<Eigen::Quaterniond> q(static_cast<std::size_t>(k));
  for (int j = 0; j < k; ++j) {
    q[j] = transforms[j].rotation.normalized();
    if (q[j].w() < 0) q[j].coeffs() *= -1.0;
  }
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  // One handle: slerp(I, q, h) = (cos(hθ/2), sin(hθ/2) a) with q = (cos(θ/2), sin(θ/2) a).
  // With h the mean of three vertex values, e^{i h θ/2} is the product of the vertices'
  // e^{i φ_v θ/6}: one sincos per vertex instead of one per triangle (twice as many).
  double half_angle = 0;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
  bool stretched = false;
  std::complex<double>* turn = nullptr;
  if (k == 1) {
    const double s = q[0].vec().norm();
    if (s > 0) {
      half_angle = std::atan2(s, q[0].w());
      axis = q[0].vec() / s;
    }
    stretched = !transforms[0].stretch.isIdentity(0.0);
    scratch.turn.resize(static_cast<std::size_t>(n));
    turn = scratch.turn.data();
  }
  const double third = half_angle / 3.0;

  // g_l and R_l n_l of triangle l, the scalar way (any number of handles, stretch or not).
  auto triangle = [&](Eigen::Index l) {
    Eigen::Quaterniond R;
    Eigen::Matrix3d S;
    if (k == 1) {
      // Written out: std::complex's operator* calls __muldc3 (Annex G's inf/NaN cases).
      const std::complex<double> a = turn[F(l, 0)], b = turn[F(l, 1)], c = turn[F(l, 2)];
      const double re = a.real() * b.real() - a.imag() * b.imag();
      const double im = a.real() * b.imag() + a.imag() * b.real();
      R.w() = re * c.real() - im * c.imag();
      R.vec() = (re * c.imag() + im * c.real()) * axis;
      if (stretched) {
        const double h = (Phi(F(l, 0), 0) + Phi(F(l, 1), 0) + Phi(F(l, 2), 0)) / 3.0;
        S = (1.0 - h) * I + h * transforms[0].stretch;
      } else {
        S = I;
      }
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
    const Eigen::Matrix3d Rm = R.toRotationMatrix();
    const Eigen::Matrix3d M = stretched || k != 1 ? Eigen::Matrix3d(Rm * S) : Rm;
    const Eigen::Vector3d nl = normals.row(l).transpose();
    const Eigen::Vector3d Mn = M * nl;
    if (Rn) Rn->row(l) = (stretched || k != 1 ? Eigen::Vector3d(Rm * nl) : Mn).transpose();
    // g_l = Y_l Mᵀ with Y_l = I − n nᵀ (the rest gradient block, SPEC's check), written out
    // into g's row-major storage: Phase/100000/guidance 2.58 -> 2.42 ms against Eigen's
    // `g.middleRows<3>(3l) = Mᵀ − n (M n)ᵀ` (same run, interleaved).
    double* gl = g.data() + 9 * l;  // g is row-major: block l is 9 contiguous doubles
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) gl[3 * r + c] = M(c, r) - nl[r] * Mn[c];
  };
  // One handle without stretch: four triangles at a time where the CPU has AVX2 + FMA
  // (guidance_rotation.h); each chunk then does the few left of its own.
  const bool vector_isa = kernel_isa() == Isa::avx2;
  const bool vector_rotation = k == 1 && !stretched && vector_isa;
  double* rn = Rn ? Rn->data() : nullptr;

  // Chunks each, on the caller and the solve's helper thread (two_threads.h for_chunks).
  if (turn)
    for_chunks(n, [&](Eigen::Index v0, Eigen::Index v1, int) {
      if (vector_isa) return detail::vertex_turns_avx2(Phi.data(), v0, v1, third, turn);
      for (Eigen::Index v = v0; v < v1; ++v)
        turn[v] = {std::cos(Phi(v, 0) * third), std::sin(Phi(v, 0) * third)};
    });
  for_chunks(m, [&](Eigen::Index l0, Eigen::Index l1, int) {
    Eigen::Index l = l0;
    if (vector_rotation)
      l = detail::guidance_rotation_avx2(F.data(), normals.data(), turn, axis.data(), l0, l1,
                                         g.data(), rn);
    for (; l < l1; ++l) triangle(l);
  });
}

}  // namespace hdeform

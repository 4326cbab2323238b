// guidance.h against SPEC.md §Harmonic guidance field written out the plain way (Eigen's
// slerp per triangle, the quaternion average, g_l = Y_l M_lᵀ), on any Φ: the engine's one
// sincos per vertex (a product of three per-vertex turns) is the same field to rounding.
#include "each_isa.h"
#include "engine/deform/guidance.h"
#include "engine/simd/guidance_rotation.h"
#include "fixtures.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <limits>
#include <random>

namespace hdeform {
namespace {

GuidanceField reference(const Triangles& F, const Vertices& normals, const Eigen::MatrixXd& Phi,
                        std::span<const HandleTransform> t, std::vector<Eigen::Quaterniond>& R) {
  const Eigen::Index m = F.rows();
  const int k = static_cast<int>(t.size());
  GuidanceField g(3 * m, 3);
  R.resize(static_cast<std::size_t>(m));
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  for (Eigen::Index l = 0; l < m; ++l) {
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    Eigen::Vector4d qc = Eigen::Vector4d::Zero();
    double rest = 1;
    for (int j = 0; j < k; ++j) {
      const double h = (Phi(F(l, 0), j) + Phi(F(l, 1), j) + Phi(F(l, 2), j)) / 3.0;
      Eigen::Quaterniond q = t[j].rotation.normalized();
      if (q.w() < 0) q.coeffs() *= -1.0;
      if (k == 1) R[l] = Eigen::Quaterniond::Identity().slerp(h, q);
      qc += h * q.coeffs();
      S += h * t[j].stretch;
      rest -= h;
    }
    S += rest * I;
    if (k > 1) {
      qc[3] += rest;
      R[l].coeffs() = qc.normalized();
    }
    const Eigen::Matrix3d M = R[l].toRotationMatrix() * S;
    const Eigen::Vector3d n = normals.row(l).transpose();
    const Eigen::Matrix3d Y = I - n * n.transpose();
    g.middleRows<3>(3 * l) = Y * M.transpose();
  }
  return g;
}

HandleTransform rotation(double degrees, Eigen::Vector3d axis, Eigen::Matrix3d S) {
  HandleTransform h;
  h.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized()));
  h.stretch = S;
  return h;
}

// Quaternions are compared as rotations (q and −q are the same one).
// R_l n_l per triangle (guidance_field's Rn) from the reference's rotations.
Vertices turned_normals(const std::vector<Eigen::Quaterniond>& R, const Vertices& normals) {
  Vertices Rn(normals.rows(), 3);
  for (Eigen::Index l = 0; l < Rn.rows(); ++l)
    Rn.row(l) = (R[static_cast<std::size_t>(l)] * normals.row(l).transpose()).transpose();
  return Rn;
}

void expect_same_field(const PreparedMesh& pm, const Eigen::MatrixXd& Phi,
                       std::span<const HandleTransform> t, const char* what) {
  std::vector<Eigen::Quaterniond> R_ref;
  const GuidanceField expected = reference(pm.mesh().F, pm.normals(), Phi, t, R_ref);
  GuidanceField g;
  Vertices Rn;
  GuidanceScratch scratch;
  guidance_field(pm.mesh().F, pm.normals(), Phi, t, g, &Rn, scratch);
  ASSERT_EQ(g.rows(), expected.rows());
  EXPECT_LT((g - expected).cwiseAbs().maxCoeff(), 1e-13) << what;
  ASSERT_EQ(Rn.rows(), pm.m());
  EXPECT_LT((Rn - turned_normals(R_ref, pm.normals())).cwiseAbs().maxCoeff(), 1e-13) << what;
  // Without R_l n_l (drag frames): the same g, bit for bit.
  GuidanceField g2;
  guidance_field(pm.mesh().F, pm.normals(), Phi, t, g2, nullptr, scratch);
  EXPECT_EQ(g2, g) << what;
}

// Each build of the kernels (cpu_features.h): one handle without stretch takes the AVX2 loop
// (guidance_rotation.h) where the CPU has it, the scalar loop otherwise.
class Guidance : public test::OnEachIsa {};

TEST_P(Guidance, OneHandleIsThePerTriangleSlerp) {
  const test::Benchmark b = test::load_benchmark("cactus");
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform def = HandleTransform::from_matrix(b.T, cs.centroid(0));
  expect_same_field(*b.mesh, cs.harmonic_basis(), std::span(&def, 1), "cactus .def");
  // Large angles (to 179°, where slerp is furthest from linear) with and without stretch.
  Eigen::Matrix3d S;
  S << 1.5, 0.2, 0, 0.2, 0.8, 0.1, 0, 0.1, 1.2;
  for (double deg : {1e-7, 30.0, 120.0, 179.0}) {
    const HandleTransform plain = rotation(deg, {1, 2, 3}, Eigen::Matrix3d::Identity());
    const HandleTransform stretched = rotation(deg, {-1, 0.5, 2}, S);
    expect_same_field(*b.mesh, cs.harmonic_basis(), std::span(&plain, 1), "rotation");
    expect_same_field(*b.mesh, cs.harmonic_basis(), std::span(&stretched, 1), "stretched");
  }
}

TEST_P(Guidance, SeveralHandlesAverageTheQuaternions) {
  const test::Benchmark b = test::load_benchmark("cactus");
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 0.5);
  Eigen::MatrixXd Phi(b.mesh->n(), 2);
  for (Eigen::Index v = 0; v < Phi.rows(); ++v) Phi(v, 0) = u(rng), Phi(v, 1) = u(rng);
  Eigen::Matrix3d S = Eigen::Vector3d(1.3, 0.9, 1.1).asDiagonal();
  const HandleTransform t[2] = {rotation(100, {0, 0, 1}, S),
                                rotation(-60, {1, 1, 0}, Eigen::Matrix3d::Identity())};
  expect_same_field(*b.mesh, Phi, t, "two handles");
}

// Threads only split the loops: 1 and 2 OpenMP threads give the same bits.
TEST_P(Guidance, SameBitsOnOneAndTwoThreads) {
  const test::Benchmark b = test::load_benchmark("cactus");
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform t = rotation(75, {0, 1, 1}, Eigen::Matrix3d::Identity());
  GuidanceScratch scratch;
  GuidanceField g1, g2;
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  guidance_field(b.mesh->mesh().F, b.mesh->normals(), cs.harmonic_basis(), std::span(&t, 1), g1,
                 nullptr, scratch);
  omp_set_num_threads(2);
  guidance_field(b.mesh->mesh().F, b.mesh->normals(), cs.harmonic_basis(), std::span(&t, 1), g2,
                 nullptr, scratch);
  omp_set_num_threads(before);
  EXPECT_EQ(g1, g2);
}

// Meshes whose triangle count is not a multiple of four (the vector loop's tails), and the
// two builds against each other: rounding only (FMA, the turns' polynomials), a few ulp.
TEST_P(Guidance, BuildsAgreeOnEveryTriangle) {
  const test::Benchmark b = test::capsule_benchmark(3000);
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform t = rotation(140, {2, -1, 1}, Eigen::Matrix3d::Identity());
  for (Eigen::Index m : {Eigen::Index{1}, Eigen::Index{6}, Eigen::Index{7}, Eigen::Index{b.mesh->m()}}) {
    SCOPED_TRACE(m);
    const Triangles F = b.mesh->mesh().F.topRows(m);
    const Vertices N = b.mesh->normals().topRows(m);
    GuidanceScratch scratch;
    GuidanceField g, g_other;
    Vertices Rn, Rn_other;
    guidance_field(F, N, cs.harmonic_basis(), std::span(&t, 1), g, &Rn, scratch);
    std::vector<Eigen::Quaterniond> R_ref;
    const GuidanceField expected = reference(F, N, cs.harmonic_basis(), std::span(&t, 1), R_ref);
    EXPECT_LT((g - expected).cwiseAbs().maxCoeff(), 1e-13);
    EXPECT_LT((Rn - turned_normals(R_ref, N)).cwiseAbs().maxCoeff(), 1e-13);
    const Isa other = GetParam() == Isa::avx2 ? Isa::generic : Isa::avx2;
    if (!set_kernel_isa(other)) continue;
    guidance_field(F, N, cs.harmonic_basis(), std::span(&t, 1), g_other, &Rn_other, scratch);
    set_kernel_isa(GetParam());
    EXPECT_LT((g - g_other).cwiseAbs().maxCoeff(), 4e-15);
    if (m == b.mesh->m()) {
      EXPECT_NE(g, g_other) << "both builds ran the same code";
    }
    EXPECT_LT((Rn - Rn_other).cwiseAbs().maxCoeff(), 4e-15);
  }
}

// The AVX2 build's per-vertex turns (polynomials up to |x| ≤ kTurnPolyMax, the library
// beyond) against std::cos / std::sin, across and past the polynomials' range.
TEST(GuidanceTurns, PolynomialsMatchTheLibrary) {
  if (!isa_supported(Isa::avx2)) GTEST_SKIP() << "no AVX2 here";
  const int n = 40001;
  std::vector<double> phi(n);
  for (int v = 0; v < n; ++v) phi[v] = -2.0 + 4.0 * v / (n - 1);
  phi[7] = std::numeric_limits<double>::quiet_NaN();  // its block falls back to the library
  for (double third : {1.0, M_PI / 3, 1e-9, 0.0}) {
    std::vector<std::complex<double>> turn(n);
    detail::vertex_turns_avx2(phi.data(), 0, n, third, turn.data());
    double err = 0;
    for (int v = 8; v < n; ++v) {  // the NaN's block of four: checked below
      const double x = phi[v] * third;
      err = std::max({err, std::abs(turn[v].real() - std::cos(x)), std::abs(turn[v].imag() - std::sin(x))});
    }
    EXPECT_LT(err, 4.5e-16) << third;
    EXPECT_TRUE(std::isnan(turn[7].real()) && std::isnan(turn[7].imag()));
    EXPECT_EQ(turn[4], std::complex<double>(std::cos(phi[4] * third), std::sin(phi[4] * third)));
  }
}

INSTANTIATE_TEST_SUITE_P(Isa, Guidance, test::kEachIsa, test::isa_param_name);

}  // namespace
}  // namespace hdeform

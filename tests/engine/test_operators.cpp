// SPEC.md §Operators: analytic identities of G, A, L, D, W_β.
#include "fixtures.h"

#include <gtest/gtest.h>

#include <cmath>

namespace hdeform {
namespace {

using test::data_path;

std::shared_ptr<const PreparedMesh> cactus() {
  static auto pm = PreparedMesh::create(read_mesh(data_path("botsch-sorkine/cactus.off")).mesh);
  return pm;
}

// The textbook cotangent Laplacian, built from angles only (no gradients):
// L_ij = −½ (cot α_ij + cot β_ij), L_ii = −Σ_j L_ij.
SparseMatrix cotangent_laplacian(const Vertices& V, const Triangles& F) {
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index l = 0; l < F.rows(); ++l)
    for (int c = 0; c < 3; ++c) {
      const int i = F(l, c), j = F(l, (c + 1) % 3), o = F(l, (c + 2) % 3);
      const Eigen::Vector3d u = V.row(i) - V.row(o), w = V.row(j) - V.row(o);
      const double cot = u.dot(w) / u.cross(w).norm();  // angle at o, opposite edge ij
      t.emplace_back(i, j, -0.5 * cot);
      t.emplace_back(j, i, -0.5 * cot);
      t.emplace_back(i, i, 0.5 * cot);
      t.emplace_back(j, j, 0.5 * cot);
    }
  SparseMatrix L(V.rows(), V.rows());
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

TEST(Operators, GradientOfRestPoseIsTangentProjector) {
  const auto pm = cactus();
  const Eigen::MatrixX3d Y = pm->G() * pm->mesh().V;
  double worst = 0;
  for (int l = 0; l < pm->m(); ++l) {
    const Eigen::Vector3d n = pm->normals().row(l).transpose();
    const Eigen::Matrix3d expected = Eigen::Matrix3d::Identity() - n * n.transpose();
    worst = std::max(worst, (Y.middleRows<3>(3 * l) - expected).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(Operators, GradientOfConstantIsZeroAndOfLinearIsExact) {
  const auto pm = cactus();
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(pm->n());
  EXPECT_LT((pm->G() * ones).cwiseAbs().maxCoeff(), 1e-9);
  // f(x) = a·x has gradient (I − nnᵀ) a on each triangle.
  const Eigen::Vector3d a(0.3, -1.2, 2.0);
  const Eigen::VectorXd f = pm->mesh().V * a;
  const Eigen::VectorXd gf = pm->G() * f;
  for (int l = 0; l < pm->m(); l += 97) {
    const Eigen::Vector3d n = pm->normals().row(l).transpose();
    EXPECT_LT((gf.segment<3>(3 * l) - (a - n * n.dot(a))).norm(), 1e-8) << "triangle " << l;
  }
}

TEST(Operators, LaplacianEqualsIndependentCotangentLaplacian) {
  const auto pm = cactus();
  const SparseMatrix ref = cotangent_laplacian(pm->mesh().V, pm->mesh().F);
  const double scale = ref.coeffs().cwiseAbs().maxCoeff();
  EXPECT_LT(SparseMatrix(pm->L() - ref).coeffs().cwiseAbs().maxCoeff(), 1e-9 * scale);
}

TEST(Operators, LaplacianIsSymmetricWithZeroRowSums) {
  const auto pm = cactus();
  const SparseMatrix& L = pm->L();
  EXPECT_LT(SparseMatrix(L - SparseMatrix(L.transpose())).coeffs().cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::VectorXd rows = L * Eigen::VectorXd::Ones(pm->n());
  EXPECT_LT(rows.cwiseAbs().maxCoeff(), 1e-9 * L.coeffs().cwiseAbs().maxCoeff());
  // Positive semi-definite: xᵀ L x ≥ 0 for a few arbitrary x.
  for (int s = 0; s < 3; ++s) {
    const Eigen::VectorXd x = Eigen::VectorXd::Random(pm->n());
    EXPECT_GE(x.dot(L * x), 0.0);
  }
}

TEST(Operators, EnergyDifferencesHaveOnePlusOneMinusPerInteriorEdge) {
  const auto pm = cactus();
  const SparseMatrix D = energy_differences(pm->edges(), pm->m());
  // Closed cactus: every edge interior, |E| = 3m/2.
  EXPECT_EQ(static_cast<int>(pm->edges().size()), 3 * pm->m() / 2);
  const Eigen::VectorXd row_sums = D * Eigen::VectorXd::Ones(pm->m());
  EXPECT_LT(row_sums.cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(D.nonZeros(), 2 * static_cast<Eigen::Index>(pm->edges().size()));
  for (const InteriorEdge& e : pm->edges()) ASSERT_GT(e.length, 0.0);
}

TEST(Operators, KOfBetaIsGtWbetaG) {
  const auto pm = cactus();
  const double beta = 0.3;
  const SparseMatrix W = W_beta(pm->areas(), pm->edges(), beta);
  const SparseMatrix K = SparseMatrix(pm->G().transpose()) * W * pm->G();
  const SparseMatrix K2 = (1 - beta) * pm->L() + beta * pm->Reg();
  EXPECT_LT(SparseMatrix(K - K2).coeffs().cwiseAbs().maxCoeff(),
            1e-9 * K.coeffs().cwiseAbs().maxCoeff());
  // Constants have zero gradient everywhere, so no jumps: the regularizer annihilates them.
  EXPECT_LT((pm->Reg() * Eigen::VectorXd::Ones(pm->n())).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Operators, AreaUnitsMapToRawBetaBySpecFormula) {
  const auto pm = cactus();
  const double s = 1.0 / std::sqrt(pm->total_area());
  for (double beta : {0.0, 0.1, 0.5, 0.9}) {
    const double raw = pm->raw_beta({beta, BetaUnits::area});
    EXPECT_NEAR(raw / (1 - raw), beta / ((1 - beta) * s), 1e-12 * (1 + beta / (1 - beta) / s));
    EXPECT_EQ(pm->raw_beta({beta, BetaUnits::raw}), beta);
  }
  EXPECT_THROW(pm->raw_beta({1.0, BetaUnits::area}), InvalidInput);
  EXPECT_THROW(pm->raw_beta({-0.1, BetaUnits::raw}), InvalidInput);
  EXPECT_THROW(pm->raw_beta({std::nan(""), BetaUnits::raw}), InvalidInput);
}

}  // namespace
}  // namespace hdeform

// Local regularization: a per-triangle β field around the handle.
#include "fixtures.h"

#include <gtest/gtest.h>

namespace hdeform {
namespace {

// Cactus, base fixed by the benchmark's .sel, a single top vertex pulled sideways: the
// protruding-triangle artifact of the naive method (thesis Figure 7.8, "Cactus Side").
struct SingleVertexPull {
  test::Benchmark b = test::load_benchmark("cactus");
  Constraints c;
  int handle = 0;
  SingleVertexPull() {
    const Vertices& X = b.mesh->mesh().V;
    X.col(2).maxCoeff(&handle);
    c.fixed = b.constraints.fixed;
    c.handles = {{handle}};
  }
  HandleTransform pull() const {
    HandleTransform h;
    h.translation = Eigen::Vector3d(0.08, 0.0, 0.0);
    return h;
  }
};

TEST(LocalBeta, StrongLocalBetaSuppressesTheSpikeAndLeavesTheRestAlone) {
  const SingleVertexPull s;
  const ConstraintSet cs(s.b.mesh, s.c);
  const HandleTransform h = s.pull();
  const Frame naive = cs.update(std::span(&h, 1), {0.0, BetaUnits::area});
  // β = 0.3 within 0.03 of the handle (≈ 4 edge lengths), 0 elsewhere.
  const LocalBeta local{falloff_beta(*s.b.mesh, {s.handle}, 0.3, 0.03), BetaUnits::area};
  EXPECT_EQ((local.beta.array() > 0).count() < s.b.mesh->m() / 50, true);
  const Frame reg = cs.update_local(std::span(&h, 1), local);
  EXPECT_LT(reg.measures.max_e_iso, naive.measures.max_e_iso / 10.0)
      << "naive " << naive.measures.max_e_iso << " local " << reg.measures.max_e_iso;

  // Half the cactus's height away, vertices stay within 10 % of the pull of the naive
  // result: removing the spike widens the bump, it does not move the far surface.
  const Vertices& X = s.b.mesh->mesh().V;
  double far_dev = 0;
  for (int v = 0; v < s.b.mesh->n(); ++v)
    if ((X.row(v) - X.row(s.handle)).norm() > 0.4)
      far_dev = std::max(far_dev, (reg.positions.row(v) - naive.positions.row(v)).norm());
  EXPECT_LT(far_dev, 0.1 * h.translation.norm());
  EXPECT_GT(far_dev, 0.0);
}

TEST(LocalBeta, UniformFieldEqualsGlobalBeta) {
  const SingleVertexPull s;
  const ConstraintSet cs(s.b.mesh, s.c);
  const HandleTransform h = s.pull();
  for (BetaUnits u : {BetaUnits::area, BetaUnits::raw}) {
    const Frame global = cs.update(std::span(&h, 1), {0.3, u});
    const Frame local = cs.update_local(
        std::span(&h, 1), LocalBeta{Eigen::VectorXd::Constant(s.b.mesh->m(), 0.3), u});
    EXPECT_LT((global.positions - local.positions).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(LocalBeta, FalloffFieldEqualsBruteForceDistances) {
  const SingleVertexPull s;
  const Vertices& V = s.b.mesh->mesh().V;
  const Triangles& F = s.b.mesh->mesh().F;
  const std::vector<int>& region = s.b.constraints.handles[0];
  const double radius = 0.07;
  const Eigen::VectorXd field = falloff_beta(*s.b.mesh, region, 0.5, radius);
  int inside = 0;
  for (int l = 0; l < s.b.mesh->m(); ++l) {
    const Eigen::RowVector3d c = (V.row(F(l, 0)) + V.row(F(l, 1)) + V.row(F(l, 2))) / 3.0;
    double d = 1e300;
    for (int v : region) d = std::min(d, (V.row(v) - c).norm());
    const double t = std::max(0.0, 1.0 - d / radius);
    ASSERT_NEAR(field[l], 0.5 * t * t, 1e-15) << "triangle " << l;
    inside += field[l] > 0;
  }
  EXPECT_GT(inside, 100);
  EXPECT_LT(inside, s.b.mesh->m() / 2);
  const Eigen::VectorXd flat = region_beta(*s.b.mesh, region, 0.2);
  EXPECT_EQ(flat.maxCoeff(), 0.2);
  EXPECT_THROW(region_beta(*s.b.mesh, {-1}, 0.2), InvalidInput);
  EXPECT_THROW(falloff_beta(*s.b.mesh, region, 0.2, 0.0), InvalidInput);
}

TEST(LocalBeta, RejectsBadFields) {
  const SingleVertexPull s;
  const ConstraintSet cs(s.b.mesh, s.c);
  const HandleTransform h = s.pull();
  EXPECT_THROW(cs.update_local(std::span(&h, 1), LocalBeta{Eigen::VectorXd::Zero(3)}),
               InvalidInput);
  Eigen::VectorXd bad = Eigen::VectorXd::Zero(s.b.mesh->m());
  bad[17] = 1.0;
  try {
    cs.update_local(std::span(&h, 1), LocalBeta{bad});
    ADD_FAILURE();
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 17"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hdeform

// Automatic β: picks the thesis's recommended range (0.1–0.25, raw units) where the naive
// result has artifacts and 0 where it has none.
#include "auto_beta.h"
#include "fixtures.h"

#include <gtest/gtest.h>

namespace hdeform {
namespace {

AutoBetaResult pick_benchmark(const char* model) {
  const auto b = test::load_benchmark(model);
  ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
  return select_beta(cs, std::span(&h, 1));
}

TEST(AutoBeta, CleanBenchmarksKeepBetaZero) {
  // Cylinder: β only raises every measure. Cactus: β barely lowers the maxima (−17 %)
  // while the global energy rises.
  EXPECT_EQ(pick_benchmark("cylinder").beta.value, 0.0);
  EXPECT_EQ(pick_benchmark("cactus").beta.value, 0.0);
}

TEST(AutoBeta, BarArtifactsGetTheRecommendedRange) {
  const AutoBetaResult r = pick_benchmark("bar");
  EXPECT_GE(r.beta.value, 0.1);
  EXPECT_LE(r.beta.value, 0.25);
  EXPECT_EQ(r.beta.units, BetaUnits::raw);
}

TEST(AutoBeta, SingleVertexHandlesGetTheRecommendedRange) {
  const auto b = test::load_benchmark("cactus");
  int top = 0;
  b.mesh->mesh().V.col(2).maxCoeff(&top);
  ConstraintSet cs(b.mesh, Constraints{b.constraints.fixed, {{top}}});
  HandleTransform side;  // thesis Figure 7.8: a single vertex pulled sideways
  side.translation = Eigen::Vector3d(0.08, 0, 0);
  const HandleTransform bend =  // Figure 7.7: the benchmark's bend on one vertex
      HandleTransform::from_matrix(b.T, b.mesh->mesh().V.row(top).transpose());
  for (const HandleTransform& h : {side, bend}) {
    const AutoBetaResult r = select_beta(cs, std::span(&h, 1));
    EXPECT_GE(r.beta.value, 0.1);
    EXPECT_LE(r.beta.value, 0.25);
    const Measures& naive = r.samples.front().measures;
    for (const AutoBetaSample& s : r.samples)
      if (s.beta == r.beta.value) {
        EXPECT_LT(s.measures.max_e_iso, naive.max_e_iso / 10);
      }
  }
  // Rejected samples' factorizations are dropped: β = 0 and the pick remain.
  EXPECT_LE(cs.num_cached_factorizations(), 3u);
}

}  // namespace
}  // namespace hdeform

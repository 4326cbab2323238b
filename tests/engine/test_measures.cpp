// measure() (SPEC.md §Measures): the AVX2 build of its loop (measures_avx2.h) against the
// scalar one, on the bundled models (triangle counts of every residue mod 4 between them)
// at a solved frame and at a scrambled one with flipped triangles.
#include "cpu_features.h"
#include "fixtures.h"
#include "measures.h"

#include <gtest/gtest.h>

#include <random>

namespace hdeform {
namespace {

struct Result {
  Measures m;
  Eigen::VectorXf ef2;
  Vertices face_w;
};

Result run(const PreparedMesh& pm, const Vertices& X, const GuidanceField& g,
           const std::vector<Eigen::Quaterniond>& R, Isa isa) {
  const Isa before = kernel_isa();
  EXPECT_TRUE(set_kernel_isa(isa));
  Result r;
  r.m = measure(pm, X, g, R, &r.ef2, &r.face_w);
  set_kernel_isa(before);
  return r;
}

void expect_close(const Result& a, const Result& b) {
  auto rel = [](double x, double y) { return std::abs(x - y) / std::max(std::abs(y), 1e-300); };
  EXPECT_LT(rel(a.m.E, b.m.E), 1e-12);
  EXPECT_LT(rel(a.m.E_iso_N, b.m.E_iso_N), 1e-12);
  EXPECT_LT(rel(a.m.E_conf_N, b.m.E_conf_N), 1e-10);  // near 0 on a rigid frame
  EXPECT_LT(std::abs(a.m.E_area_pct - b.m.E_area_pct), 1e-10);
  EXPECT_LT(rel(a.m.max_e_iso, b.m.max_e_iso), 1e-10);
  EXPECT_LT(rel(a.m.max_e_conf, b.m.max_e_conf), 1e-10);
  EXPECT_LT(rel(a.m.max_ef2, b.m.max_ef2), 1e-10);
  EXPECT_EQ(a.m.flips, b.m.flips);
  EXPECT_TRUE(a.face_w == b.face_w);  // the normals' weights: bit for bit (no FMA there)
  ASSERT_EQ(a.ef2.size(), b.ef2.size());
  for (Eigen::Index l = 0; l < a.ef2.size(); ++l)
    ASSERT_NEAR(a.ef2[l], b.ef2[l], 1e-6f * std::max(1.0f, b.ef2[l])) << l;
}

TEST(Measures, Avx2BuildEqualsTheScalarLoop) {
  if (!isa_supported(Isa::avx2)) GTEST_SKIP() << "no AVX2 here";
  std::mt19937 rng(5);
  for (const char* model : {"bar", "cactus", "cylinder", "plane"}) {
    SCOPED_TRACE(model);
    const test::Benchmark b = test::load_benchmark(model);
    const ConstraintSet cs(b.mesh, b.constraints);
    const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
    const Frame f = cs.update(std::span(&h, 1), {0.3});
    GuidanceField g;
    std::vector<Eigen::Quaterniond> R;
    GuidanceScratch scratch;
    cs.guidance(std::span(&h, 1), g, &R, scratch);
    const PreparedMesh& pm = *b.mesh;
    std::printf("  %s: m = %d (mod 4 = %d)\n", model, pm.m(), pm.m() % 4);
    const Result vec = run(pm, f.positions, g, R, Isa::avx2);
    const Result scalar = run(pm, f.positions, g, R, Isa::generic);
    expect_close(vec, scalar);
    EXPECT_NEAR(vec.m.E, f.measures.E, 1e-12 * f.measures.E);  // the frame's own measures
    // Positions scrambled: many flipped triangles, large distortions.
    Vertices X = f.positions;
    std::normal_distribution<double> noise(0, 0.05 * (X.colwise().maxCoeff() - X.colwise().minCoeff()).norm());
    for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] += noise(rng);
    const Result vec2 = run(pm, X, g, R, Isa::avx2);
    const Result scalar2 = run(pm, X, g, R, Isa::generic);
    EXPECT_GT(scalar2.m.flips, 0);
    expect_close(vec2, scalar2);
  }
}

}  // namespace
}  // namespace hdeform

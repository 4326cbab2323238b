// measures.h against closed forms (SPEC.md §Measures): the rest pose, a uniform scale, a
// rigid rotation, counted flips; and the AVX2 build against the scalar one on a noisy pose.
#include "each_isa.h"
#include "engine/deform/guidance.h"
#include "engine/deform/measures.h"
#include "fixtures.h"
#include "helper_busy.h"

#include <gtest/gtest.h>

#include <random>

namespace hdeform {
namespace {

// The rest guidance (g_l = Y_l = I − n_l n_lᵀ, R_l = I) of a mesh.
struct RestGuidance {
  GuidanceField g;
  Vertices Rn;
};
RestGuidance rest_guidance(const PreparedMesh& pm) {
  RestGuidance r{GuidanceField(3 * pm.m(), 3), pm.normals()};
  for (Eigen::Index l = 0; l < pm.m(); ++l) {
    const Eigen::Vector3d n = pm.normals().row(l).transpose();
    r.g.middleRows<3>(3 * l) = Eigen::Matrix3d::Identity() - n * n.transpose();
  }
  return r;
}

class Measure : public test::OnEachIsa {};

TEST_P(Measure, RestPoseIsZero) {
  const test::Benchmark b = test::load_benchmark("cactus");
  const PreparedMesh& pm = *b.mesh;
  const RestGuidance rest = rest_guidance(pm);
  const Measures m = measure(pm, pm.mesh().V, rest.g, rest.Rn);
  EXPECT_LT(m.E, 1e-24 * pm.total_area());
  EXPECT_LT(m.max_ef2, 1e-24);
  EXPECT_NEAR(m.E_iso_N, 0, 1e-13);
  EXPECT_NEAR(m.E_conf_N, 0, 1e-13);
  EXPECT_NEAR(m.E_area_pct, 0, 1e-11);
  EXPECT_EQ(m.flips, 0);
}

// X' = s X against the rest guidance: Y'_l = s Y_l, r_l = (s − 1) Y_l, σ₁ = σ₂ = s.
TEST_P(Measure, UniformScaleHasClosedForms) {
  const test::Benchmark b = test::load_benchmark("bar");
  const PreparedMesh& pm = *b.mesh;
  const RestGuidance rest = rest_guidance(pm);
  for (double s : {0.5, 1.25, 3.0}) {
    SCOPED_TRACE(s);
    Eigen::VectorXf ef2;
    const Measures m = measure(pm, Vertices(s * pm.mesh().V), rest.g, rest.Rn, &ef2);
    const double e = 2 * (s - 1) * (s - 1);  // ‖(s − 1) Y_l‖²_F, Y_l a rank-2 projector
    EXPECT_NEAR(m.E, e * pm.total_area(), 1e-12 * e * pm.total_area());
    EXPECT_NEAR(m.max_ef2, e, 1e-12 * e);
    EXPECT_NEAR(m.E_iso_N, e, 1e-12 * e);
    EXPECT_NEAR(m.max_e_iso, e, 1e-11 * e);
    EXPECT_NEAR(m.E_conf_N, 0, 1e-12);
    EXPECT_NEAR(m.E_area_pct, 100 * (s * s - 1), 1e-10);
    EXPECT_EQ(m.flips, 0);
    ASSERT_EQ(ef2.size(), pm.m());
    EXPECT_NEAR(ef2.maxCoeff(), e, 1e-6 * e);
    EXPECT_NEAR(ef2.minCoeff(), e, 1e-6 * e);
  }
}

// A rigid rotation Q of the mesh with its guidance (g_l = Y_l Qᵀ, R_l n_l = Q n_l) is
// distortion-free; the same rotation with the rest guidance is not, by its known amount.
TEST_P(Measure, RotationWithItsGuidanceIsFree) {
  const test::Benchmark b = test::load_benchmark("cactus");
  const PreparedMesh& pm = *b.mesh;
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  const Vertices X = pm.mesh().V * Q.transpose();
  RestGuidance turned = rest_guidance(pm);
  for (Eigen::Index l = 0; l < pm.m(); ++l)
    turned.g.middleRows<3>(3 * l) = Eigen::Matrix3d(turned.g.middleRows<3>(3 * l)) * Q.transpose();
  turned.Rn = pm.normals() * Q.transpose();
  const Measures m = measure(pm, X, turned.g, turned.Rn);
  EXPECT_LT(m.E, 1e-22 * pm.total_area());
  EXPECT_NEAR(m.E_iso_N, 0, 1e-12);
  EXPECT_NEAR(m.E_conf_N, 0, 1e-12);
  EXPECT_NEAR(m.E_area_pct, 0, 1e-10);
  EXPECT_EQ(m.flips, 0);
  // Against the rest guidance: ‖Y_l Qᵀ − Y_l‖²_F = 2 tr(Y_l) − 2 tr(Y_l Qᵀ Y_l)... per
  // triangle; what does not depend on the triangle is that E > 0 and the shape is intact.
  const RestGuidance rest = rest_guidance(pm);
  const Measures off = measure(pm, X, rest.g, rest.Rn);
  EXPECT_GT(off.E, 1e-3 * pm.total_area());
  EXPECT_NEAR(off.E_iso_N, 0, 1e-12);
  EXPECT_NEAR(off.E_area_pct, 0, 1e-10);
}

// flips counts the triangles whose deformed normal turned against R_l n_l.
TEST_P(Measure, CountsFlippedTriangles) {
  const test::Benchmark b = test::load_benchmark("cactus");
  const PreparedMesh& pm = *b.mesh;
  RestGuidance rest = rest_guidance(pm);
  int expected = 0;
  for (Eigen::Index l = 0; l < pm.m(); l += 3) {
    rest.Rn.row(l) *= -1;
    ++expected;
  }
  EXPECT_EQ(measure(pm, pm.mesh().V, rest.g, rest.Rn).flips, expected);
  EXPECT_EQ(measure(pm, pm.mesh().V, rest.g, Vertices(-pm.normals())).flips, pm.m());
}

// The two builds on a noisy pose with a real guidance field, on the cactus less 0–3 of its
// last triangles (every tail m mod 4 after the blocks of four); on two threads and on one.
TEST_P(Measure, BuildsAgree) {
  const Isa other = GetParam() == Isa::avx2 ? Isa::generic : Isa::avx2;
  if (!isa_supported(other)) GTEST_SKIP() << "one build only on this CPU";
  const test::Benchmark cactus = test::load_benchmark("cactus");
  for (int less = 0; less < 4; ++less) {
    TriMesh mesh = cactus.mesh->mesh();
    mesh.F.conservativeResize(mesh.F.rows() - less, 3);
    const auto pm_ptr = PreparedMesh::create(std::move(mesh));
    const PreparedMesh& pm = *pm_ptr;
    SCOPED_TRACE(pm.m());
    const ConstraintSet cs(pm_ptr, cactus.constraints);
    HandleTransform t;
    t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.5, Eigen::Vector3d(1, 1, 0).normalized()));
    GuidanceField g;
    Vertices Rn;
    GuidanceScratch scratch;
    cs.guidance(std::span(&t, 1), g, &Rn, scratch);
    std::mt19937 rng(11);
    std::normal_distribution<double> noise(0, 0.05);
    Vertices X = pm.mesh().V;
    for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] += noise(rng);
    Measures two;
    Eigen::VectorXf ef2_two;
    // The halves on two threads, then both on this one (the helper held by a caller of
    // its own): the same bits.
    for (bool helper_busy : {false, true}) {
      SCOPED_TRACE(helper_busy ? "one thread" : "two threads");
      Eigen::VectorXf ef2, ef2_other;
      Vertices w, w_other;
      Measures a, again, o;
      auto run = [&] {
        a = measure(pm, X, g, Rn, &ef2, &w);
        again = measure(pm, X, g, Rn);
        set_kernel_isa(other);
        o = measure(pm, X, g, Rn, &ef2_other, &w_other);
        set_kernel_isa(GetParam());
      };
      if (helper_busy)
        test::run_with_helper_busy(run);
      else
        run();
      EXPECT_EQ(again.E, a.E) << "not deterministic";
      EXPECT_GT(a.flips, 0);  // the noise folds some triangles over
      EXPECT_EQ(a.flips, o.flips);
      EXPECT_NEAR(a.E, o.E, 1e-12 * a.E);
      EXPECT_NEAR(a.E_iso_N, o.E_iso_N, 1e-12 * a.E_iso_N);
      EXPECT_NEAR(a.E_conf_N, o.E_conf_N, 1e-12 * a.E_conf_N);
      EXPECT_NEAR(a.E_area_pct, o.E_area_pct, 1e-10 * std::abs(a.E_area_pct));
      EXPECT_NEAR(a.max_ef2, o.max_ef2, 1e-12 * a.max_ef2);
      EXPECT_NEAR(a.max_e_iso, o.max_e_iso, 1e-12 * a.max_e_iso);
      EXPECT_NEAR(a.max_e_conf, o.max_e_conf, 1e-12 * a.max_e_conf);
      EXPECT_LT((ef2 - ef2_other).cwiseAbs().maxCoeff(), 1e-6f * ef2.cwiseAbs().maxCoeff());
      EXPECT_TRUE(w == w_other) << "the normals' weights must not depend on the build";
      // The builds round differently (FMA), so some sum differs in its last bits; any one
      // sum may still round to the same double (E did, on one of these meshes).
      EXPECT_TRUE(a.E != o.E || a.E_iso_N != o.E_iso_N || a.E_conf_N != o.E_conf_N ||
                  a.E_area_pct != o.E_area_pct || !(ef2 == ef2_other))
          << "both builds ran the same code";
      if (helper_busy) {
        EXPECT_EQ(a.E, two.E);
        EXPECT_EQ(a.E_iso_N, two.E_iso_N);
        EXPECT_EQ(a.E_conf_N, two.E_conf_N);
        EXPECT_EQ(a.E_area_pct, two.E_area_pct);
        EXPECT_EQ(a.max_ef2, two.max_ef2);
        EXPECT_EQ(a.flips, two.flips);
        EXPECT_TRUE(ef2 == ef2_two);
      } else {
        two = a;
        ef2_two = ef2;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Isa, Measure, test::kEachIsa, test::isa_param_name);

}  // namespace
}  // namespace hdeform

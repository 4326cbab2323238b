// SPEC.md's analytic checks on the full deformation: rest pose, equivariances, maximum
// principle, KKT optimality, constraint validation.
#include "fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

namespace hdeform {
namespace {

using test::Benchmark;
using test::load_benchmark;

const Benchmark& cactus() {
  static const Benchmark b = load_benchmark("cactus");
  return b;
}

double max_abs(const Vertices& a) { return a.cwiseAbs().maxCoeff(); }

HandleTransform bend() {
  HandleTransform h;
  h.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 0.2, 0).normalized()));
  h.stretch = Eigen::Vector3d(1.1, 0.9, 1.0).asDiagonal();
  h.translation = Eigen::Vector3d(0.05, -0.1, 0.02);
  return h;
}

TEST(Deformer, RestPoseIsReproducedAtAnyBeta) {
  const ConstraintSet cs(cactus().mesh, cactus().constraints);
  const HandleTransform identity;
  for (BetaUnits u : {BetaUnits::raw, BetaUnits::area})
    for (double beta : {0.0, 0.1, 0.5, 0.99}) {
      const Frame f = cs.update(std::span(&identity, 1), {beta, u});
      EXPECT_LT(max_abs(f.positions - cactus().mesh->mesh().V), 1e-9) << "beta " << beta;
      EXPECT_LT(f.measures.E, 1e-16);
      EXPECT_EQ(f.measures.flips, 0);
    }
}

TEST(Deformer, HandleTargetsAndFixedVerticesAreExact) {
  const ConstraintSet cs(cactus().mesh, cactus().constraints);
  const HandleTransform h = HandleTransform::from_matrix(cactus().T, cs.centroid(0));
  const Frame f = cs.update(std::span(&h, 1), {0.2, BetaUnits::area});
  const Vertices& X = cactus().mesh->mesh().V;
  for (int v : cactus().constraints.fixed) EXPECT_EQ(f.positions.row(v), X.row(v));
  for (int v : cactus().constraints.handles[0]) {
    const Eigen::Vector4d target = cactus().T * X.row(v).transpose().homogeneous();
    EXPECT_LT((f.positions.row(v).transpose() - target.head<3>()).norm(), 1e-12);
  }
}

// Uniform scaling by 1000 (area units): the same shape, ×1000.
TEST(Deformer, ScaleEquivarianceInAreaUnits) {
  TriMesh big = cactus().mesh->mesh();
  big.V *= 1000.0;
  const auto pm_big = PreparedMesh::create(big);
  const ConstraintSet small(cactus().mesh, cactus().constraints);
  const ConstraintSet large(pm_big, cactus().constraints);
  HandleTransform h = bend(), H = bend();
  H.translation *= 1000.0;
  for (double beta : {0.0, 0.25}) {
    const Frame a = small.update(std::span(&h, 1), {beta, BetaUnits::area});
    const Frame b = large.update(std::span(&H, 1), {beta, BetaUnits::area});
    EXPECT_LT(max_abs(b.positions - 1000.0 * a.positions), 1e-9 * 1000.0) << "beta " << beta;
    EXPECT_NEAR(b.measures.E, 1e6 * a.measures.E, 1e-6 * b.measures.E);
    EXPECT_NEAR(b.measures.max_e_iso, a.measures.max_e_iso, 1e-6);
  }
  // Raw units are not scale-invariant: the same β gives a different shape.
  const Frame a = small.update(std::span(&h, 1), {0.25, BetaUnits::raw});
  const Frame b = large.update(std::span(&H, 1), {0.25, BetaUnits::raw});
  EXPECT_GT(max_abs(b.positions - 1000.0 * a.positions), 1e-3);
}

TEST(Deformer, TranslationAndRotationEquivariance) {
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(3.0, -2.0, 0.5);
  TriMesh moved = cactus().mesh->mesh();
  moved.V = (moved.V * Q.transpose()).rowwise() + t.transpose();
  const ConstraintSet orig(cactus().mesh, cactus().constraints);
  const ConstraintSet other(PreparedMesh::create(moved), cactus().constraints);
  const HandleTransform h = bend();
  // The same handle motion expressed in the moved frame: x ↦ Q x + t conjugates it.
  HandleTransform H;
  H.rotation = Eigen::Quaterniond(Q * h.rotation.toRotationMatrix() * Q.transpose());
  H.stretch = Q * h.stretch * Q.transpose();
  H.translation = Q * h.translation;
  for (double beta : {0.0, 0.3}) {
    const Frame a = orig.update(std::span(&h, 1), {beta, BetaUnits::area});
    const Frame b = other.update(std::span(&H, 1), {beta, BetaUnits::area});
    const Vertices expected = (a.positions * Q.transpose()).rowwise() + t.transpose();
    EXPECT_LT(max_abs(b.positions - expected), 1e-9) << "beta " << beta;
    EXPECT_NEAR(b.measures.E, a.measures.E, 1e-9 * (1 + a.measures.E));
  }
}

TEST(Deformer, HarmonicBasisObeysMaximumPrinciple) {
  // Two handles (top and a side blob) plus the fixed base.
  const Benchmark& b = cactus();
  Constraints c = b.constraints;
  const Vertices& X = b.mesh->mesh().V;
  std::vector<int> side;
  for (int v = 0; v < b.mesh->n(); ++v)
    if (c.handles[0].end() == std::find(c.handles[0].begin(), c.handles[0].end(), v) &&
        c.fixed.end() == std::find(c.fixed.begin(), c.fixed.end(), v) &&
        (X.row(v) - X.row(2000)).norm() < 0.05)
      side.push_back(v);
  ASSERT_GT(side.size(), 3u);
  c.handles.push_back(side);
  const ConstraintSet cs(b.mesh, c);
  const Eigen::MatrixXd& Phi = cs.harmonic_basis();
  ASSERT_EQ(Phi.cols(), 2);
  EXPECT_GE(Phi.minCoeff(), -1e-12);
  EXPECT_LE(Phi.maxCoeff(), 1 + 1e-12);
  EXPECT_LE(Phi.rowwise().sum().maxCoeff(), 1 + 1e-12);
  // Strictly inside on free vertices (the fields are not trivially 0 or 1).
  for (int v = 0; v < b.mesh->n(); v += 101)
    if (std::find(b.constraints.fixed.begin(), b.constraints.fixed.end(), v) ==
            b.constraints.fixed.end() &&
        std::find(c.handles[0].begin(), c.handles[0].end(), v) == c.handles[0].end() &&
        std::find(side.begin(), side.end(), v) == side.end()) {
      EXPECT_GT(Phi(v, 0), 0.0);
      EXPECT_LT(Phi(v, 0), 1.0);
    }
  // L Φ = 0 on free vertices.
  const Eigen::MatrixXd LPhi = b.mesh->L() * Phi;
  std::vector<char> constrained(b.mesh->n(), 0);
  for (int v : c.fixed) constrained[v] = 1;
  for (const auto& h : c.handles)
    for (int v : h) constrained[v] = 1;
  double worst = 0;
  for (int v = 0; v < b.mesh->n(); ++v)
    if (!constrained[v]) worst = std::max(worst, LPhi.row(v).cwiseAbs().maxCoeff());
  EXPECT_LT(worst, 1e-9);
}

// KKT: the energy gradient Gᵀ W_β (G x − g) vanishes on the free vertices.
TEST(Deformer, SolutionSatisfiesKKTOptimality) {
  const Benchmark& b = cactus();
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
  for (double beta : {0.0, 0.3}) {
    const Frame f = cs.update(std::span(&h, 1), {beta, BetaUnits::raw});
    GuidanceField g;
    GuidanceScratch scratch;
    cs.guidance(std::span(&h, 1), g, nullptr, scratch);
    const SparseMatrix W = W_beta(b.mesh->areas(), b.mesh->edges(), beta);
    const Eigen::MatrixX3d grad =
        SparseMatrix(b.mesh->G().transpose()) * (W * (b.mesh->G() * f.positions - g));
    const Eigen::MatrixX3d rhs_scale = SparseMatrix(b.mesh->G().transpose()) * (W * g);
    std::vector<char> constrained(b.mesh->n(), 0);
    for (int v : b.constraints.fixed) constrained[v] = 1;
    for (int v : b.constraints.handles[0]) constrained[v] = 1;
    double worst = 0;
    for (int v = 0; v < b.mesh->n(); ++v)
      if (!constrained[v]) worst = std::max(worst, grad.row(v).cwiseAbs().maxCoeff());
    EXPECT_LT(worst, 1e-8 * rhs_scale.cwiseAbs().maxCoeff()) << "beta " << beta;
    // Perturbing a free vertex raises the energy (a minimum, not a saddle).
    Vertices x = f.positions;
    x(2500, 0) += 1e-3;
    const auto energy = [&](const Vertices& y) {
      const Eigen::MatrixX3d r = b.mesh->G() * y - g;
      return (r.transpose() * (W * r)).trace();
    };
    EXPECT_GT(energy(x), energy(f.positions));
  }
}

// A β change reuses the symbolic analysis; results equal a fresh constraint set's.
TEST(Deformer, CachedFactorizationsMatchFreshOnes) {
  const Benchmark& b = cactus();
  const ConstraintSet warm(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, warm.centroid(0));
  for (double beta : {0.5, 0.1, 0.9}) warm.update(std::span(&h, 1), {beta, BetaUnits::raw});
  EXPECT_EQ(warm.num_cached_factorizations(), 4u);  // 0 (harmonic), 0.5, 0.1, 0.9
  const ConstraintSet fresh(b.mesh, b.constraints);
  const Frame a = warm.update(std::span(&h, 1), {0.1, BetaUnits::raw});
  const Frame c = fresh.update(std::span(&h, 1), {0.1, BetaUnits::raw});
  EXPECT_LT(max_abs(a.positions - c.positions), 1e-10);
}

TEST(Deformer, SeveralHandlesUseTheQuaternionField) {
  const Benchmark& b = cactus();
  Constraints c = b.constraints;
  // Split the handle region into two halves by x.
  std::vector<int> left, right;
  const Vertices& X = b.mesh->mesh().V;
  double mid = 0;
  for (int v : c.handles[0]) mid += X(v, 0);
  mid /= static_cast<double>(c.handles[0].size());
  for (int v : c.handles[0]) (X(v, 0) < mid ? left : right).push_back(v);
  c.handles = {left, right};
  const ConstraintSet cs(b.mesh, c);
  // Same rigid motion on both: the result equals the single-handle one only in the
  // constraints; measures are finite and targets exact.
  const HandleTransform h0 = HandleTransform::from_matrix(b.T, cs.centroid(0));
  const HandleTransform h1 = HandleTransform::from_matrix(b.T, cs.centroid(1));
  const std::vector<HandleTransform> hs{h0, h1};
  const Frame f = cs.update(hs, {0.0, BetaUnits::raw});
  for (int v : right) {
    const Eigen::Vector4d target = b.T * X.row(v).transpose().homogeneous();
    EXPECT_LT((f.positions.row(v).transpose() - target.head<3>()).norm(), 1e-12);
  }
  EXPECT_TRUE(std::isfinite(f.measures.E));
  // Both handles share one rotation: the blended field is exactly that rotation's slerp
  // profile, so the result matches the single-handle deformation closely.
  const ConstraintSet one(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, one.centroid(0));
  const Frame g = one.update(std::span(&h, 1), {0.0, BetaUnits::raw});
  EXPECT_LT(max_abs(f.positions - g.positions), 0.05 * max_abs(X));
  EXPECT_THROW(cs.update(std::span(&h0, 1), {0.0, BetaUnits::raw}), InvalidInput);
}

TEST(Deformer, RejectsBadConstraintsWithPreciseMessages) {
  const Benchmark& b = cactus();
  auto message = [&](Constraints c) {
    try {
      ConstraintSet cs(b.mesh, std::move(c));
    } catch (const InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Constraints c = b.constraints;
  c.fixed.push_back(b.mesh->n() + 5);
  EXPECT_NE(message(c).find("out of range"), std::string::npos) << message(c);
  c = b.constraints;
  c.fixed.push_back(c.handles[0][3]);
  EXPECT_NE(message(c).find("overlaps"), std::string::npos) << message(c);
  c = b.constraints;
  c.fixed.clear();
  EXPECT_NE(message(c).find("single handle needs a fixed region"), std::string::npos);
  c = b.constraints;
  c.handles.clear();
  EXPECT_NE(message(c).find("at least one handle"), std::string::npos);
  c = b.constraints;
  c.handles.push_back({});
  // Handles are numbered from 0 everywhere (as Constraints::handles and the API's handles[j]).
  EXPECT_NE(message(c).find("handle 1 is empty"), std::string::npos) << message(c);

  // Two disjoint copies of the cactus, constraints on the first only.
  TriMesh two = b.mesh->mesh();
  const int n = two.num_vertices();
  two.V.conservativeResize(2 * n, 3);
  two.V.bottomRows(n) = b.mesh->mesh().V.rowwise() + Eigen::RowVector3d(5, 0, 0);
  two.F.conservativeResize(2 * two.F.rows(), 3);
  two.F.bottomRows(b.mesh->m()) = b.mesh->mesh().F.array() + n;
  const auto pm2 = PreparedMesh::create(two);
  try {
    ConstraintSet cs(pm2, b.constraints);
    ADD_FAILURE() << "expected an error";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("component 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no constrained vertex"), std::string::npos);
  }
}

TEST(Deformer, RejectsBadTransformsAndBeta) {
  const ConstraintSet cs(cactus().mesh, cactus().constraints);
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  EXPECT_THROW(HandleTransform::from_matrix(mirror, Eigen::Vector3d::Zero()), InvalidInput);
  Eigen::Matrix4d flat = Eigen::Matrix4d::Identity();
  flat(2, 2) = 0;
  EXPECT_THROW(HandleTransform::from_matrix(flat, Eigen::Vector3d::Zero()), InvalidInput);
  HandleTransform h;
  h.translation.x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(cs.update(std::span(&h, 1), {0.0, BetaUnits::area}), InvalidInput);
  h = HandleTransform();
  h.stretch(0, 0) = -1;
  EXPECT_THROW(cs.update(std::span(&h, 1), {0.0, BetaUnits::area}), InvalidInput);
  h = HandleTransform();
  EXPECT_THROW(cs.update(std::span(&h, 1), {1.0, BetaUnits::area}), InvalidInput);
}

// Every vertex constrained: an empty system must not reach CHOLMOD (which crashes on
// a null factor). Decision (docs/api.md): the answer is simply the targets.
TEST(Deformer, NoFreeVertexGivesTheTargets) {
  const Benchmark& b = cactus();
  Constraints c;
  const int n = b.mesh->n();
  c.handles.resize(1);
  for (int v = 0; v < n; ++v) (v < n / 2 ? c.fixed : c.handles[0]).push_back(v);
  for (double beta : {0.0, 0.3}) {
    const ConstraintSet cs(b.mesh, c);
    HandleTransform h;
    h.translation = Eigen::Vector3d(0.5, -1, 2);
    const Frame f = cs.update(std::span(&h, 1), {beta, BetaUnits::area});
    for (int v = 0; v < n; ++v) {
      const Eigen::RowVector3d rest = b.mesh->mesh().V.row(v);
      const Eigen::RowVector3d want = v < n / 2 ? rest : rest + h.translation.transpose();
      ASSERT_LT((f.positions.row(v) - want).norm(), 1e-12) << "vertex " << v << " beta " << beta;
    }
    const Frame t = cs.update_transient(std::span(&h, 1), {0.6, BetaUnits::area});
    EXPECT_EQ(t.positions, f.positions);
  }
}

// Issue 8 (4): transforms near 1e300 gave NaN/Inf positions that were streamed and written.
TEST(Deformer, OutOfRangeResultIsRejectedNamingTheHandle) {
  const Benchmark& b = cactus();
  Constraints c = b.constraints;
  c.handles.push_back(c.handles[0]);
  c.handles[0].resize(c.handles[0].size() / 2);
  c.handles[1].erase(c.handles[1].begin(), c.handles[1].begin() + c.handles[0].size());
  const ConstraintSet cs(b.mesh, c);
  for (double big : {1e300, 1e200, 1e40}) {
    std::vector<HandleTransform> hs(2);
    hs[1].translation = Eigen::Vector3d(big, 0, 0);
    try {
      cs.update(hs, {0.0, BetaUnits::area});
      ADD_FAILURE() << "expected an error for translation " << big;
    } catch (const InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find("handle 1's transform"), std::string::npos) << e.what();
    }
    hs[1] = HandleTransform();
    hs[0].stretch *= big;
    EXPECT_THROW(cs.update(hs, {0.25, BetaUnits::area}), InvalidInput);
  }
  // Large but representable moves still solve.
  std::vector<HandleTransform> hs(2);
  hs[0].translation = Eigen::Vector3d(1e6, 0, 0);
  EXPECT_TRUE(cs.update(hs, {0.0, BetaUnits::area}).positions.allFinite());
}

// Issue 8 (5): a strong shear (det = 1) was called "singular or reflecting (det = 1.000000)".
TEST(Deformer, ShearIsAcceptedAndSingularMatricesSayWhy) {
  Eigen::Matrix4d shear = Eigen::Matrix4d::Identity();
  shear(0, 1) = 1e5;
  const HandleTransform h = HandleTransform::from_matrix(shear, Eigen::Vector3d::Zero());
  const Eigen::Vector3d x(0.3, 0.7, -0.2);
  EXPECT_LT((h.apply(x, Eigen::Vector3d::Zero()) - (shear * x.homogeneous()).head<3>()).norm(),
            1e-6);
  auto message = [](const Eigen::Matrix4d& T) {
    try {
      HandleTransform::from_matrix(T, Eigen::Vector3d::Zero());
    } catch (const InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Eigen::Matrix4d flat = Eigen::Matrix4d::Identity();
  flat(2, 2) = 0;
  EXPECT_NE(message(flat).find("singular values 1, 1, 0"), std::string::npos) << message(flat);
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(1, 1) = -2;
  EXPECT_NE(message(mirror).find("reflection (det = -2"), std::string::npos) << message(mirror);
}

// Sweeps and automatic β solve with update_transient: the shared cache is left as it was.
TEST(Deformer, TransientUpdateLeavesTheCacheAlone) {
  const Benchmark& b = cactus();
  const ConstraintSet cs(b.mesh, b.constraints);
  cs.prepare({0.1, BetaUnits::area});  // the β > 0 pattern, built once and shared by all β
  const std::size_t before = cs.num_cached_factorizations();
  const std::size_t bytes = cs.memory_bytes();
  const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
  const Frame t = cs.update_transient(std::span(&h, 1), {0.4, BetaUnits::area});
  EXPECT_EQ(cs.num_cached_factorizations(), before);
  EXPECT_EQ(cs.memory_bytes(), bytes);
  const Frame f = cs.update(std::span(&h, 1), {0.4, BetaUnits::area});
  EXPECT_EQ(cs.num_cached_factorizations(), before + 1);
  EXPECT_LT((t.positions - f.positions).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Deformer, PolarDecompositionRoundTripsTheMatrix) {
  const Eigen::Matrix4d T = cactus().T;
  const Eigen::Vector3d p(0.1, 0.2, 0.3);
  const HandleTransform h = HandleTransform::from_matrix(T, p);
  for (int v = 0; v < 50; ++v) {
    const Eigen::Vector3d x = cactus().mesh->mesh().V.row(v * 13).transpose();
    EXPECT_LT((h.apply(x, p) - (T * x.homogeneous()).head<3>()).norm(), 1e-12);
  }
  EXPECT_NEAR(h.rotation.norm(), 1.0, 1e-12);
}

}  // namespace
}  // namespace hdeform

namespace hdeform {
namespace {

// update() is const and thread-safe: concurrent moves on one factorization (each with its
// own workspace; one of them gets the helper thread, the other runs its loops alone) give
// exactly the sequential results, exact and drag frames alike.
TEST(Deformer, ConcurrentUpdatesMatchSequentialOnes) {
  const auto& b = cactus();
  const ConstraintSet cs(b.mesh, b.constraints);
  std::vector<HandleTransform> hs(8);
  for (int i = 0; i < 8; ++i) hs[i].translation = Eigen::Vector3d(0.01 * i, 0.0, 0.02);
  UpdateOptions drag;
  drag.measures = drag.energies = false;
  drag.precision = FramePrecision::drag;
  for (const UpdateOptions& options : {UpdateOptions{}, drag}) {
    std::vector<Frame> expected;
    for (const auto& h : hs)
      expected.push_back(cs.update(std::span(&h, 1), {0.1, BetaUnits::area}, options));
    std::vector<Frame> got(hs.size());
    std::vector<std::thread> threads;
    for (int t = 0; t < 2; ++t)
      threads.emplace_back([&, t] {
        for (std::size_t i = t; i < hs.size(); i += 2)
          got[i] = cs.update(std::span(&hs[i], 1), {0.1, BetaUnits::area}, options);
      });
    for (auto& th : threads) th.join();
    for (std::size_t i = 0; i < hs.size(); ++i) {
      EXPECT_TRUE(got[i].positions == expected[i].positions) << i;
      EXPECT_TRUE(got[i].normals == expected[i].normals) << i;
      EXPECT_TRUE(got[i].energies == expected[i].energies) << i;
      EXPECT_EQ(got[i].measures.E, expected[i].measures.E) << i;
    }
  }
}

}  // namespace
}  // namespace hdeform

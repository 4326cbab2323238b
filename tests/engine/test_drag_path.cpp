// The drag path (SPEC.md §Drag frames) and the reusable move buffers
// (item 4): drag frames stay within kDragTolerance × bbox diagonal of the exact solve over
// whole drags (cold start, warm start, a jump), flags say what a frame is, and a workspace
// reused across moves allocates nothing and changes no bit of an exact frame.
#include "each_isa.h"
#include "fixtures.h"
#include "fixtures/procedural.h"

#include <gtest/gtest.h>

#include <cstdio>

namespace hdeform {
namespace {

// The benchmark's transform scaled to a fraction t of the way (t = 1: the .def itself).
HandleTransform part_way(const HandleTransform& h, double t) {
  HandleTransform p = h;
  p.rotation = Eigen::Quaterniond::Identity().slerp(t, h.rotation);
  p.stretch = (1 - t) * Eigen::Matrix3d::Identity() + t * h.stretch;
  p.translation = t * h.translation;
  return p;
}

double bbox_diagonal(const Vertices& V) {
  return (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
}

// Drags the handle through `ts` with drag frames from one workspace; returns the largest
// error against the exact solve, as a fraction of the bbox diagonal.
struct DragResult {
  double error = 0;  // largest, as a fraction of the bbox diagonal
  double solves = 0;  // mean float32 solves per frame
};

DragResult drag(const ConstraintSet& cs, const HandleTransform& h, Beta beta,
                const std::vector<double>& ts) {
  const double diag = bbox_diagonal(cs.mesh().mesh().V);
  UpdateWorkspace ws;
  Frame drag;
  UpdateOptions dragging;
  dragging.precision = FramePrecision::drag;
  dragging.measures = false;
  DragResult r;
  for (double t : ts) {
    const HandleTransform p = part_way(h, t);
    cs.update(std::span(&p, 1), beta, dragging, ws, drag);
    const Frame exact = cs.update(std::span(&p, 1), beta);
    EXPECT_FALSE(drag.exact);
    EXPECT_TRUE(exact.exact);
    r.error = std::max(r.error, (drag.positions - exact.positions).cwiseAbs().maxCoeff() / diag);
    r.solves += drag.solves / static_cast<double>(ts.size());
  }
  return r;
}

// A drag in 10 steps, a jump back to the start, a jump to the end (warm starts far from
// the answer), and a cold start at the end.
const std::vector<double> kDrag = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 0.0, 1.0};

// A transform that throws the surface out of range (beyond kMaxCoordinate, or to inf / NaN)
// is refused by name on both paths, and the drag that follows is as good as ever (a rejected
// solution is never a warm start).
TEST(DragPath, OutOfRangeResultsAreRefusedByNameAndLoseNothing) {
  const auto b = test::load_benchmark("cactus");
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
  UpdateWorkspace ws;
  Frame frame;
  UpdateOptions dragging;
  dragging.precision = FramePrecision::drag;
  const HandleTransform start = part_way(h, 0.5);
  cs.update(std::span(&start, 1), {0.0, BetaUnits::raw}, dragging, ws, frame);
  HandleTransform far = start, huge = start;
  far.translation = Eigen::Vector3d(2e30, 0, 0);  // finite targets beyond kMaxCoordinate
  huge.stretch = 1e300 * Eigen::Matrix3d::Identity();  // x − p times 1e300: inf
  for (const HandleTransform* bad : {&far, &huge})
    for (FramePrecision precision : {FramePrecision::exact, FramePrecision::drag}) {
      UpdateOptions o;
      o.precision = precision;
      try {
        cs.update(std::span(bad, 1), {0.0, BetaUnits::raw}, o, ws, frame);
        ADD_FAILURE() << "no error";
      } catch (const InvalidInput& e) {
        EXPECT_NE(std::string(e.what()).find("handle 0's transform"), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("moves the surface out of range"), std::string::npos)
            << e.what();
      }
    }
  const HandleTransform next = part_way(h, 0.6);
  cs.update(std::span(&next, 1), {0.0, BetaUnits::raw}, dragging, ws, frame);
  const Frame exact = cs.update(std::span(&next, 1), {0.0, BetaUnits::raw});
  EXPECT_LE((frame.positions - exact.positions).cwiseAbs().maxCoeff() /
                bbox_diagonal(b.mesh->mesh().V),
            kDragTolerance);
}

TEST(DragPath, BenchmarkDragsStayWithinToleranceOfTheExactSolve) {
  for (const char* model : {"bar", "cactus", "cylinder", "plane"}) {
    const auto b = test::load_benchmark(model);
    const ConstraintSet cs(b.mesh, b.constraints);
    const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
    for (double beta : {0.0, 0.5}) {
      const DragResult r = drag(cs, h, {beta, BetaUnits::area}, kDrag);
      std::printf("drag %-8s beta %.1f: error %.3g of the bbox diagonal, %.2f solves/frame\n",
                  model, beta, r.error, r.solves);
      EXPECT_LE(r.error, kDragTolerance) << model << " beta " << beta;
      const DragResult cold = drag(cs, h, {beta, BetaUnits::area}, {1.0});
      EXPECT_LE(cold.error, kDragTolerance) << model << " beta " << beta << " (cold start)";
    }
  }
}

TEST(DragPath, LargeCapsuleDragStaysWithinTolerance) {
  // Larger meshes have worse-conditioned K_FF: the float32 factor's error grows with n.
  const auto cc = procedural::capsule_case(40000);
  const auto pm = PreparedMesh::create(cc.mesh);
  const ConstraintSet cs(pm, Constraints{cc.base, {cc.cap}});
  HandleTransform h;
  h.rotation = Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitX());
  h.translation = Eigen::Vector3d(2.0, 0.5, -1.0);
  for (double beta : {0.0, 0.5}) {
    const DragResult r = drag(cs, h, {beta, BetaUnits::area}, kDrag);
    std::printf("drag capsule-40K beta %.1f: error %.3g of the bbox diagonal, %.2f solves/frame\n",
                beta, r.error, r.solves);
    EXPECT_LE(r.error, kDragTolerance) << "beta " << beta;
  }
}

TEST(DragPath, FlagsSayWhatAFrameHolds) {
  const auto b = test::load_benchmark("bar");
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
  UpdateWorkspace ws;
  Frame f;
  cs.update(std::span(&h, 1), {0.0}, UpdateOptions{}, ws, f);
  EXPECT_TRUE(f.exact);
  EXPECT_TRUE(f.has_measures);
  EXPECT_GT(f.measures.E, 0);
  EXPECT_EQ(f.energies.size(), b.mesh->m());
  EXPECT_EQ(f.normals.rows(), b.mesh->n());

  UpdateOptions bare{.energies = false, .normals = false, .measures = false,
                     .precision = FramePrecision::drag};
  cs.update(std::span(&h, 1), {0.0}, bare, ws, f);
  EXPECT_FALSE(f.exact);
  EXPECT_FALSE(f.has_measures);
  EXPECT_EQ(f.measures.E, 0);
  EXPECT_EQ(f.energies.size(), 0);
  EXPECT_EQ(f.normals.rows(), 0);

  bare.energies = true;  // energies come from the measures' pass: both are filled
  cs.update(std::span(&h, 1), {0.0}, bare, ws, f);
  EXPECT_TRUE(f.has_measures);
  EXPECT_EQ(f.energies.size(), b.mesh->m());
}

TEST(UpdateWorkspace, MovesReuseTheirBuffersAndGiveTheSameBits) {
  const auto b = test::load_benchmark("cactus");
  const ConstraintSet cs(b.mesh, b.constraints);
  const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
  for (double beta : {0.0, 0.5}) {
    UpdateWorkspace ws;
    Frame f;
    cs.update(std::span(&h, 1), {beta}, UpdateOptions{}, ws, f);
    const double* positions = f.positions.data();
    const double* normals = f.normals.data();
    const float* energies = f.energies.data();
    const std::size_t bytes = ws.memory_bytes();
    for (double t : {0.5, 0.75, 1.0}) {
      const HandleTransform p = part_way(h, t);
      cs.update(std::span(&p, 1), {beta}, UpdateOptions{}, ws, f);
      EXPECT_EQ(f.positions.data(), positions) << "a move reallocated the positions";
      EXPECT_EQ(f.normals.data(), normals) << "a move reallocated the normals";
      EXPECT_EQ(f.energies.data(), energies) << "a move reallocated the energies";
      EXPECT_EQ(ws.memory_bytes(), bytes);
      const Frame fresh = cs.update(std::span(&p, 1), {beta});
      EXPECT_TRUE(f.positions == fresh.positions) << "beta " << beta << " t " << t;
      EXPECT_TRUE(f.normals == fresh.normals);
      EXPECT_TRUE(f.energies == fresh.energies);
      EXPECT_EQ(f.measures.E, fresh.measures.E);
    }
  }
}

// The gathering, parallel vertex normals give the same bits as mesh_io's serial scatter, in
// each build of the kernels (vertex_normals_kernels.h).
class VertexNormals : public test::OnEachIsa {};

TEST_P(VertexNormals, GatherEqualsTheSerialScatterBitwise) {
  for (const char* model : {"bar", "cactus", "cylinder", "plane"}) {
    const auto b = test::load_benchmark(model);
    const ConstraintSet cs(b.mesh, b.constraints);
    const HandleTransform h = HandleTransform::from_matrix(b.T, cs.centroid(0));
    // With measures, the normals reuse the measures' face weights; without, their own pass.
    const Frame f = cs.update(std::span(&h, 1), {0.3});
    const Vertices serial = vertex_normals(f.positions, b.mesh->mesh().F);
    EXPECT_TRUE(f.normals == serial) << model;
    UpdateOptions bare;
    bare.measures = bare.energies = false;
    const Frame g = cs.update(std::span(&h, 1), {0.3}, bare);
    EXPECT_FALSE(g.has_measures);
    EXPECT_TRUE(g.normals == serial) << model;
  }
  // A vertex no triangle uses gets a zero normal, as in the serial version.
  Vertices V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5;
  Triangles F(1, 3);
  F << 0, 1, 2;
  Vertices w, N;
  vertex_normals(V, F, VertexTriangles::build(4, F), w, N);
  EXPECT_TRUE(N == vertex_normals(V, F));
  EXPECT_EQ(N.row(3).norm(), 0.0);
}

INSTANTIATE_TEST_SUITE_P(Isa, VertexNormals, test::kEachIsa, test::isa_param_name);

}  // namespace
}  // namespace hdeform

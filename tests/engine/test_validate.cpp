// Mesh validation: one test per error class, each on a small hand-made bad mesh.
#include "engine/mesh/validate.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <string>

namespace hdeform {
namespace {

using test::tetra;

void add_vertex(TriMesh& m, double x, double y, double z) {
  m.V.conservativeResize(m.V.rows() + 1, 3);
  m.V.row(m.V.rows() - 1) << x, y, z;
}

void add_triangle(TriMesh& m, int a, int b, int c) {
  m.F.conservativeResize(m.F.rows() + 1, 3);
  m.F.row(m.F.rows() - 1) << a, b, c;
}

// An nx × ny grid of vertices (i, j, height(i, j)), two triangles a cell.
template <class Height>
TriMesh grid(int nx, int ny, Height height) {
  TriMesh m;
  m.V.resize(nx * ny, 3);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) m.V.row(j * nx + i) << i, j, height(i, j);
  m.F.resize(2 * (nx - 1) * (ny - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int a = j * nx + i;
      m.F.row(t++) << a, a + 1, a + nx + 1;
      m.F.row(t++) << a, a + nx + 1, a + nx;
    }
  return m;
}

// The message of the InvalidInput validate_mesh throws ("" if it does not throw).
std::string error_of(const TriMesh& m) {
  try {
    validate_mesh(m);
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << "message: " << (haystack)

TEST(Validate, TetrahedronIsValid) {
  const ValidationResult r = validate_mesh(tetra());
  EXPECT_TRUE(r.unreferenced.empty());
  EXPECT_TRUE(r.warnings.empty());
}

TEST(Validate, OpenSurfaceWithBoundaryIsValid) {
  // A 30×20 grid: boundary edges (one triangle) are fine, so is every boundary vertex fan.
  const TriMesh m = grid(30, 20, [](int i, int j) { return 0.1 * std::sin(i + j); });
  EXPECT_EQ(error_of(m), "");
}

TEST(Validate, EmptyMesh) {
  TriMesh none;
  EXPECT_CONTAINS(error_of(none), "empty mesh: no vertices");
  TriMesh no_tris;
  no_tris.V = tetra().V;
  EXPECT_CONTAINS(error_of(no_tris), "empty mesh: no triangles (4 vertices)");
}

TEST(Validate, IndexOutOfRange) {
  TriMesh m = tetra();
  m.F(2, 1) = 9;
  m.F(3, 0) = -1;
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "triangle index out of range: 2 triangles use vertex ids outside [0, 4)");
  EXPECT_CONTAINS(e, "triangle 2 uses vertex 9");
  EXPECT_CONTAINS(e, "triangle 3 uses vertex -1");
}

TEST(Validate, NonFiniteCoordinates) {
  TriMesh m = tetra();
  m.V(3, 1) = std::numeric_limits<double>::quiet_NaN();
  m.V(1, 2) = std::numeric_limits<double>::infinity();
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "non-finite coordinates: 2 vertices have NaN or infinite coordinates");
  EXPECT_CONTAINS(e, "vertices 1, 3");
}

TEST(Validate, ZeroAreaTriangles) {
  // Vertex 4 on edge 0–1 (collinear triangle 4) and triangle 5 with a repeated corner.
  TriMesh m = tetra();
  add_vertex(m, 0.5, 0, 0);
  add_triangle(m, 0, 4, 1);
  add_triangle(m, 2, 2, 3);
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "zero-area triangles: 2 triangles have area");
  EXPECT_CONTAINS(e, "triangles 4, 5");
}

TEST(Validate, TinyButNonZeroTrianglesPass) {
  // Area 1e-10 with bbox diagonal² = 3: well above the 1e-14 · 3 threshold.
  TriMesh m = tetra();
  m.V.row(3) << 0, 0, 1e-5;
  add_vertex(m, 1, 1, 1);  // keeps the bbox diagonal² at 3
  const ValidationResult r = validate_mesh(m);
  EXPECT_EQ(r.unreferenced, std::vector<int>{4});
}

TEST(Validate, NonManifoldEdgeWithThreeTriangles) {
  // A fin: triangles 0, 1, 2 all contain edge 0–1.
  TriMesh m;
  m.V.resize(5, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
  m.F.resize(3, 3);
  m.F << 0, 1, 2, 1, 0, 3, 0, 4, 1;
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "non-manifold edge: 1 edge has more than two triangles");
  EXPECT_CONTAINS(e, "vertices 0–1, triangles 0, 1, 2");
}

TEST(Validate, DuplicateTrianglesAreNamedAsSuch) {
  // A face written twice, in either orientation, is not reported as an edge problem.
  for (const bool flipped : {false, true}) {
    TriMesh m = tetra();
    m.F.conservativeResize(5, 3);
    m.F.row(4) = m.F.row(1);
    if (flipped) m.F.row(4) << m.F(1, 0), m.F(1, 2), m.F(1, 1);
    const std::string e = error_of(m);
    EXPECT_CONTAINS(e, "duplicate triangles: 1 triangle has the same three vertices as an earlier one");
    EXPECT_CONTAINS(e, "triangle 4 repeats triangle 1");
  }
}

TEST(Validate, InconsistentOrientation) {
  // Flip one face of the tetrahedron: its 3 edges are each used twice in the same direction.
  TriMesh m = tetra();
  m.F.row(2) << 1, 3, 2;
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "inconsistent orientation");
  EXPECT_CONTAINS(e, "3 edges are used twice in the same direction");
  EXPECT_CONTAINS(e, "vertices 1–2, triangles 0, 2");
}

TEST(Validate, NonManifoldVertexBowtie) {
  // Two triangles touching only at vertex 2.
  TriMesh m;
  m.V.resize(5, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0, 2, 0, 1, 2, 0;
  m.F.resize(2, 3);
  m.F << 0, 1, 2, 2, 4, 3;
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "non-manifold vertex: 1 vertex has triangles forming more than one fan");
  EXPECT_CONTAINS(e, "vertex 2 (2 fans)");
}

TEST(Validate, NonManifoldVertexTwoClosedTetrahedra) {
  // Two closed tetrahedra sharing vertex 0: every edge is manifold, vertex 0 has two fans.
  TriMesh a = tetra();
  TriMesh m;
  m.V.resize(7, 3);
  m.V.topRows(4) = a.V;
  m.V.bottomRows(3) << -1, 0, 0, 0, -1, 0, 0, 0, -1;
  m.F.resize(8, 3);
  m.F.topRows(4) = a.F;
  // Mirror image of the first (x, y, z → −x, −y, −z), orientation reversed to stay outward.
  m.F.bottomRows(4) << 0, 5, 4, 0, 4, 6, 4, 5, 6, 0, 6, 5;
  const std::string e = error_of(m);
  EXPECT_CONTAINS(e, "non-manifold vertex: 1 vertex");
  EXPECT_CONTAINS(e, "vertex 0 (2 fans)");
}

TEST(Validate, UnreferencedVerticesAreReportedNotRejected) {
  TriMesh m = tetra();
  add_vertex(m, 5, 5, 5);
  add_vertex(m, 6, 6, 6);
  const ValidationResult r = validate_mesh(m);
  EXPECT_EQ(r.unreferenced, (std::vector<int>{4, 5}));
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_CONTAINS(r.warnings[0], "2 unreferenced vertices (first: 4, 5)");
}

TEST(Validate, LargeGridIsFast) {
  // 500×500 = 250K vertices, ~500K triangles; the check is near-linear.
  const TriMesh m = grid(500, 500, [](int, int) { return 0.0; });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NO_THROW(validate_mesh(m));
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
#ifdef NDEBUG
  EXPECT_LT(s, 5.0);  // generous (sanitizers, busy machine); an -O2 build takes ≈ 0.1 s
#else
  (void)s;  // unoptimised builds: correctness only
#endif
}

}  // namespace
}  // namespace hdeform

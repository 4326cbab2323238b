// Mesh repair: each defect alone and together, the maps back to input ids, bit-for-bit
// identity on valid meshes, idempotence, and a repaired file written back through its layout.
#include "engine/io/repair_loaded.h"
#include "engine/mesh/repair.h"
#include "engine/mesh/validate.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace hdeform {
namespace {

using test::data_path;
using test::same_bits;

using test::tetra;

int add_vertex(TriMesh& m, double x, double y, double z) {
  m.V.conservativeResize(m.V.rows() + 1, 3);
  m.V.row(m.V.rows() - 1) << x, y, z;
  return static_cast<int>(m.V.rows() - 1);
}

void add_triangle(TriMesh& m, int a, int b, int c) {
  m.F.conservativeResize(m.F.rows() + 1, 3);
  m.F.row(m.F.rows() - 1) << a, b, c;
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

bool same_row_bits(const Vertices& a, Eigen::Index i, const Vertices& b, Eigen::Index j) {
  const double ra[3] = {a(i, 0), a(i, 1), a(i, 2)}, rb[3] = {b(j, 0), b(j, 1), b(j, 2)};
  return std::memcmp(ra, rb, sizeof ra) == 0;
}

std::vector<int> iota_of(int n) {
  std::vector<int> v(static_cast<size_t>(n));
  std::iota(v.begin(), v.end(), 0);
  return v;
}

bool mentions(const RepairReport& r, const std::string& text) {
  for (const std::string& line : r.lines)
    if (line.find(text) != std::string::npos) return true;
  return false;
}

std::string lines_of(const RepairReport& r) {
  std::string s;
  for (const std::string& line : r.lines) s += line + "\n";
  return s;
}

// The invariants every repair result keeps, whatever the input: repaired positions are input
// positions bit for bit, the maps are inverse where defined, kept triangles ascend, and each
// repaired triangle's corners sit where the input triangle's corners sat (merging keeps the
// survivor's position; exact merging only joins equal positions).
void expect_consistent(const TriMesh& in, const RepairResult& r, bool exact = true) {
  const int n = r.mesh.num_vertices();
  ASSERT_EQ(r.to_input.size(), static_cast<size_t>(n));
  ASSERT_EQ(r.from_input.size(), static_cast<size_t>(in.num_vertices()));
  ASSERT_EQ(r.kept_triangles.size(), static_cast<size_t>(r.mesh.num_triangles()));
  EXPECT_TRUE(std::is_sorted(r.kept_triangles.begin(), r.kept_triangles.end()));
  EXPECT_EQ(std::adjacent_find(r.kept_triangles.begin(), r.kept_triangles.end()), r.kept_triangles.end());
  EXPECT_EQ(n, r.mesh.num_vertices());
  std::set<int> survivors(r.from_input.begin(), r.from_input.end());
  survivors.erase(-1);
  EXPECT_EQ(static_cast<int>(survivors.size()) + r.report.added_vertices, n);
  for (int j = 0; j < n; ++j) {
    const int i = r.to_input[static_cast<size_t>(j)];
    ASSERT_GE(i, 0);
    ASSERT_LT(i, in.num_vertices());
    EXPECT_TRUE(same_row_bits(in.V, i, r.mesh.V, j)) << "repaired vertex " << j;
    ASSERT_GE(r.from_input[static_cast<size_t>(i)], 0) << "input vertex " << i << " is used but maps to -1";
    if (j < n - r.report.added_vertices) {  // not a split's copy: the maps are inverse
      EXPECT_EQ(r.from_input[static_cast<size_t>(i)], j);
    }
  }
  for (int i = 0; i < in.num_vertices(); ++i) {
    const int j = r.from_input[static_cast<size_t>(i)];
    if (j < 0) continue;
    ASSERT_LT(j, n);
    if (exact) {
      EXPECT_EQ(in.V.row(i), r.mesh.V.row(j)) << "input vertex " << i;
    }
  }
  for (int t = 0; t < r.mesh.num_triangles(); ++t) {
    const int s = r.kept_triangles[static_cast<size_t>(t)];
    for (int k = 0; k < 3; ++k) {
      const int v = r.mesh.F(t, k);
      ASSERT_GE(v, 0);
      ASSERT_LT(v, n);
      EXPECT_TRUE(same_row_bits(in.V, r.to_input[static_cast<size_t>(v)], r.mesh.V, v));
      if (exact) {
        EXPECT_EQ(in.V.row(in.F(s, k)), r.mesh.V.row(v)) << "triangle " << t << " corner " << k;
      }
    }
  }
}

void expect_unchanged(const TriMesh& in, const RepairResult& r) {
  EXPECT_FALSE(r.report.changed()) << lines_of(r.report);
  EXPECT_TRUE(r.report.lines.empty());
  EXPECT_TRUE(same_bits(in.V, r.mesh.V));
  EXPECT_EQ(in.F, r.mesh.F);
  EXPECT_EQ(r.to_input, iota_of(in.num_vertices()));
  EXPECT_EQ(r.from_input, iota_of(in.num_vertices()));
  EXPECT_EQ(r.kept_triangles, iota_of(in.num_triangles()));
}

// Repairing the result again changes nothing.
void expect_idempotent(const RepairResult& r, const RepairOptions& options = {}) {
  const RepairResult again = repair_mesh(r.mesh, options);
  expect_unchanged(r.mesh, again);
}

// Every edge used by exactly two triangles.
bool closed(const TriMesh& m) {
  std::map<std::pair<int, int>, int> uses;
  for (int t = 0; t < m.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = m.F(t, k), b = m.F(t, (k + 1) % 3);
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  for (const auto& [edge, count] : uses)
    if (count != 2) return false;
  return !uses.empty();
}

TEST(Repair, ExactDuplicateVerticesAreMerged) {
  TriMesh m = tetra();
  const int d = add_vertex(m, 0, 0, 0);  // a copy of vertex 0 used by the last triangle
  m.F.row(3) << d, 3, 2;
  EXPECT_FALSE(closed(m));  // a slit along edges 0–2 and 0–3
  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.merged_vertices, 1);
  EXPECT_EQ(r.report.degenerate_triangles + r.report.duplicate_triangles + r.report.unreferenced_vertices +
                r.report.split_vertices,
            0);
  ASSERT_EQ(r.report.lines.size(), 1u);
  EXPECT_NE(r.report.lines[0].find("merged 1 duplicate vertex"), std::string::npos) << r.report.lines[0];
  EXPECT_NE(r.report.lines[0].find("4→0"), std::string::npos) << r.report.lines[0];
  EXPECT_TRUE(same_bits(r.mesh.V, tetra().V));
  EXPECT_EQ(r.mesh.F, tetra().F);
  EXPECT_EQ(r.from_input, (std::vector<int>{0, 1, 2, 3, 0}));
  EXPECT_EQ(r.to_input, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(error_of(r.mesh), "");
  EXPECT_TRUE(closed(r.mesh));
  expect_consistent(m, r);
  expect_idempotent(r);
}

TEST(Repair, SignedZerosAreTheSamePosition) {
  TriMesh m = tetra();
  const int d = add_vertex(m, -0.0, 0, -0.0);
  m.F.row(3) << d, 3, 2;
  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.merged_vertices, 1);
  EXPECT_TRUE(same_bits(r.mesh.V, tetra().V));  // the survivor keeps its own bits (+0)
  EXPECT_EQ(error_of(r.mesh), "");
}

TEST(Repair, ToleranceMergesWithinItButNotWithout) {
  TriMesh m = tetra();
  const int d = add_vertex(m, 1e-9, -1e-9, 0);  // |Δ| ≈ 1.4e-9; bbox diagonal √3
  m.F.row(3) << d, 3, 2;

  const RepairResult exact = repair_mesh(m);
  EXPECT_EQ(exact.report.merged_vertices, 0);
  EXPECT_FALSE(exact.report.changed());
  expect_unchanged(m, exact);

  RepairOptions tight;
  tight.merge_tolerance = 1e-10;  // 1.7e-10 < 1.4e-9
  EXPECT_EQ(repair_mesh(m, tight).report.merged_vertices, 0);

  RepairOptions loose;
  loose.merge_tolerance = 1e-8;  // 1.7e-8 > 1.4e-9
  const RepairResult r = repair_mesh(m, loose);
  EXPECT_EQ(r.report.merged_vertices, 1);
  EXPECT_TRUE(mentions(r.report, "4→0")) << lines_of(r.report);
  EXPECT_TRUE(mentions(r.report, "within 1e-08 × bbox diagonal")) << lines_of(r.report);
  EXPECT_TRUE(same_bits(r.mesh.V, tetra().V));  // merged into vertex 0, whose bits stay
  EXPECT_EQ(r.mesh.F, tetra().F);
  EXPECT_EQ(error_of(r.mesh), "");
  expect_consistent(m, r, false);
  expect_idempotent(r, loose);
}

// Merging goes to the earliest survivor within the tolerance, never through a chain: a row of
// points 0.6·tol apart merges pairwise, not all into the first.
TEST(Repair, ToleranceMergesIntoSurvivorsOnly) {
  TriMesh m;
  const double step = 0.6e-3;
  for (int i = 0; i < 6; ++i) add_vertex(m, i * step, 0, 0);
  add_vertex(m, 0, 1, 0);
  add_vertex(m, 0, 0, 1);
  add_triangle(m, 0, 6, 7);
  add_triangle(m, 2, 6, 7);
  add_triangle(m, 4, 6, 7);
  RepairOptions o;
  o.merge_tolerance = 1e-3 / std::sqrt(2.0 + (5 * step) * (5 * step));  // tol · diag = 1e-3
  const RepairResult r = repair_mesh(m, o);
  // 1 → 0; 2 is 1.2e-3 from 0: a survivor; 3 → 2; 4 survives; 5 → 4. The triangles on
  // edge 6–7 are separate sheets: each keeps its own vertices.
  EXPECT_EQ(r.report.merged_vertices, 3);
  EXPECT_TRUE(mentions(r.report, "1→0, 3→2, 5→4")) << lines_of(r.report);
}

// A tolerance merge of many points stays fast (grid hash, not all pairs): 90 000 points, each
// also present with a jitter inside the tolerance, and 20 000 copies of one point.
TEST(Repair, ToleranceMergeOfManyPointsIsLinear) {
  TriMesh m;
  const int k = 150;
  m.V.resize(2 * k * k + 20000, 3);
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) {
      m.V.row(j * k + i) << i, j, 0;
      m.V.row(k * k + j * k + i) << i + 1e-7, j - 1e-7, 1e-7;
    }
  for (int i = 0; i < 20000; ++i) m.V.row(2 * k * k + i) << 7, 7, 0;
  m.F.resize(2 * (k - 1) * (k - 1), 3);  // the first grid, triangulated
  int t = 0;
  for (int j = 0; j + 1 < k; ++j)
    for (int i = 0; i + 1 < k; ++i) {
      const int a = j * k + i;
      m.F.row(t++) << a, a + 1, a + k + 1;
      m.F.row(t++) << a, a + k + 1, a + k;
    }
  RepairOptions o;
  o.merge_tolerance = 1e-6;
  const RepairResult r = repair_mesh(m, o);
  EXPECT_EQ(r.report.merged_vertices, k * k + 20000);
  EXPECT_EQ(r.report.unreferenced_vertices, 0);
  EXPECT_EQ(r.mesh.num_vertices(), k * k);
  EXPECT_EQ(r.mesh.F, m.F);
  EXPECT_EQ(error_of(r.mesh), "");
}

// What Blender writes with "split faces" (or an STL): every face of a quad cube carries its own
// four vertices. Merging gives the closed cube back, which validate_mesh accepts.
TEST(Repair, QuadCubeWrittenAsSeparateFacesBecomesClosed) {
  const int corners[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  const double xyz[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  std::string obj;
  for (const auto& face : corners)
    for (int c : face)
      obj += "v " + std::to_string(xyz[c][0]) + " " + std::to_string(xyz[c][1]) + " " + std::to_string(xyz[c][2]) + "\n";
  for (int f = 0; f < 6; ++f)
    obj += "f " + std::to_string(4 * f + 1) + " " + std::to_string(4 * f + 2) + " " + std::to_string(4 * f + 3) +
           " " + std::to_string(4 * f + 4) + "\n";
  const LoadedMesh in = read_mesh_bytes(obj, "split.obj");
  ASSERT_EQ(in.mesh.num_vertices(), 24);
  ASSERT_EQ(in.mesh.num_triangles(), 12);
  EXPECT_FALSE(closed(in.mesh));

  const RepairResult r = repair_mesh(in.mesh);
  EXPECT_EQ(r.report.merged_vertices, 16);
  EXPECT_EQ(r.mesh.num_vertices(), 8);
  EXPECT_EQ(r.mesh.num_triangles(), 12);
  EXPECT_TRUE(closed(r.mesh));
  EXPECT_EQ(error_of(r.mesh), "");
  EXPECT_TRUE(validate_mesh(r.mesh).warnings.empty());
  expect_consistent(in.mesh, r);
  expect_idempotent(r);
}

TEST(Repair, DegenerateTrianglesAreDropped) {
  TriMesh m = tetra();
  add_triangle(m, 0, 0, 1);                    // 4: a repeated corner
  const int mid = add_vertex(m, 0.5, 0, 0);    // on edge 0–1
  add_triangle(m, 0, 1, mid);                  // 5: collinear, zero area
  const int dup = add_vertex(m, 0, 1, 0);      // a copy of vertex 2
  add_triangle(m, 2, 3, dup);                  // 6: a repeated corner once merged
  EXPECT_NE(error_of(m).find("zero-area"), std::string::npos) << error_of(m);

  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.degenerate_triangles, 3);
  EXPECT_EQ(r.report.merged_vertices, 1);
  EXPECT_EQ(r.report.unreferenced_vertices, 1);  // mid, used only by a dropped triangle
  EXPECT_TRUE(mentions(r.report, "dropped 3 degenerate triangles")) << lines_of(r.report);
  EXPECT_TRUE(mentions(r.report, "first: triangles 4, 5, 6")) << lines_of(r.report);
  EXPECT_TRUE(mentions(r.report, "dropped 1 unreferenced vertex (no remaining triangle uses it) (first: 4)"))
      << lines_of(r.report);
  EXPECT_EQ(r.kept_triangles, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_TRUE(same_bits(r.mesh.V, tetra().V));
  EXPECT_EQ(r.mesh.F, tetra().F);
  EXPECT_EQ(error_of(r.mesh), "");
  expect_consistent(m, r);
  expect_idempotent(r);
}

// The area threshold is validate_mesh's, from the shared constant: a sliver just above it is
// kept (and accepted), one at it is dropped (and would be refused).
TEST(Repair, AreaThresholdIsValidatesOne) {
  for (const double height : {1e-12, 1e-15}) {
    TriMesh m;
    add_vertex(m, 0, 0, 0);
    add_vertex(m, 1, 0, 0);
    add_vertex(m, 0.5, height, 0);
    add_vertex(m, 0, 0, 1);  // bbox diagonal² ≈ 2
    add_triangle(m, 0, 1, 2);
    add_triangle(m, 0, 3, 1);
    const bool sliver_ok = 0.5 * height > kZeroAreaScale * 2;
    const RepairResult r = repair_mesh(m);
    EXPECT_EQ(r.report.degenerate_triangles, sliver_ok ? 0 : 1) << height;
    EXPECT_EQ(error_of(m).find("zero-area") == std::string::npos, sliver_ok) << height;
    EXPECT_EQ(error_of(r.mesh), "") << height;
  }
}

TEST(Repair, DuplicateTrianglesAreDropped) {
  TriMesh m = tetra();
  add_triangle(m, 2, 1, 0);  // 4: triangle 0 rotated
  add_triangle(m, 0, 3, 1);  // 5: triangle 1 the other way round
  add_triangle(m, 1, 3, 0);  // 6: triangle 1 again
  EXPECT_NE(error_of(m), "");
  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.duplicate_triangles, 3);
  EXPECT_TRUE(mentions(r.report, "first: triangle 4 repeats 0, 5 repeats 1, 6 repeats 1")) << lines_of(r.report);
  EXPECT_EQ(r.kept_triangles, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(r.mesh.F, tetra().F);
  EXPECT_TRUE(same_bits(r.mesh.V, tetra().V));
  EXPECT_EQ(error_of(r.mesh), "");
  expect_consistent(m, r);
  expect_idempotent(r);
}

// Two tetrahedra touching at vertex 0: its triangles form two fans. The fan of its earliest
// triangle keeps id 0; the other gets a copy appended at the end.
TEST(Repair, BowtieIsSplitIntoAManifold) {
  TriMesh m = tetra();
  add_vertex(m, -1, 0, 0);  // 4
  add_vertex(m, 0, -1, 0);  // 5
  add_vertex(m, 0, 0, -1);  // 6
  add_triangle(m, 0, 4, 5);
  add_triangle(m, 0, 6, 4);
  add_triangle(m, 4, 6, 5);
  add_triangle(m, 0, 5, 6);
  EXPECT_NE(error_of(m).find("non-manifold vertex"), std::string::npos) << error_of(m);

  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.split_vertices, 1);
  EXPECT_EQ(r.report.added_vertices, 1);
  EXPECT_TRUE(mentions(r.report, "split 1 non-manifold vertex")) << lines_of(r.report);
  EXPECT_TRUE(mentions(r.report, "vertex 0 (2 fans)")) << lines_of(r.report);
  ASSERT_EQ(r.mesh.num_vertices(), 8);
  EXPECT_EQ(r.to_input, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 0}));
  EXPECT_EQ(r.from_input, iota_of(7));
  EXPECT_EQ(r.mesh.F.topRows(4), tetra().F);
  for (int t = 4; t < 8; ++t)
    for (int k = 0; k < 3; ++k) EXPECT_NE(r.mesh.F(t, k), 0) << t;
  EXPECT_EQ(r.mesh.F(4, 0), 7);
  EXPECT_EQ(error_of(r.mesh), "");
  EXPECT_TRUE(closed(r.mesh));
  expect_consistent(m, r);
  expect_idempotent(r);
}

// Sheets that only touch where their own coincident vertices sit are left alone: merging
// would make a bowtie or a fin, so each fan keeps its own input vertex. Both inputs are valid
// and come back identical.
TEST(Repair, TouchingSheetsKeepTheirOwnVertices) {
  TriMesh touching = tetra();  // a second tetrahedron touching the first at the origin
  add_vertex(touching, 0, 0, 0);   // 4: the touch point, its own id
  add_vertex(touching, -1, 0, 0);  // 5
  add_vertex(touching, 0, -1, 0);  // 6
  add_vertex(touching, 0, 0, -1);  // 7
  add_triangle(touching, 4, 5, 6);
  add_triangle(touching, 4, 7, 5);
  add_triangle(touching, 5, 7, 6);
  add_triangle(touching, 4, 6, 7);
  ASSERT_EQ(error_of(touching), "");
  expect_unchanged(touching, repair_mesh(touching));

  TriMesh fin;  // three triangles along one positional edge, each with its own two ends
  for (int f = 0; f < 3; ++f) {
    const int a = add_vertex(fin, 0, 0, 0), b = add_vertex(fin, 1, 0, 0);
    const int c = add_vertex(fin, 0.5, std::cos(2.0 * f), std::sin(2.0 * f));
    add_triangle(fin, a, b, c);
  }
  ASSERT_EQ(error_of(fin), "");
  expect_unchanged(fin, repair_mesh(fin));
  RepairOptions o;
  o.merge_tolerance = 1e-3;
  expect_unchanged(fin, repair_mesh(fin, o));
}

// Three open triangles around one vertex, no edge shared: three fans, two copies; the
// report counts vertices split and copies added.
TEST(Repair, ThreeFansGiveTwoCopies) {
  TriMesh m;
  add_vertex(m, 0, 0, 0);
  for (int f = 0; f < 3; ++f) {
    const double a = f * 2.0;
    const int p = add_vertex(m, std::cos(a), std::sin(a), 0);
    const int q = add_vertex(m, std::cos(a + 0.5), std::sin(a + 0.5), 0.1 * f);
    add_triangle(m, 0, p, q);
  }
  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.split_vertices, 1);
  EXPECT_EQ(r.report.added_vertices, 2);
  EXPECT_TRUE(mentions(r.report, "2 copies appended")) << lines_of(r.report);
  EXPECT_EQ(r.mesh.num_vertices(), 9);
  EXPECT_EQ(r.mesh.F(0, 0), 0);
  EXPECT_EQ(r.mesh.F(1, 0), 7);
  EXPECT_EQ(r.mesh.F(2, 0), 8);
  EXPECT_EQ(error_of(r.mesh), "");
  expect_consistent(m, r);
  expect_idempotent(r);
}

// Two fans of 100 000 triangles each around one vertex: no recursion, linear work.
TEST(Repair, HugeFansAreSplitWithoutRecursion) {
  const int k = 100000;
  TriMesh m;
  m.V.resize(2 * (k + 1) + 1, 3);
  m.V.row(0) << 0, 0, 0;
  m.F.resize(2 * k, 3);
  for (int i = 0; i <= k; ++i) {
    const double a = 1.5 * M_PI * i / k;
    m.V.row(1 + i) << std::cos(a), std::sin(a), 0;      // a fan in the plane z = 0
    m.V.row(2 + k + i) << 0, 2 * std::cos(a), 2 * std::sin(a);  // and one in x = 0
  }
  for (int i = 0; i < k; ++i) {
    m.F.row(i) << 0, 1 + i, 2 + i;
    m.F.row(k + i) << 0, 2 + k + i, 3 + k + i;
  }
  EXPECT_NE(error_of(m).find("non-manifold vertex"), std::string::npos);
  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.split_vertices, 1);
  EXPECT_EQ(r.report.added_vertices, 1);
  EXPECT_EQ(error_of(r.mesh), "");
  for (int i = k; i < 2 * k; ++i) ASSERT_EQ(r.mesh.F(i, 0), r.mesh.num_vertices() - 1);
}

TEST(Repair, UnreferencedVerticesAreDroppedInOrder) {
  TriMesh m;
  add_vertex(m, 9, 9, 9);  // 0: stray
  add_vertex(m, 0, 0, 0);  // 1
  add_vertex(m, 8, 8, 8);  // 2: stray
  add_vertex(m, 1, 0, 0);  // 3
  add_vertex(m, 0, 1, 0);  // 4
  add_vertex(m, 0, 0, 1);  // 5
  add_vertex(m, 7, 7, 7);  // 6: stray
  const TriMesh t = tetra();
  const int ids[4] = {1, 3, 4, 5};
  for (int f = 0; f < 4; ++f) add_triangle(m, ids[t.F(f, 0)], ids[t.F(f, 1)], ids[t.F(f, 2)]);
  EXPECT_EQ(validate_mesh(m).unreferenced, (std::vector<int>{0, 2, 6}));

  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.unreferenced_vertices, 3);
  EXPECT_TRUE(mentions(r.report, "dropped 3 unreferenced vertices")) << lines_of(r.report);
  EXPECT_TRUE(mentions(r.report, "(first: 0, 2, 6)")) << lines_of(r.report);
  EXPECT_EQ(r.to_input, (std::vector<int>{1, 3, 4, 5}));
  EXPECT_EQ(r.from_input, (std::vector<int>{-1, 0, -1, 1, 2, 3, -1}));
  EXPECT_TRUE(same_bits(r.mesh.V, t.V));
  EXPECT_EQ(r.mesh.F, t.F);
  EXPECT_TRUE(validate_mesh(r.mesh).unreferenced.empty());
  expect_consistent(m, r);
  expect_idempotent(r);
}

// More than two triangles on an edge is not repaired: the fin stays one fan at both ends,
// so validate_mesh still refuses it with its own message (also after other repairs).
TEST(Repair, NonManifoldEdgeIsLeftForValidation) {
  TriMesh m;
  add_vertex(m, 0, 0, 0);
  add_vertex(m, 1, 0, 0);
  add_vertex(m, 0, 1, 0);
  add_vertex(m, 0, -1, 0);
  add_vertex(m, 0, 0, 1);
  add_triangle(m, 0, 1, 2);
  add_triangle(m, 1, 0, 3);
  add_triangle(m, 0, 1, 4);
  const std::string before = error_of(m);
  EXPECT_NE(before.find("non-manifold edge"), std::string::npos) << before;
  const RepairResult same = repair_mesh(m);
  expect_unchanged(m, same);

  const int d = add_vertex(m, 0, 0, 1);  // a duplicate of 4, in a repeat of triangle 2
  add_triangle(m, 1, 0, d);
  const int e = add_vertex(m, 1, 1, 1);  // and a fourth triangle on the edge
  add_triangle(m, 1, 0, e);
  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.merged_vertices, 1);
  EXPECT_EQ(r.report.duplicate_triangles, 1);
  EXPECT_EQ(r.report.split_vertices, 0);
  EXPECT_EQ(r.mesh.num_vertices(), 6);
  EXPECT_NE(error_of(r.mesh).find("non-manifold edge"), std::string::npos) << error_of(r.mesh);
  expect_consistent(m, r);
}

// A misoriented edge is not cut apart either.
TEST(Repair, InconsistentOrientationIsLeftForValidation) {
  TriMesh m = tetra();
  m.F.row(3) << 0, 2, 3;  // flipped
  const RepairResult r = repair_mesh(m);
  expect_unchanged(m, r);
  EXPECT_NE(error_of(r.mesh).find("inconsistent orientation"), std::string::npos) << error_of(r.mesh);
}

// Every bundled mesh is valid, without unreferenced or coincident vertices.
TEST(Repair, ValidMeshesAreUnchangedBitForBit) {
  for (const std::string name : {"botsch-sorkine/cactus.off", "botsch-sorkine/bar.off", "botsch-sorkine/cylinder.off",
                                 "models/bunny.off", "models/cow.off", "models/hand.off", "models/horse.obj",
                                 "models/knight.off"}) {
    SCOPED_TRACE(name);
    const LoadedMesh in = read_mesh(data_path(name));
    ASSERT_EQ(error_of(in.mesh), "") << name;
    ASSERT_TRUE(validate_mesh(in.mesh).unreferenced.empty()) << name;
    const RepairResult r = repair_mesh(in.mesh);
    expect_unchanged(in.mesh, r);
    RepairOptions o;
    o.merge_tolerance = 1e-9;  // far below any edge of these meshes
    expect_unchanged(in.mesh, repair_mesh(in.mesh, o));
  }
}

// Every defect at once, on a real mesh: its faces split apart at one vertex (a duplicate),
// a degenerate and a duplicate triangle, a second surface touching it at one vertex, and
// stray vertices. The result validates, maps back consistently, and repairs to itself.
TEST(Repair, AllDefectsTogether) {
  const TriMesh base = read_mesh(data_path("botsch-sorkine/cactus.off")).mesh;
  TriMesh m = base;
  const int n = base.num_vertices();
  // Duplicate vertex 0 for the triangles of its last use.
  const int dup = add_vertex(m, m.V(0, 0), m.V(0, 1), m.V(0, 2));
  int last = -1;
  for (int t = 0; t < m.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k)
      if (m.F(t, k) == 0) last = t;
  ASSERT_GE(last, 0);
  for (int k = 0; k < 3; ++k)
    if (m.F(last, k) == 0) m.F(last, k) = dup;
  add_triangle(m, 1, 1, 2);                        // degenerate
  add_triangle(m, m.F(5, 2), m.F(5, 0), m.F(5, 1));  // duplicate of 5
  add_vertex(m, 1e2, 1e2, 1e2);                    // stray (also widens the box)
  // A tetrahedron hanging at vertex 7 (a bowtie).
  const Eigen::RowVector3d p = m.V.row(7);
  const int a = add_vertex(m, p(0) + 1, p(1), p(2)), b = add_vertex(m, p(0), p(1) + 1, p(2)),
            c = add_vertex(m, p(0), p(1), p(2) + 1);
  add_triangle(m, 7, b, a);
  add_triangle(m, 7, a, c);
  add_triangle(m, a, b, c);
  add_triangle(m, 7, c, b);
  EXPECT_NE(error_of(m), "");

  const RepairResult r = repair_mesh(m);
  EXPECT_EQ(r.report.merged_vertices, 1);
  EXPECT_EQ(r.report.degenerate_triangles, 1);
  EXPECT_EQ(r.report.duplicate_triangles, 1);
  EXPECT_EQ(r.report.unreferenced_vertices, 1);
  EXPECT_EQ(r.report.split_vertices, 1);
  EXPECT_EQ(r.report.lines.size(), 5u) << lines_of(r.report);
  EXPECT_EQ(r.mesh.num_vertices(), n + 3 + 1);
  EXPECT_EQ(r.mesh.num_triangles(), base.num_triangles() + 4);
  EXPECT_EQ(r.to_input.back(), 7);
  EXPECT_EQ(r.from_input[static_cast<size_t>(dup)], 0);
  EXPECT_EQ(r.from_input[static_cast<size_t>(dup + 1)], -1);
  EXPECT_EQ(error_of(r.mesh), "");
  EXPECT_TRUE(validate_mesh(r.mesh).warnings.empty());
  // The cactus itself is untouched (its vertices first, in order, with the same bits).
  EXPECT_TRUE(same_bits(r.mesh.V.topRows(n), base.V));
  expect_consistent(m, r);
  expect_idempotent(r);
  RepairOptions o;
  o.merge_tolerance = 1e-9;
  const RepairResult rt = repair_mesh(m, o);
  EXPECT_EQ(rt.mesh.F, r.mesh.F);
  EXPECT_TRUE(same_bits(rt.mesh.V, r.mesh.V));
  expect_idempotent(rt, o);
}

TEST(Repair, UnfixableInputThrowsValidatesMessage) {
  TriMesh range = tetra();
  range.F(2, 1) = 9;
  std::string got;
  try {
    repair_mesh(range);
  } catch (const InvalidInput& e) {
    got = e.what();
  }
  EXPECT_EQ(got, error_of(range));
  EXPECT_NE(got.find("out of range"), std::string::npos) << got;

  TriMesh nan = tetra();
  add_vertex(nan, std::numeric_limits<double>::quiet_NaN(), 0, 0);  // even unreferenced
  got.clear();
  try {
    repair_mesh(nan);
  } catch (const InvalidInput& e) {
    got = e.what();
  }
  EXPECT_EQ(got, error_of(nan));
  EXPECT_NE(got.find("non-finite"), std::string::npos) << got;

  RepairOptions bad;
  bad.merge_tolerance = -1;
  EXPECT_THROW(repair_mesh(tetra(), bad), InvalidInput);
  bad.merge_tolerance = std::numeric_limits<double>::infinity();
  EXPECT_THROW(repair_mesh(tetra(), bad), InvalidInput);
}

TEST(Repair, EmptyAndAllDegenerate) {
  const RepairResult empty = repair_mesh(TriMesh{});
  EXPECT_FALSE(empty.report.changed());
  EXPECT_EQ(empty.mesh.num_vertices(), 0);

  TriMesh flat;
  add_vertex(flat, 0, 0, 0);
  add_vertex(flat, 1, 0, 0);
  add_vertex(flat, 2, 0, 0);
  add_triangle(flat, 0, 1, 2);
  const RepairResult r = repair_mesh(flat);
  EXPECT_EQ(r.report.degenerate_triangles, 1);
  EXPECT_EQ(r.report.unreferenced_vertices, 3);
  EXPECT_EQ(r.mesh.num_triangles(), 0);
  EXPECT_NE(error_of(r.mesh).find("empty mesh"), std::string::npos);
}

// ---- repair_loaded_mesh ----

// A quad cube in OBJ where one face uses a second copy of vertex 1 (as exporters do at a UV
// seam). Repaired, the layout is kept (merging only): the user's 9 vertices map onto 8,
// every quad survives, and both the engine-order writer (with polygons) and the input-layout
// one produce consistent files.
TEST(RepairLoaded, PolygonObjWithDuplicatedVertexWritesBack) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 1 0 0\n"
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 9 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
  LoadedMesh m = read_mesh_bytes(obj, "seam.obj");
  ASSERT_EQ(m.polygons.size(), 6u);
  const TriMesh before = m.mesh;
  const size_t warnings_before = m.warnings.size();

  const RepairReport report = repair_loaded_mesh(m);
  EXPECT_EQ(report.merged_vertices, 1);
  EXPECT_EQ(m.mesh.num_vertices(), 8);
  EXPECT_EQ(error_of(m.mesh), "");
  EXPECT_TRUE(closed(m.mesh));
  EXPECT_EQ(m.input_to_engine, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 1}));
  EXPECT_FALSE(m.identity_layout());
  EXPECT_EQ(m.input_triangles, before.F);  // still in input ids, every triangle kept
  EXPECT_EQ(m.repair_to_input, iota_of(8));
  EXPECT_EQ(m.repair_triangles_to_input, iota_of(12));
  ASSERT_EQ(m.warnings.size(), warnings_before + 1);
  EXPECT_NE(m.warnings.back().find("8→1"), std::string::npos) << m.warnings.back();
  ASSERT_EQ(m.polygons.size(), 6u);
  // The input layout drives positions: input vertex i at engine vertex input_to_engine[i].
  for (int t = 0; t < m.input_triangles.rows(); ++t)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(m.mesh.F(t, k), m.input_to_engine[static_cast<size_t>(m.input_triangles(t, k))]);

  // Engine order, the user's quads back.
  WriteOptions options;
  options.polygons = m.polygons;
  const std::string out = write_mesh_bytes(MeshFileFormat::obj, m.mesh.V, m.mesh.F, nullptr, options);
  const LoadedMesh back = read_mesh_bytes(out, "back.obj");
  EXPECT_TRUE(same_bits(back.mesh.V, m.mesh.V));
  EXPECT_EQ(back.mesh.F, m.mesh.F);
  EXPECT_EQ(back.polygons.size(), 6u);
  EXPECT_NE(out.find("f 2 3 7 6"), std::string::npos) << out;  // the seam face, now on vertex 2

  // Input layout (what a base GLB or a glTF rewrite carries): 9 positions, input triangles.
  const Vertices positions = m.to_input_layout(m.mesh.V);
  ASSERT_EQ(positions.rows(), 9);
  EXPECT_TRUE(same_row_bits(positions, 8, positions, 1));
  const std::string glb = write_mesh_bytes(MeshFileFormat::glb, positions, m.input_triangles);
  const LoadedMesh glb_back = read_mesh_bytes(glb, "back.glb");
  EXPECT_EQ(glb_back.mesh.num_vertices(), 8);  // the glTF reader welds the seam itself
  EXPECT_EQ(glb_back.mesh.num_triangles(), 12);

  // Nothing left to do the second time.
  const LoadedMesh once = m;
  EXPECT_FALSE(repair_loaded_mesh(m).changed());
  EXPECT_EQ(m.input_to_engine, once.input_to_engine);
  EXPECT_EQ(m.warnings, once.warnings);
}

// A vertex dropped or split leaves no map from input vertices to engine vertices: the layout
// becomes the identity over the repaired mesh, never a −1. A quad whose corners collapse is
// dropped from the polygons; the others keep their faces, renumbered.
TEST(RepairLoaded, DroppedVerticesGiveAnIdentityLayout) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 1 0 0\n"
      "f 1 2 10 4\n"                              // a quad whose corner 10 repeats corner 2
      "f 1 4 3 2\nf 6 7 8 9\nf 1 2 7 6\nf 2 3 8 7\nf 3 4 9 8\nf 4 1 6 9\n";
  LoadedMesh m = read_mesh_bytes(obj, "collapse.obj");
  ASSERT_EQ(m.polygons.size(), 7u);
  const RepairReport report = repair_loaded_mesh(m);
  EXPECT_EQ(report.degenerate_triangles, 1);  // (1, 2, 10): corners 2 and 10 coincide
  EXPECT_EQ(report.duplicate_triangles, 0);
  EXPECT_EQ(report.unreferenced_vertices, 1);  // v 5 5 5
  // Triangle (1, 10, 4) is left of the collapsed quad, lying over the cube's bottom. Merging
  // 10 into 2 would put it on a third triangle of edge 1–2, so 10 keeps its own vertex;
  // edge 1–4 has three triangles in the input itself, which validation still names. The
  // layout must be writable all the same.
  EXPECT_EQ(report.merged_vertices, 0);
  EXPECT_NE(error_of(m.mesh).find("non-manifold edge"), std::string::npos) << error_of(m.mesh);
  EXPECT_TRUE(m.identity_layout());
  EXPECT_EQ(m.input_triangles, m.mesh.F);
  EXPECT_EQ(m.mesh.num_vertices(), 9);
  EXPECT_EQ(m.repair_to_input, (std::vector<int>{0, 1, 2, 3, 5, 6, 7, 8, 9}));
  EXPECT_EQ(m.repair_triangles_to_input.front(), 1);
  ASSERT_EQ(m.polygons.size(), 6u);
  EXPECT_EQ(m.polygons.front().first_triangle, 1);
  EXPECT_NE(m.warnings.back().find("1 polygon changed by the repair"), std::string::npos) << m.warnings.back();
  for (int e : m.input_to_engine) {
    EXPECT_GE(e, 0);
    EXPECT_LT(e, m.mesh.num_vertices());
  }
  WriteOptions options;
  options.polygons = m.polygons;
  for (const auto format : {MeshFileFormat::obj, MeshFileFormat::off, MeshFileFormat::ply}) {
    const std::string out = write_mesh_bytes(format, m.mesh.V, m.mesh.F, nullptr, options);
    const char* name = format == MeshFileFormat::obj ? "o.obj" : format == MeshFileFormat::off ? "o.off" : "o.ply";
    const LoadedMesh back = read_mesh_bytes(out, name);
    EXPECT_EQ(back.mesh.F, m.mesh.F) << name;
    EXPECT_EQ(back.polygons.size(), 6u) << name;
  }
  const Vertices positions = m.to_input_layout(m.mesh.V);
  EXPECT_TRUE(same_bits(positions, m.mesh.V));
  EXPECT_NO_THROW(write_mesh_bytes(MeshFileFormat::glb, positions, m.input_triangles));
}

// A bowtie in an OBJ: the split vertex has two engine vertices, so the layout becomes the
// identity over the repaired mesh, and the copy maps back to the user's vertex 1.
TEST(RepairLoaded, SplitVertexGivesAnIdentityLayout) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv -1 0 0\nv 0 -1 0\nv 0 0 -1\n"
      "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\nf 1 5 6\nf 1 7 5\nf 5 7 6\nf 1 6 7\n";
  LoadedMesh m = read_mesh_bytes(obj, "bowtie.obj");
  EXPECT_NE(error_of(m.mesh).find("non-manifold vertex"), std::string::npos);
  const RepairReport report = repair_loaded_mesh(m);
  EXPECT_EQ(report.split_vertices, 1);
  EXPECT_EQ(error_of(m.mesh), "");
  EXPECT_TRUE(m.identity_layout());
  EXPECT_EQ(m.input_to_engine.size(), 8u);
  EXPECT_EQ(m.input_triangles, m.mesh.F);
  EXPECT_EQ(m.repair_to_input, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 0}));
  EXPECT_EQ(m.repair_triangles_to_input, iota_of(8));
  EXPECT_NE(m.warnings.back().find("split 1 non-manifold vertex"), std::string::npos) << m.warnings.back();
  const Vertices positions = m.to_input_layout(m.mesh.V);
  const LoadedMesh back = read_mesh_bytes(write_mesh_bytes(MeshFileFormat::off, positions, m.input_triangles), "b.off");
  EXPECT_TRUE(same_bits(back.mesh.V, m.mesh.V));
  EXPECT_EQ(back.mesh.F, m.mesh.F);
}

TEST(RepairLoaded, UnchangedMeshIsLeftAlone) {
  LoadedMesh m = read_mesh(data_path("botsch-sorkine/cactus.off"));
  const LoadedMesh before = m;
  EXPECT_FALSE(repair_loaded_mesh(m).changed());
  EXPECT_TRUE(same_bits(m.mesh.V, before.mesh.V));
  EXPECT_EQ(m.mesh.F, before.mesh.F);
  EXPECT_EQ(m.input_to_engine, before.input_to_engine);
  EXPECT_EQ(m.warnings, before.warnings);
  EXPECT_TRUE(m.repair_to_input.empty());
}

TEST(RepairLoaded, ToInputLayoutRefusesAnOutOfRangeEntry) {
  LoadedMesh m = read_mesh(data_path("botsch-sorkine/cactus.off"));
  m.input_to_engine[3] = -1;
  EXPECT_THROW(m.to_input_layout(m.mesh.V), std::invalid_argument);
}

}  // namespace
}  // namespace hdeform

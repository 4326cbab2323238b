// Botsch–Sorkine .sel/.def parsing and geometric selectors.
#include "engine/io/selection.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

namespace hdeform {
namespace {

std::string slurp(const std::string& rel) {
  std::ifstream in(std::string(HDEFORM_TEST_DATA) + "/" + rel);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "(no InvalidInput thrown)";
}

struct SelCounts {
  const char* name;
  int vertices, fixed, free, handle;
};

TEST(Selection, BenchmarkSelFiles) {
  // Counted independently: awk 'NR>2 {c[$1]++} END {print c[0], c[1], c[2]}' NAME.sel
  const SelCounts cases[] = {{"cactus", 5261, 446, 4397, 418},
                             {"bar", 6084, 382, 5122, 580},
                             {"cylinder", 4802, 241, 4320, 241},
                             {"plane", 40401, 1809, 36984, 1608}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const auto labels = parse_sel(slurp(std::string("botsch-sorkine/") + c.name + ".sel"), c.vertices,
                                  std::string(c.name) + ".sel");
    ASSERT_EQ(static_cast<int>(labels.size()), c.vertices);
    EXPECT_EQ(static_cast<int>(select_label(labels, 0).size()), c.fixed);
    EXPECT_EQ(static_cast<int>(select_label(labels, 1).size()), c.free);
    EXPECT_EQ(static_cast<int>(select_label(labels, 2).size()), c.handle);
  }
  // Wrong vertex count for the mesh: the error names the file and the count.
  const std::string e = error_of([] { parse_sel(slurp("botsch-sorkine/cactus.sel"), 5262, "cactus.sel"); });
  EXPECT_EQ(e, "cactus.sel:5263: 5261 labels but the mesh has 5262 vertices");
  const std::string more = error_of([] { parse_sel(slurp("botsch-sorkine/cactus.sel"), 5000, "cactus.sel"); });
  EXPECT_EQ(more, "cactus.sel:5003: more labels than the mesh's 5000 vertices");
}

TEST(Selection, BenchmarkDefFiles) {
  const Eigen::Matrix4d cactus = parse_def(slurp("botsch-sorkine/cactus.def"), "cactus.def");
  EXPECT_EQ(cactus(0, 0), 0.999641);
  EXPECT_EQ(cactus(1, 2), 0.939416);
  EXPECT_EQ(cactus(2, 1), -0.939457);
  EXPECT_EQ(cactus(2, 3), 0.821073);
  EXPECT_EQ(cactus.row(3), Eigen::RowVector4d(0, 0, 0, 1));
  const Eigen::Matrix4d cyl = parse_def(slurp("botsch-sorkine/cylinder.def"), "cylinder.def");
  EXPECT_EQ(cyl(0, 3), 5.196152);
  EXPECT_EQ(cyl(2, 0), 0.866025);
  for (const char* n : {"bar", "plane"})
    EXPECT_NO_THROW(parse_def(slurp(std::string("botsch-sorkine/") + n + ".def"), n));
}

TEST(Selection, SelLabelOrderAndComments) {
  const auto labels = parse_sel("# header\n# 4 vertices\n0\n2\r\n\n 1 \n2\n", 4, "t.sel");
  EXPECT_EQ(labels, (std::vector<int>{0, 2, 1, 2}));
  EXPECT_EQ(select_label(labels, 2), (std::vector<int>{1, 3}));
}

TEST(Selection, BadSelFilesNameTheLine) {
  EXPECT_EQ(error_of([] { parse_sel("# a\n# 3 vertices\n0\n3\n1\n", 3, "bad.sel"); }),
            "bad.sel:4: bad label '3' (expected 0 = fixed, 1 = free or 2 = handle)");
  EXPECT_EQ(error_of([] { parse_sel("# a\n# 3 vertices\n0\n1 2\n1\n", 3, "two.sel"); }),
            "two.sel:4: bad label '1 2' (expected 0 = fixed, 1 = free or 2 = handle)");
  EXPECT_EQ(error_of([] { parse_sel("# a\n# 3 vertices\n0\nx\n1\n", 3, "x.sel"); }),
            "x.sel:4: bad label 'x' (expected 0 = fixed, 1 = free or 2 = handle)");
  EXPECT_EQ(error_of([] { parse_sel("# a\n# 3 vertices\n0\n1\n", 3, "short.sel"); }),
            "short.sel:4: 2 labels but the mesh has 3 vertices");
  EXPECT_EQ(error_of([] { parse_sel("# a\n# 3 vertices\n0\n1\n1\n2\n", 3, "long.sel"); }),
            "long.sel:6: more labels than the mesh's 3 vertices");
  EXPECT_EQ(error_of([] { parse_sel("0\n-1\n", 2); }), "<sel>:2: bad label '-1' (expected 0 = fixed, 1 = free or 2 = handle)");
}

TEST(Selection, BadBytesAreEscapedInMessages) {
  // Invalid UTF-8 / control bytes quoted from the file come back escaped (valid UTF-8).
  EXPECT_EQ(error_of([] { parse_sel(std::string("0\n\xff\xc3\x01\n", 6), 2, "u.sel"); }),
            "u.sel:2: bad label '\\xff\\xc3\\x01' (expected 0 = fixed, 1 = free or 2 = handle)");
  EXPECT_EQ(error_of([] { parse_def("1 0 0 \xe2\x82\n", "u.def"); }),
            "u.def:1: bad number '\\xe2\\x82' in matrix row 1");
}

TEST(Selection, BadDefFilesNameTheLine) {
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0\n0 0 1 0\n0 0 0 1\n", "r.def"); }),
            "r.def:3: matrix row 2 has 3 numbers, expected 4");
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0 0 0\n0 0 1 0\n0 0 0 1\n", "r5.def"); }),
            "r5.def:3: more than 4 numbers in matrix row 2");
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0 0\n0 0 one 0\n0 0 0 1\n", "n.def"); }),
            "n.def:4: bad number 'one' in matrix row 3");
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0 0\n", "few.def"); }),
            "few.def:3: expected a 4×4 matrix, found 2 rows");
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n", "p.def"); }),
            "p.def:5: last matrix row must be 0 0 0 1 (an affine transform)");
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 2 3 4\n", "x.def"); }),
            "x.def:6: unexpected content after the 4×4 matrix: '1 2 3 4'");
  EXPECT_EQ(error_of([] { parse_def("# m\n1 0 0 0\n0 1 0 0\n0 0 1 nan\n0 0 0 1\n", "nan.def"); }),
            "nan.def:4: non-finite number 'nan' in matrix");
}

// Tiny mesh: the 8 corners of the unit cube plus its centre (vertex 8).
Vertices cube_points() {
  Vertices V(9, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1, 0.5, 0.5, 0.5;
  return V;
}

TEST(Selection, BoxIsClosed) {
  const Vertices V = cube_points();
  EXPECT_EQ(select_box(V, {0, 0, 0}, {1, 1, 0}), (std::vector<int>{0, 1, 2, 3}));  // z = 0 face, bounds inclusive
  EXPECT_EQ(select_box(V, {0.25, 0.25, 0.25}, {0.75, 0.75, 0.75}), (std::vector<int>{8}));
  EXPECT_TRUE(select_box(V, {2, 2, 2}, {3, 3, 3}).empty());
  EXPECT_EQ(select_box(V, {-1, -1, -1}, {2, 2, 2}).size(), 9u);
}

TEST(Selection, Sphere) {
  const Vertices V = cube_points();
  EXPECT_EQ(select_sphere(V, {0, 0, 0}, 1.0), (std::vector<int>{0, 1, 2, 4, 8}));  // boundary included; centre at √3/2
  EXPECT_EQ(select_sphere(V, {0.5, 0.5, 0.5}, 0.1), (std::vector<int>{8}));
  EXPECT_EQ(select_sphere(V, {0.5, 0.5, 0.5}, 0.9).size(), 9u);  // corners at √3/2 ≈ 0.866
}

TEST(Selection, HalfSpace) {
  const Vertices V = cube_points();
  EXPECT_EQ(select_half_space(V, {0, 0, 1}, 1.0), (std::vector<int>{4, 5, 6, 7}));
  EXPECT_EQ(select_half_space(V, {1, 1, 0}, 1.5), (std::vector<int>{3, 7}));
  EXPECT_EQ(select_half_space(V, {-1, 0, 0}, 0.0), (std::vector<int>{0, 2, 4, 6}));
}

TEST(Selection, Unite) {
  EXPECT_EQ(unite({5, 1, 3}, {3, 2, 2, 9}), (std::vector<int>{1, 2, 3, 5, 9}));
  EXPECT_EQ(unite({}, {}), std::vector<int>{});
  const Vertices V = cube_points();
  const auto u = unite(select_half_space(V, {0, 0, 1}, 1.0), select_box(V, {0, 0, 0}, {1, 1, 0}));
  EXPECT_EQ(u, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7}));
}

}  // namespace
}  // namespace hdeform

// Issue 10, item 5: the operators and system blocks assembled straight into compressed
// storage (operator_assembly.h, system_blocks.h) against the straightforward builds they
// replaced (triplets, sparse products, Eigen sums), and one vs two OpenMP threads.
#include "engine/mesh/validate.h"
#include "engine/operators/operator_assembly.h"
#include "engine/operators/system_blocks.h"
#include "fixtures.h"
#include "fixtures/procedural.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cstring>

namespace hdeform {
namespace {

using test::data_path;

struct Reference {  // the pre-issue-10 build of PreparedMesh::create
  SparseMatrix G, GtA, L, GtDBD, Reg;
  std::vector<InteriorEdge> edges;
};

Reference reference(const TriMesh& mesh) {
  const Vertices& V = mesh.V;
  const Triangles& F = mesh.F;
  Reference r;
  r.G = grad(V, F);
  r.edges = interior_edges(V, F);
  const Eigen::VectorXd a = triangle_areas(V, F);
  Eigen::VectorXd a3(3 * F.rows());
  for (Eigen::Index l = 0; l < F.rows(); ++l) a3.segment<3>(3 * l).setConstant(a[l]);
  const SparseMatrix Gt = r.G.transpose();
  r.GtA = Gt * a3.asDiagonal();
  r.L = (r.GtA * r.G).pruned(0.0, 0.0);
  std::vector<Eigen::Triplet<double>> t;  // B₃ D₃
  for (std::size_t e = 0; e < r.edges.size(); ++e)
    for (int d = 0; d < 3; ++d) {
      t.emplace_back(static_cast<int>(3 * e) + d, 3 * r.edges[e].tri[0] + d, r.edges[e].length);
      t.emplace_back(static_cast<int>(3 * e) + d, 3 * r.edges[e].tri[1] + d, -r.edges[e].length);
    }
  SparseMatrix BD(3 * static_cast<Eigen::Index>(r.edges.size()), 3 * F.rows());
  BD.setFromTriplets(t.begin(), t.end());
  const SparseMatrix DG = gradient_jumps(r.G, r.edges);
  r.GtDBD = SparseMatrix(DG.transpose()) * BD;
  r.Reg = r.GtDBD * r.G;
  return r;
}

// Same pattern, and values within 1e-14 of the largest entry (in practice bit-identical:
// the count of differing values is printed).
template <class Sparse>
void expect_same(const Sparse& got, const Sparse& want, const std::string& what) {
  ASSERT_EQ(got.rows(), want.rows()) << what;
  ASSERT_EQ(got.cols(), want.cols()) << what;
  ASSERT_TRUE(got.isCompressed() && want.isCompressed()) << what;
  ASSERT_EQ(got.nonZeros(), want.nonZeros()) << what;
  ASSERT_TRUE(std::equal(got.outerIndexPtr(), got.outerIndexPtr() + got.outerSize() + 1,
                         want.outerIndexPtr()))
      << what;
  ASSERT_TRUE(std::equal(got.innerIndexPtr(), got.innerIndexPtr() + got.nonZeros(),
                         want.innerIndexPtr()))
      << what;
  const auto n = static_cast<std::size_t>(want.nonZeros());
  double scale = 0, worst = 0;
  std::size_t differing = 0;
  for (std::size_t k = 0; k < n; ++k) {
    scale = std::max(scale, std::abs(want.valuePtr()[k]));
    worst = std::max(worst, std::abs(got.valuePtr()[k] - want.valuePtr()[k]));
    differing += std::memcmp(got.valuePtr() + k, want.valuePtr() + k, sizeof(double)) != 0;
  }
  EXPECT_LE(worst, 1e-14 * scale) << what;
  std::printf("  %-8s nnz %zu, values differing in any bit: %zu\n", what.c_str(), n, differing);
}

template <class Sparse>
bool same_bits(const Sparse& a, const Sparse& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && a.nonZeros() == b.nonZeros() &&
         std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.outerSize() + 1, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr()) &&
         std::memcmp(a.valuePtr(), b.valuePtr(), sizeof(double) * a.nonZeros()) == 0;
}

std::vector<std::pair<std::string, TriMesh>> meshes() {
  std::vector<std::pair<std::string, TriMesh>> out;
  for (const char* name : {"cactus", "bar", "plane"})  // plane: a boundary and right angles
    out.emplace_back(name, read_mesh(data_path(std::string("botsch-sorkine/") + name + ".off")).mesh);
  out.emplace_back("capsule", procedural::capsule_case(3000).mesh);
  TriMesh loose = procedural::capsule_case(500).mesh;  // plus one vertex no triangle uses
  loose.V.conservativeResize(loose.V.rows() + 1, 3);
  loose.V.row(loose.V.rows() - 1) << 5, 5, 5;
  out.emplace_back("unreferenced", std::move(loose));
  return out;
}

TEST(OperatorAssembly, EqualsTheTripletAndProductBuild) {
  for (const auto& [name, mesh] : meshes()) {
    SCOPED_TRACE(name);
    std::printf("%s\n", name.c_str());
    const Reference ref = reference(mesh);
    const auto pm = PreparedMesh::create(mesh);
    const VertexTriangles& vt = pm->vertex_triangles();
    const auto edges = interior_edges(mesh.V, mesh.F, vt);
    ASSERT_EQ(edges.size(), ref.edges.size());
    for (std::size_t e = 0; e < edges.size(); ++e) {
      EXPECT_EQ(edges[e].tri[0], ref.edges[e].tri[0]) << e;
      EXPECT_EQ(edges[e].tri[1], ref.edges[e].tri[1]) << e;
      EXPECT_EQ(edges[e].length, ref.edges[e].length) << e;
    }
    expect_same(pm->G(), ref.G, "G");
    expect_same(pm->GtA(), ref.GtA, "GtA");
    expect_same(pm->L(), ref.L, "L");
    expect_same(pm->GtDBD(), ref.GtDBD, "GtDBD");
    expect_same(pm->Reg(), ref.Reg, "Reg");
  }
}

// The blocks against the triplet split that built them before, on a model's constraints.
Blocks triplet_split(const SparseMatrix& K, const SparseMatrix& GtW, const BlockLayout& b) {
  std::vector<Eigen::Triplet<double>> ff, fc, gw;
  for (Eigen::Index c = 0; c < K.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (b.region_of[r] >= 0) continue;
      (b.region_of[c] < 0 ? ff : fc).emplace_back(b.block_index[r], b.block_index[c], it.value());
    }
  for (Eigen::Index c = 0; c < GtW.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(GtW, c); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (b.region_of[r] < 0) gw.emplace_back(b.block_index[r], static_cast<int>(c), it.value());
    }
  Blocks out;
  out.FF.resize(b.nF, b.nF);
  out.FF.setFromTriplets(ff.begin(), ff.end());
  out.FC.resize(b.nF, b.nC);
  out.FC.setFromTriplets(fc.begin(), fc.end());
  out.GtW_F.resize(b.nF, GtW.cols());
  out.GtW_F.setFromTriplets(gw.begin(), gw.end());
  return out;
}

class OperatorAssemblyBlocks : public testing::TestWithParam<const char*> {};

// bar: closed; plane: a boundary (triangles with fewer than three interior edges).
TEST_P(OperatorAssemblyBlocks, EqualTheTripletSplit) {
  const test::Benchmark b = test::load_benchmark(GetParam());
  const PreparedMesh& pm = *b.mesh;
  std::vector<int> region_of(static_cast<std::size_t>(pm.n()), -1), block_index(region_of.size());
  for (int v : b.constraints.fixed) region_of[v] = 0;
  for (int v : b.constraints.handles[0]) region_of[v] = 1;
  std::vector<int> free_;
  Eigen::Index nF = 0, nC = 0;
  for (int v = 0; v < pm.n(); ++v) {
    block_index[v] = static_cast<int>(region_of[v] < 0 ? nF++ : nC++);
    if (region_of[v] < 0) free_.push_back(v);
  }
  const BlockLayout layout{region_of, block_index, nF, nC};
  const SparseMatrix GtA = pm.GtA(), GtDBD = pm.GtDBD();

  const Blocks narrow = split(pm.L(), &GtA, layout);
  const Blocks narrow_ref = triplet_split(pm.L(), GtA, layout);
  expect_same(narrow.FF, narrow_ref.FF, "L_FF");
  expect_same(narrow.FC, narrow_ref.FC, "L_FC");
  expect_same(narrow.GtW_F, narrow_ref.GtW_F, "GtA_F");
  expect_same(free_rows_gta(pm.mesh().F, pm.gradients(), pm.areas(), pm.vertex_triangles(), free_),
              narrow_ref.GtW_F, "GtA_F*");

  Blocks area, reg;
  split_union(pm.L(), pm.Reg(), &GtA, &GtDBD, layout, area, reg);
  SparseMatrixR area_rows, reg_rows;  // what the engine uses for β > 0
  assemble_wide_free_rows(pm.mesh().F, pm.gradients(), pm.areas(), pm.edges(),
                          pm.vertex_triangles(), free_, area_rows, reg_rows);
  const SparseMatrix Lw = pm.L() + 0.0 * pm.Reg(), Rw = pm.Reg() + 0.0 * pm.L();
  const SparseMatrix Aw = GtA + 0.0 * GtDBD, Dw = GtDBD + 0.0 * GtA;
  const Blocks area_ref = triplet_split(Lw, Aw, layout), reg_ref = triplet_split(Rw, Dw, layout);
  expect_same(area.FF, area_ref.FF, "wide FF1");
  expect_same(area.FC, area_ref.FC, "wide FC1");
  expect_same(area.GtW_F, area_ref.GtW_F, "wide GW1");
  expect_same(reg.FF, reg_ref.FF, "wide FF2");
  expect_same(reg.FC, reg_ref.FC, "wide FC2");
  expect_same(reg.GtW_F, reg_ref.GtW_F, "wide GW2");
  expect_same(area_rows, area_ref.GtW_F, "wide GW1*");
  expect_same(reg_rows, reg_ref.GtW_F, "wide GW2*");
  const double beta = 0.37;  // the engine's (GᵀW_β)_F against combining the two parts
  SparseMatrixR combined = area_rows;
  for (Eigen::Index k = 0; k < combined.nonZeros(); ++k)
    combined.valuePtr()[k] = (1 - beta) * area_rows.valuePtr()[k] + beta * reg_rows.valuePtr()[k];
  expect_same(assemble_wide_free_rows(pm.mesh().F, pm.gradients(), pm.areas(), pm.edges(),
                                      pm.vertex_triangles(), free_, 1 - beta, beta),
              combined, "GtW_beta");

  // The column loops run on the OpenMP threads: one thread gives the same bits.
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const Blocks narrow1 = split(pm.L(), &GtA, layout);
  Blocks area1, reg1;
  split_union(pm.L(), pm.Reg(), &GtA, &GtDBD, layout, area1, reg1);
  SparseMatrixR area_rows1, reg_rows1;
  assemble_wide_free_rows(pm.mesh().F, pm.gradients(), pm.areas(), pm.edges(),
                          pm.vertex_triangles(), free_, area_rows1, reg_rows1);
  const SparseMatrixR gta1 =
      free_rows_gta(pm.mesh().F, pm.gradients(), pm.areas(), pm.vertex_triangles(), free_);
  omp_set_num_threads(threads);
  EXPECT_TRUE(same_bits(narrow1.FF, narrow.FF));
  EXPECT_TRUE(same_bits(narrow1.FC, narrow.FC));
  EXPECT_TRUE(same_bits(gta1, narrow.GtW_F));
  EXPECT_TRUE(same_bits(area1.FF, area.FF));
  EXPECT_TRUE(same_bits(reg1.FF, reg.FF));
  EXPECT_TRUE(same_bits(reg1.FC, reg.FC));
  EXPECT_TRUE(same_bits(reg1.GtW_F, reg.GtW_F));
  EXPECT_TRUE(same_bits(area_rows1, area_rows));
  EXPECT_TRUE(same_bits(reg_rows1, reg_rows));
}

INSTANTIATE_TEST_SUITE_P(Models, OperatorAssemblyBlocks, testing::Values("bar", "plane"));

// Each column (vertex, edge) is computed by one thread in a fixed order: one and two
// threads must give the same bits.
TEST(OperatorAssembly, OneAndTwoThreadsGiveTheSameBits) {
  const TriMesh mesh = procedural::capsule_case(20000).mesh;
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = PreparedMesh::create(mesh);
  const SparseMatrix G1 = one->G(), A1 = one->GtA(), D1 = one->GtDBD();
  const SparseMatrix R1 = one->Reg();  // assembled on each call: here, on one thread
  omp_set_num_threads(2);
  const auto two = PreparedMesh::create(mesh);
  const SparseMatrix R2 = two->Reg();
  const SparseMatrix G2 = two->G(), A2 = two->GtA(), D2 = two->GtDBD();
  omp_set_num_threads(threads);
  EXPECT_TRUE(same_bits(one->L(), two->L()));
  EXPECT_TRUE(same_bits(R1, R2));
  EXPECT_TRUE(same_bits(R1, two->Reg()));  // and the same bits on every call
  EXPECT_TRUE(same_bits(G1, G2));
  EXPECT_TRUE(same_bits(A1, A2));
  EXPECT_TRUE(same_bits(D1, D2));
  EXPECT_EQ(0, std::memcmp(one->gradients().data(), two->gradients().data(),
                           sizeof(double) * one->gradients().size()));
  ASSERT_EQ(one->edges().size(), two->edges().size());
  for (std::size_t e = 0; e < one->edges().size(); ++e) {
    EXPECT_EQ(one->edges()[e].tri[0], two->edges()[e].tri[0]);
    EXPECT_EQ(one->edges()[e].length, two->edges()[e].length);
  }
}

}  // namespace
}  // namespace hdeform

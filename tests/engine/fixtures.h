// Shared helpers for engine tests: bundled benchmark meshes and their constraints.
#pragma once

#include "engine/deform/deformer.h"
#include "engine/io/mesh_io.h"
#include "engine/io/selection.h"
#include "fixtures/procedural.h"

#include <cstring>
#include <fstream>
#include <vector>
#include <sstream>
#include <string>

namespace hdeform::test {

inline std::string data_path(const std::string& rel) { return std::string(HDEFORM_TEST_DATA) + "/" + rel; }

// Equal bit for bit (not only within rounding): the engine's determinism checks.
inline bool same_bits(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

// Closed, consistently oriented (outward) tetrahedron.
inline TriMesh tetra() {
  TriMesh m;
  m.V.resize(4, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.F.resize(4, 3);
  m.F << 0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2;
  return m;
}

inline std::string slurp(const std::string& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// A Botsch–Sorkine benchmark: mesh, .sel constraints (0 fixed, 2 handle) and .def matrix.
struct Benchmark {
  std::shared_ptr<const PreparedMesh> mesh;
  Constraints constraints;
  Eigen::Matrix4d T;
};

inline Benchmark load_benchmark(const std::string& name) {
  const std::string base = data_path("botsch-sorkine/" + name);
  Benchmark b;
  b.mesh = PreparedMesh::create(read_mesh(base + ".off").mesh);
  const auto labels = parse_sel(slurp(base + ".sel"), b.mesh->n(), name + ".sel");
  b.constraints.fixed = select_label(labels, 0);
  b.constraints.handles = {select_label(labels, 2)};
  b.T = parse_def(slurp(base + ".def"), name + ".def");
  return b;
}

// The bench's procedural capsule of about n vertices: its base fixed, its cap the handle
// (T is the identity).
inline Benchmark capsule_benchmark(int n) {
  procedural::CapsuleCase cc = procedural::capsule_case(n);
  Benchmark b;
  b.mesh = PreparedMesh::create(std::move(cc.mesh));
  b.constraints.fixed = std::move(cc.base);
  b.constraints.handles = {std::move(cc.cap)};
  b.T = Eigen::Matrix4d::Identity();
  return b;
}

// The free vertices (neither fixed nor in a handle), ascending: K_FF's row i is free[i].
inline std::vector<int> free_vertices(const PreparedMesh& pm, const Constraints& c) {
  std::vector<char> fixed(static_cast<std::size_t>(pm.n()), 0);
  for (int v : c.fixed) fixed[v] = 1;
  for (const auto& h : c.handles)
    for (int v : h) fixed[v] = 1;
  std::vector<int> free;
  for (std::size_t v = 0; v < fixed.size(); ++v)
    if (!fixed[v]) free.push_back(static_cast<int>(v));
  return free;
}

// K = (1 − β) L + β Reg (β raw; β = 0: the Laplacian alone, its narrow pattern), with the
// constrained rows and columns removed: K_FF as the engine builds it.
inline SparseMatrix k_ff(const PreparedMesh& pm, const Constraints& c, double beta) {
  std::vector<int> index(static_cast<std::size_t>(pm.n()), -1);
  int nF = 0;
  for (int v : free_vertices(pm, c)) index[v] = nF++;
  const SparseMatrix K =
      beta == 0 ? SparseMatrix(pm.L()) : SparseMatrix((1 - beta) * pm.L() + beta * pm.Reg());
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index col = 0; col < K.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(K, col); it; ++it)
      if (index[it.row()] >= 0 && index[col] >= 0)
        t.emplace_back(index[it.row()], index[col], it.value());
  SparseMatrix K_FF(nF, nF);
  K_FF.setFromTriplets(t.begin(), t.end());
  return K_FF;
}

}  // namespace hdeform::test

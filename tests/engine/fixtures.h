// Shared helpers for engine tests: bundled benchmark meshes and their constraints.
#pragma once

#include "deformer.h"
#include "mesh_io.h"
#include "selection.h"

#include <fstream>
#include <sstream>
#include <string>

namespace hdeform::test {

inline std::string data_path(const std::string& rel) { return std::string(HDEFORM_TEST_DATA) + "/" + rel; }

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

}  // namespace hdeform::test

#include "engine/deform/local_beta.h"

#include "engine/deform/deformer.h"

#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>

namespace hdeform {

namespace {

void check_beta(double beta) {
  if (!(beta >= 0 && beta < 1))
    throw InvalidInput("local beta must be in [0, 1), got " + std::to_string(beta));
}

void check_ids(const PreparedMesh& pm, const std::vector<int>& ids) {
  for (int v : ids)
    if (v < 0 || v >= pm.n())
      throw InvalidInput("local beta region has vertex id " + std::to_string(v) +
                         " out of range [0, " + std::to_string(pm.n()) + ")");
}

}  // namespace

Eigen::VectorXd falloff_beta(const PreparedMesh& pm, const std::vector<int>& around,
                             double beta, double radius) {
  check_beta(beta);
  if (!(radius > 0) || !std::isfinite(radius))
    throw InvalidInput("local beta falloff radius must be positive and finite");
  check_ids(pm, around);
  const Vertices& V = pm.mesh().V;
  const Triangles& F = pm.mesh().F;

  // Region vertices bucketed in cubes of side `radius`: a centroid only needs the 27 cubes
  // around its own.
  auto cell = [radius](double x) { return static_cast<std::int64_t>(std::floor(x / radius)); };
  auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    return static_cast<std::uint64_t>((i * 73856093) ^ (j * 19349663) ^ (k * 83492791));
  };
  std::unordered_map<std::uint64_t, std::vector<int>> grid;
  for (int v : around) grid[key(cell(V(v, 0)), cell(V(v, 1)), cell(V(v, 2)))].push_back(v);

  Eigen::VectorXd field = Eigen::VectorXd::Zero(pm.m());
  for (Eigen::Index l = 0; l < pm.m(); ++l) {
    const Eigen::RowVector3d c = (V.row(F(l, 0)) + V.row(F(l, 1)) + V.row(F(l, 2))) / 3.0;
    const std::int64_t ci = cell(c[0]), cj = cell(c[1]), ck = cell(c[2]);
    double d = std::numeric_limits<double>::infinity();
    for (std::int64_t i = ci - 1; i <= ci + 1; ++i)
      for (std::int64_t j = cj - 1; j <= cj + 1; ++j)
        for (std::int64_t k = ck - 1; k <= ck + 1; ++k)
          if (auto it = grid.find(key(i, j, k)); it != grid.end())
            for (int v : it->second) d = std::min(d, (V.row(v) - c).norm());
    const double t = std::max(0.0, 1.0 - d / radius);
    field[l] = beta * t * t;
  }
  return field;
}

Eigen::VectorXd region_beta(const PreparedMesh& pm, const std::vector<int>& region,
                            double beta) {
  check_beta(beta);
  check_ids(pm, region);
  std::vector<char> in(static_cast<std::size_t>(pm.n()), 0);
  for (int v : region) in[v] = 1;
  const Triangles& F = pm.mesh().F;
  Eigen::VectorXd field = Eigen::VectorXd::Zero(pm.m());
  for (Eigen::Index l = 0; l < pm.m(); ++l)
    if (in[F(l, 0)] || in[F(l, 1)] || in[F(l, 2)]) field[l] = beta;
  return field;
}

}  // namespace hdeform

#include "engine/operators/operators.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <unordered_map>

namespace hdeform {

// The per-triangle loops below run on all OpenMP threads: each triangle's values depend on
// that triangle alone, so the bits do not depend on the thread count.
namespace {
Eigen::Vector3d row(const Vertices& V, int i) { return V.row(i).transpose(); }
}  // namespace

Eigen::VectorXd triangle_areas(const Vertices& V, const Triangles& F) {
  Eigen::VectorXd a(F.rows());
#pragma omp parallel for schedule(static)
  for (Eigen::Index l = 0; l < F.rows(); ++l) {
    const Eigen::Vector3d e1 = row(V, F(l, 1)) - row(V, F(l, 0));
    const Eigen::Vector3d e2 = row(V, F(l, 2)) - row(V, F(l, 0));
    a[l] = 0.5 * e1.cross(e2).norm();
  }
  return a;
}

Vertices triangle_normals(const Vertices& V, const Triangles& F) {
  Vertices N(F.rows(), 3);
#pragma omp parallel for schedule(static)
  for (Eigen::Index l = 0; l < F.rows(); ++l) {
    const Eigen::Vector3d e1 = row(V, F(l, 1)) - row(V, F(l, 0));
    const Eigen::Vector3d e2 = row(V, F(l, 2)) - row(V, F(l, 0));
    N.row(l) = e1.cross(e2).normalized().transpose();
  }
  return N;
}

TriangleGradients hat_gradients(const Vertices& V, const Triangles& F) {
  TriangleGradients grads(F.rows(), 9);
#pragma omp parallel for schedule(static)
  for (Eigen::Index l = 0; l < F.rows(); ++l) {
    const Eigen::Vector3d x[3] = {row(V, F(l, 0)), row(V, F(l, 1)), row(V, F(l, 2))};
    const Eigen::Vector3d c = (x[1] - x[0]).cross(x[2] - x[0]);
    const double twice_area = c.norm();
    const Eigen::Vector3d n = c / twice_area;
    for (int i = 0; i < 3; ++i)
      grads.row(l).segment<3>(3 * i) = (n.cross(x[(i + 2) % 3] - x[(i + 1) % 3]) / twice_area);
  }
  return grads;
}

SparseMatrix grad(const Vertices& V, const Triangles& F) {
  const TriangleGradients grads = hat_gradients(V, F);
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(9 * F.rows());
  for (Eigen::Index l = 0; l < F.rows(); ++l)
    for (int i = 0; i < 3; ++i)
      for (int d = 0; d < 3; ++d) t.emplace_back(3 * l + d, F(l, i), grads(l, 3 * i + d));
  SparseMatrix G(3 * F.rows(), V.rows());
  G.setFromTriplets(t.begin(), t.end());
  return G;
}

std::vector<InteriorEdge> interior_edges(const Vertices& V, const Triangles& F) {
  // Key an undirected edge by its sorted vertex pair; collect incident triangles.
  struct Incidence {
    int tri[2] = {-1, -1};
    int count = 0;
  };
  std::unordered_map<std::uint64_t, Incidence> by_edge;
  by_edge.reserve(3 * F.rows());
  for (Eigen::Index l = 0; l < F.rows(); ++l) {
    for (int c = 0; c < 3; ++c) {
      const auto a = static_cast<std::uint32_t>(F(l, c));
      const auto b = static_cast<std::uint32_t>(F(l, (c + 1) % 3));
      const std::uint64_t key = (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
      Incidence& inc = by_edge[key];
      if (inc.count < 2) inc.tri[inc.count] = static_cast<int>(l);
      ++inc.count;
    }
  }
  std::vector<std::pair<std::uint64_t, Incidence>> sorted(by_edge.begin(), by_edge.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& p, const auto& q) { return p.first < q.first; });
  std::vector<InteriorEdge> edges;
  edges.reserve(sorted.size());
  for (const auto& [key, inc] : sorted) {
    if (inc.count != 2) continue;
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffu);
    edges.push_back({{inc.tri[0], inc.tri[1]}, (row(V, a) - row(V, b)).norm()});
  }
  return edges;
}

SparseMatrix energy_differences(const std::vector<InteriorEdge>& edges, int num_triangles) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(2 * edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e) {
    t.emplace_back(static_cast<int>(e), edges[e].tri[0], 1.0);
    t.emplace_back(static_cast<int>(e), edges[e].tri[1], -1.0);
  }
  SparseMatrix D(static_cast<Eigen::Index>(edges.size()), num_triangles);
  D.setFromTriplets(t.begin(), t.end());
  return D;
}

SparseMatrix gradient_jumps(const SparseMatrix& G, const std::vector<InteriorEdge>& edges) {
  const SparseMatrixR Gr = G;  // row access
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(edges.size() * 3 * 6);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    for (int d = 0; d < 3; ++d) {
      const int r = static_cast<int>(3 * e) + d;
      for (SparseMatrixR::InnerIterator it(Gr, 3 * edges[e].tri[0] + d); it; ++it)
        t.emplace_back(r, static_cast<int>(it.col()), it.value());
      for (SparseMatrixR::InnerIterator it(Gr, 3 * edges[e].tri[1] + d); it; ++it)
        t.emplace_back(r, static_cast<int>(it.col()), -it.value());
    }
  }
  SparseMatrix J(3 * static_cast<Eigen::Index>(edges.size()), G.cols());
  J.setFromTriplets(t.begin(), t.end());  // sums the shared vertices' entries
  return J;
}

SparseMatrix W_beta(const Eigen::VectorXd& areas, const std::vector<InteriorEdge>& edges,
                    double beta) {
  std::vector<Eigen::Triplet<double>> t;
  const Eigen::Index m = areas.size();
  for (Eigen::Index l = 0; l < m; ++l)
    for (int d = 0; d < 3; ++d) t.emplace_back(3 * l + d, 3 * l + d, (1.0 - beta) * areas[l]);
  for (const InteriorEdge& e : edges) {
    const double w = beta * e.length;
    for (int d = 0; d < 3; ++d) {
      const int a = 3 * e.tri[0] + d, b = 3 * e.tri[1] + d;
      t.emplace_back(a, a, w);
      t.emplace_back(b, b, w);
      t.emplace_back(a, b, -w);
      t.emplace_back(b, a, -w);
    }
  }
  SparseMatrix W(3 * m, 3 * m);
  W.setFromTriplets(t.begin(), t.end());
  return W;
}

}  // namespace hdeform

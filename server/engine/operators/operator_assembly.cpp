#include "engine/operators/operator_assembly.h"

#include "engine/operators/column_assembly.h"

#include <algorithm>
#include <utility>

namespace hdeform {

namespace {

// The corner (0, 1, 2) of vertex v in triangle l. Precondition: v is a vertex of l.
int corner(const Triangles& F, Eigen::Index l, int v) {
  return F(l, 0) == v ? 0 : (F(l, 1) == v ? 1 : 2);
}

// Columns 3l+0..2 of Gᵀ D₃ᵀ B₃ D₃ (≤ 6 vertices: l's own and the opposite ones across its
// interior edges), summed over l's edges in ascending order as the sparse product
// SparseMatrix(DGᵀ) · B₃D₃ sums them: the jump row 3e+d of edge e times ±len_e. With
// `values` false only the vertices are found (the pattern).
struct JumpColumns {
  int size = 0;
  int vertex[6];
  double value[3][6];
  int slot(int v) {  // v's position, appended if new (its values then start unassigned)
    for (int k = 0; k < size; ++k)
      if (vertex[k] == v) return k;
    vertex[size] = v;
    return -1 - size++;
  }
  void add(int v, const double (&x)[3], bool values) {
    const int k = slot(v);
    if (!values) return;
    for (int d = 0; d < 3; ++d)  // the first term assigns, as the product does
      if (k < 0) value[d][-1 - k] = x[d];
      else value[d][k] += x[d];
  }
  void build(const Triangles& F, const TriangleGradients& grads,
             const std::vector<InteriorEdge>& edges, const std::array<int, 3>& own, int l,
             bool values) {
    size = 0;
    for (int e : own) {
      if (e < 0) continue;
      const int a = edges[e].tri[0], b = edges[e].tri[1];
      const double s = l == a ? edges[e].length : -edges[e].length;  // B₃D₃'s entry
      // Row 3e+d of D₃G: ∇φ of a's corners minus ∇φ of b's (gradient_jumps' triplet sums).
      double x[3] = {0, 0, 0};
      for (int i = 0; i < 3; ++i) {
        const int w = F(a, i);
        int j = 0;
        while (j < 3 && F(b, j) != w) ++j;
        if (values)
          for (int d = 0; d < 3; ++d) {
            const double g = grads(a, 3 * i + d);
            x[d] = (j < 3 ? g + -grads(b, 3 * j + d) : g) * s;
          }
        add(w, x, values);
      }
      for (int j = 0; j < 3; ++j) {
        const int w = F(b, j);
        if (F(a, 0) == w || F(a, 1) == w || F(a, 2) == w) continue;
        if (values)
          for (int d = 0; d < 3; ++d) x[d] = -grads(b, 3 * j + d) * s;
        add(w, x, values);
      }
    }
  }
};

// Vertex v's entries in columns 3l+0..2 of Gᵀ D₃ᵀ B₃ D₃: JumpColumns' sums for one vertex
// (the same terms in the same order), without the other five. False if v is not in the
// columns' support.
bool jump_values(const Triangles& F, const TriangleGradients& grads,
                 const std::vector<InteriorEdge>& edges, const std::array<int, 3>& own, int l,
                 int v, double (&out)[3]) {
  bool any = false;
  for (int e : own) {
    if (e < 0) continue;
    const int a = edges[e].tri[0], b = edges[e].tri[1];
    int i = 0, j = 0;
    while (i < 3 && F(a, i) != v) ++i;
    while (j < 3 && F(b, j) != v) ++j;
    if (i == 3 && j == 3) continue;
    const double s = l == a ? edges[e].length : -edges[e].length;
    for (int d = 0; d < 3; ++d) {
      double x;
      if (i < 3) {
        const double g = grads(a, 3 * i + d);
        x = (j < 3 ? g + -grads(b, 3 * j + d) : g) * s;
      } else {
        x = -grads(b, 3 * j + d) * s;
      }
      out[d] = any ? out[d] + x : x;  // the first term assigns, as the product does
    }
    any = true;
  }
  return any;
}

}  // namespace

std::vector<InteriorEdge> interior_edges(const Vertices& V, const Triangles& F,
                                         const VertexTriangles& vt) {
  const auto n = static_cast<Eigen::Index>(vt.offsets.size()) - 1;
  std::vector<int> first(static_cast<std::size_t>(n) + 1, 0);  // edges owned by vertex a < b
  std::vector<InteriorEdge> edges;
  // Each vertex a owns the edges (a, b > a): its (b, triangle) pairs sorted, a pair of
  // equal b with exactly two triangles is an interior edge. Two passes: count, then fill.
#pragma omp parallel
  {
    std::vector<std::pair<int, int>> around;  // (b, triangle)
    auto collect = [&](Eigen::Index a) {
      around.clear();
      for (int k = vt.offsets[a]; k < vt.offsets[a + 1]; ++k) {
        const int l = vt.triangles[static_cast<std::size_t>(k)];
        for (int c = 0; c < 3; ++c)
          if (F(l, c) > a) around.emplace_back(F(l, c), l);
      }
      std::sort(around.begin(), around.end());
    };
    auto for_each_edge = [&](auto&& emit) {
      for (std::size_t i = 0; i < around.size();) {
        std::size_t j = i;
        while (j < around.size() && around[j].first == around[i].first) ++j;
        if (j - i == 2) emit(around[i].first, around[i].second, around[i + 1].second);
        i = j;
      }
    };
#pragma omp for schedule(static)
    for (Eigen::Index a = 0; a < n; ++a) {
      collect(a);
      int count = 0;
      for_each_edge([&](int, int, int) { ++count; });
      first[a + 1] = count;
    }
#pragma omp single
    {
      for (Eigen::Index a = 0; a < n; ++a) first[a + 1] += first[a];
      edges.resize(static_cast<std::size_t>(first[n]));
    }
#pragma omp for schedule(static)
    for (Eigen::Index a = 0; a < n; ++a) {
      collect(a);
      int k = first[a];
      const Eigen::Vector3d xa = V.row(a).transpose();
      for_each_edge([&](int b, int l0, int l1) {
        const Eigen::Vector3d xb = V.row(b).transpose();
        edges[static_cast<std::size_t>(k++)] = {{l0, l1}, (xa - xb).norm()};
      });
    }
  }
  return edges;
}

std::vector<std::array<int, 3>> triangle_edges(const std::vector<InteriorEdge>& edges,
                                               Eigen::Index num_triangles) {
  std::vector<std::array<int, 3>> own(static_cast<std::size_t>(num_triangles), {-1, -1, -1});
  std::vector<unsigned char> count(static_cast<std::size_t>(num_triangles), 0);
  for (std::size_t e = 0; e < edges.size(); ++e)  // ascending e: each list comes out sorted
    for (int t : edges[e].tri) own[t][count[t]++] = static_cast<int>(e);
  return own;
}

SparseMatrix assemble_gradient(const Triangles& F, const TriangleGradients& grads,
                               const VertexTriangles& vt) {
  const auto n = static_cast<Eigen::Index>(vt.offsets.size()) - 1;
  SparseMatrix G(3 * F.rows(), n);
  int* outer = G.outerIndexPtr();
  for (Eigen::Index v = 0; v <= n; ++v) outer[v] = 3 * vt.offsets[v];
  G.resizeNonZeros(outer[n]);
  int* inner = G.innerIndexPtr();
  double* values = G.valuePtr();
#pragma omp parallel for schedule(static)
  for (Eigen::Index v = 0; v < n; ++v) {
    int k = outer[v];
    for (int t = vt.offsets[v]; t < vt.offsets[v + 1]; ++t) {  // ascending triangles
      const int l = vt.triangles[static_cast<std::size_t>(t)], i = corner(F, l, static_cast<int>(v));
      for (int d = 0; d < 3; ++d) {
        inner[k] = 3 * l + d;
        values[k++] = grads(l, 3 * i + d);
      }
    }
  }
  return G;
}

SparseMatrix assemble_gta(const Triangles& F, const TriangleGradients& grads,
                          const Eigen::VectorXd& areas, int n) {
  const Eigen::Index m = F.rows();
  SparseMatrix GtA(n, 3 * m);
  int* outer = GtA.outerIndexPtr();
  for (Eigen::Index c = 0; c <= 3 * m; ++c) outer[c] = static_cast<int>(3 * c);
  GtA.resizeNonZeros(9 * m);
  int* inner = GtA.innerIndexPtr();
  double* values = GtA.valuePtr();
#pragma omp parallel for schedule(static)
  for (Eigen::Index l = 0; l < m; ++l) {
    int order[3] = {0, 1, 2};  // corners by ascending vertex id: a column's row order
    std::sort(order, order + 3, [&](int p, int q) { return F(l, p) < F(l, q); });
    for (int d = 0; d < 3; ++d)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Index at = 9 * l + 3 * d + k;
        inner[at] = F(l, order[k]);
        values[at] = grads(l, 3 * order[k] + d) * areas[l];
      }
  }
  return GtA;
}

SparseMatrix assemble_laplacian(const Triangles& F, const TriangleGradients& grads,
                                const Eigen::VectorXd& areas, const VertexTriangles& vt) {
  const auto n = static_cast<Eigen::Index>(vt.offsets.size()) - 1;
  // Column v of GtA · G: G's column v (rows 3l+d, l ascending) times GtA's columns 3l+d.
  return assemble_columns(n, n, true, [&](Eigen::Index v, ColumnAccumulator& acc) {
    for (int t = vt.offsets[v]; t < vt.offsets[v + 1]; ++t) {
      const int l = vt.triangles[static_cast<std::size_t>(t)], i = corner(F, l, static_cast<int>(v));
      for (int d = 0; d < 3; ++d) {
        const double y = grads(l, 3 * i + d);
        for (int j = 0; j < 3; ++j) acc.add(F(l, j), (grads(l, 3 * j + d) * areas[l]) * y);
      }
    }
  });
}

SparseMatrix assemble_gtdbd(const Triangles& F, const TriangleGradients& grads,
                            const std::vector<InteriorEdge>& edges, int n) {
  const auto own = triangle_edges(edges, F.rows());
  return assemble_columns(n, 3 * F.rows(), false, [&](Eigen::Index c, ColumnAccumulator& acc) {
    const int l = static_cast<int>(c / 3), d = static_cast<int>(c % 3);
    JumpColumns col;
    col.build(F, grads, edges, own[static_cast<std::size_t>(l)], l, acc.values());
    for (int k = 0; k < col.size; ++k) acc.add(col.vertex[k], acc.values() ? col.value[d][k] : 0.0);
  });
}

SparseMatrix assemble_regularizer(const Triangles& F, const TriangleGradients& grads,
                                  const std::vector<InteriorEdge>& edges,
                                  const VertexTriangles& vt) {
  const auto n = static_cast<Eigen::Index>(vt.offsets.size()) - 1;
  const auto own = triangle_edges(edges, F.rows());
  // Column v of GtDBD · G: G's column v (rows 3l+d, l ascending) times GtDBD's columns 3l+d.
  return assemble_columns(n, n, false, [&](Eigen::Index v, ColumnAccumulator& acc) {
    JumpColumns col;
    for (int t = vt.offsets[v]; t < vt.offsets[v + 1]; ++t) {
      const int l = vt.triangles[static_cast<std::size_t>(t)], i = corner(F, l, static_cast<int>(v));
      col.build(F, grads, edges, own[static_cast<std::size_t>(l)], l, acc.values());
      if (!acc.values()) {  // counting pass: the rows only
        for (int k = 0; k < col.size; ++k) acc.add(col.vertex[k], 0.0);
        continue;
      }
      for (int d = 0; d < 3; ++d) {  // G's rows 3l+d in order: the product's summation order
        const double y = grads(l, 3 * i + d);
        for (int k = 0; k < col.size; ++k) acc.add(col.vertex[k], col.value[d][k] * y);
      }
    }
  });
}

namespace {

// The free rows of the β > 0 right-hand side pattern: calls emit(k, column, area, reg) for
// every entry k of `out`'s structure (built here), area and reg being Gᵀ A's and
// Gᵀ D₃ᵀ B₃ D₃'s values on the union pattern.
template <class Emit>
void wide_free_rows(const Triangles& F, const TriangleGradients& grads,
                    const Eigen::VectorXd& areas, const std::vector<InteriorEdge>& edges,
                    const VertexTriangles& vt, const std::vector<int>& free_, SparseMatrixR& out,
                    Emit&& emit) {
  const auto nF = static_cast<Eigen::Index>(free_.size());
  const auto own = triangle_edges(edges, F.rows());
  out.resize(nF, 3 * F.rows());
  int* outer = out.outerIndexPtr();
  // Row v's triangles, ascending: v's own, and across each interior edge of those the
  // triangle that does not contain v (v is its opposite vertex there, so in its support).
  auto row_triangles = [&](int v, std::vector<int>& T) {
    T.clear();
    for (int t = vt.offsets[v]; t < vt.offsets[v + 1]; ++t) {
      const int l = vt.triangles[static_cast<std::size_t>(t)];
      T.push_back(l);
      for (int e : own[static_cast<std::size_t>(l)]) {
        if (e < 0) continue;
        const int o = edges[e].tri[0] == l ? edges[e].tri[1] : edges[e].tri[0];
        if (F(o, 0) != v && F(o, 1) != v && F(o, 2) != v) T.push_back(o);
      }
    }
    std::sort(T.begin(), T.end());
    T.erase(std::unique(T.begin(), T.end()), T.end());
  };
#pragma omp parallel
  {
    std::vector<int> T;
#pragma omp for schedule(static)
    for (Eigen::Index i = 0; i < nF; ++i) {
      row_triangles(free_[static_cast<std::size_t>(i)], T);
      outer[i + 1] = 3 * static_cast<int>(T.size());
    }
#pragma omp single
    {
      for (Eigen::Index i = 0; i < nF; ++i) outer[i + 1] += outer[i];
      out.resizeNonZeros(outer[nF]);
    }
#pragma omp for schedule(static)
    for (Eigen::Index i = 0; i < nF; ++i) {
      const int v = free_[static_cast<std::size_t>(i)];
      row_triangles(v, T);
      int k = outer[i];
      for (int l : T) {
        double jump[3] = {0, 0, 0};
        const bool has_d = jump_values(F, grads, edges, own[static_cast<std::size_t>(l)], l, v, jump);
        const bool has_a = F(l, 0) == v || F(l, 1) == v || F(l, 2) == v;
        const int c = has_a ? corner(F, l, v) : 0;
        for (int d = 0; d < 3; ++d, ++k) {
          const double a = has_a ? grads(l, 3 * c + d) * areas[l] : 0.0;
          const double r = has_d ? jump[d] : 0.0;
          out.innerIndexPtr()[k] = 3 * l + d;
          // As Eigen's `X + 0.0 * Y` on the union pattern (system_blocks.h).
          emit(k, (has_a ? a : 0.0) + (has_d ? 0.0 * r : 0.0),
               (has_d ? r : 0.0) + (has_a ? 0.0 * a : 0.0));
        }
      }
    }
  }
}

}  // namespace

void assemble_wide_free_rows(const Triangles& F, const TriangleGradients& grads,
                             const Eigen::VectorXd& areas, const std::vector<InteriorEdge>& edges,
                             const VertexTriangles& vt, const std::vector<int>& free_,
                             SparseMatrixR& area, SparseMatrixR& reg) {
  // Two passes (the pair is the reference form; the engine builds the weighted sum).
  wide_free_rows(F, grads, areas, edges, vt, free_, area,
                 [&](int k, double a, double) { area.valuePtr()[k] = a; });
  wide_free_rows(F, grads, areas, edges, vt, free_, reg,
                 [&](int k, double, double r) { reg.valuePtr()[k] = r; });
}

SparseMatrixR assemble_wide_free_rows(const Triangles& F, const TriangleGradients& grads,
                                      const Eigen::VectorXd& areas,
                                      const std::vector<InteriorEdge>& edges,
                                      const VertexTriangles& vt, const std::vector<int>& free_,
                                      double w_area, double w_reg) {
  SparseMatrixR out;
  wide_free_rows(F, grads, areas, edges, vt, free_, out, [&](int k, double a, double r) {
    out.valuePtr()[k] = w_area * a + w_reg * r;  // combine()'s arithmetic, value by value
  });
  return out;
}

}  // namespace hdeform

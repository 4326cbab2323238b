#include "vertex_ordering.h"

#include <metis.h>

#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>

namespace hdeform {

namespace {

// METIS 5.1 keeps its random generator in global state (GKlib's): one call at a time, so a
// mesh gets the same order whichever other meshes are being opened meanwhile.
std::mutex metis_mutex;

// The graph METIS orders: the union of the parts' strictly lower patterns, made symmetric, as
// CSR adjacency without self-loops, built straight from the patterns (two passes, a mark per
// vertex: integers only).
struct Graph {
  std::vector<idx_t> xadj, adjncy;
};

template <class Visit>
void for_each_edge(std::initializer_list<const SparseMatrix*> parts, std::vector<Eigen::Index>& mark,
                   Visit&& visit) {
  std::fill(mark.begin(), mark.end(), -1);
  const Eigen::Index n = static_cast<Eigen::Index>(mark.size());
  for (Eigen::Index j = 0; j < n; ++j)
    for (const SparseMatrix* part : parts)
      for (SparseMatrix::InnerIterator it(*part, j); it; ++it)
        if (const Eigen::Index i = it.row(); i > j && mark[i] != j) {
          mark[i] = j;  // an edge both parts hold is one edge
          visit(static_cast<idx_t>(i), static_cast<idx_t>(j));
        }
}

Graph graph_of(std::initializer_list<const SparseMatrix*> parts) {
  const Eigen::Index n = (*parts.begin())->cols();
  for (const SparseMatrix* part : parts)
    if (part->rows() != n || part->cols() != n)
      throw std::logic_error("nested_dissection: the patterns are not all n × n");
  std::vector<Eigen::Index> mark(n);
  Graph g;
  g.xadj.assign(n + 1, 0);
  for_each_edge(parts, mark, [&](idx_t i, idx_t j) { ++g.xadj[i + 1], ++g.xadj[j + 1]; });
  std::partial_sum(g.xadj.begin(), g.xadj.end(), g.xadj.begin());
  g.adjncy.resize(g.xadj[n]);
  std::vector<idx_t> next(g.xadj.begin(), g.xadj.end() - 1);
  for_each_edge(parts, mark, [&](idx_t i, idx_t j) {
    g.adjncy[next[i]++] = j;
    g.adjncy[next[j]++] = i;
  });
  return g;
}

std::vector<int> metis_order(Graph g) {
  const std::size_t n = g.xadj.size() - 1;
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  if (g.adjncy.empty()) return order;  // no edges, no fill: any order (METIS needs one)
  idx_t nv = static_cast<idx_t>(n);
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_NUMBERING] = 0;
  std::vector<idx_t> perm(n), iperm(n);
  int status;
  {
    std::lock_guard lock(metis_mutex);
    status = METIS_NodeND(&nv, g.xadj.data(), g.adjncy.data(), nullptr, options, perm.data(),
                          iperm.data());
  }
  if (status != METIS_OK)
    throw std::runtime_error("METIS ordering failed (METIS status " + std::to_string(status) + ")");
  // METIS's perm[k] is the vertex eliminated k-th: our order.
  std::copy(perm.begin(), perm.end(), order.begin());
  return order;
}

}  // namespace

std::vector<int> nested_dissection(const SparseMatrix& A) { return metis_order(graph_of({&A})); }

std::vector<int> nested_dissection(const SparseMatrix& A, const SparseMatrix& B) {
  if (A.rows() != B.rows() || A.cols() != B.cols())
    throw std::logic_error("nested_dissection: the two patterns differ in size");
  return metis_order(graph_of({&A, &B}));
}

std::vector<int> restrict_order(const std::vector<int>& order, const std::vector<int>& free) {
  std::vector<int> index_of(order.size(), -1);
  for (std::size_t i = 0; i < free.size(); ++i) index_of.at(free[i]) = static_cast<int>(i);
  std::vector<int> perm;
  perm.reserve(free.size());
  for (int v : order)
    if (int& i = index_of.at(v); i >= 0) {
      perm.push_back(i);
      i = -1;  // a repeated vertex is not a permutation: caught by the size check below
    }
  if (perm.size() != free.size())
    throw std::logic_error("restrict_order: order is not a permutation of the vertices");
  return perm;
}

}  // namespace hdeform

// Fill-reducing orderings shared by every constraint set of one mesh (SPEC.md §Solve).
// METIS nested dissection of the whole mesh's pattern is computed once per mesh and
// pattern (β = 0's L, β > 0's L ∪ Reg); a constraint set orders K_FF by each free vertex's
// rank in it. Removing the constrained vertices keeps every separator a separator, so the
// restricted order keeps METIS's fill without a METIS call per constraint set
// (docs/benchmarks.md "Orderings shared per mesh").
#pragma once

#include "engine/mesh/validate.h"
#include "engine/operators/operators.h"

#include <cstddef>
#include <vector>

namespace hdeform {

// From this many vertices on, nested_dissection splits the graph once (METIS's vertex
// separator) and orders the two halves on two threads (run_beside.h); below it, one METIS
// call (through CHOLMOD) on the caller's thread.
inline constexpr std::size_t kSplitOrderFrom = 20000;

// METIS nested dissection of the symmetric pattern of A, n × n, read from its lower
// triangle: order[k] = the vertex eliminated k-th. Deterministic, also with concurrent
// calls, which run at once (each thread has its own METIS random stream:
// vertex_ordering.cpp). Two threads from kSplitOrderFrom vertices on (the caller's and one
// from the budget of run_beside.h; the caller alone when it is spent), else serial.
std::vector<int> nested_dissection(const SparseMatrix& A);
// The same for the union of the patterns of A and B (both n × n, symmetric).
std::vector<int> nested_dissection(const SparseMatrix& A, const SparseMatrix& B);
// The same for the mesh's edge graph (validate_mesh's): the β = 0 order, known without L.
// Where no cotangent weights cancel it is nested_dissection(L)
// (VertexOrdering.EdgeGraphIsLsPatternWithItsZeros).
std::vector<int> nested_dissection(const EdgePattern& lower);

// The permutation of a block whose row i is vertex free[i]: perm[k] = i of the k-th free
// vertex in `order` (a permutation of 0..n−1). free: distinct vertex ids in [0, n).
std::vector<int> restrict_order(const std::vector<int>& order, const std::vector<int>& free);

}  // namespace hdeform

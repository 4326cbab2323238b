#include "engine/solve/vertex_ordering.h"

#include "engine/runtime/run_beside.h"

#include <Eigen/CholmodSupport>
#include <metis.h>
#include <pthread.h>

#include <csetjmp>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>

// METIS 5.1 (Debian's build) draws its random numbers through GKlib's gk_randinit,
// gk_randint32 and gk_randint64, which call libc's srand / rand: one stream for the whole
// process, so two calls at once would each get an order that depends on the other. These
// definitions take their place (libmetis calls them through its PLT; CMakeLists.txt exports
// them from every program that links the solver) with the same generator, kept per thread:
// each call sees exactly the stream it would see alone, and calls on different threads run
// at once. Checked by VertexOrdering.ConcurrentCallsGiveTheSerialOrder and
// VertexOrdering.MetisDrawsFromItsOwnStream.
namespace {
struct ThreadRandom {
  random_data data{};
  char state[128] = {};  // 128 bytes: glibc's TYPE_3, the generator behind rand()
  ThreadRandom() { initstate_r(1, state, sizeof state, &data); }
};
thread_local ThreadRandom thread_random;

std::uint32_t next_random() {
  std::int32_t r = 0;
  random_r(&thread_random.data, &r);
  return static_cast<std::uint32_t>(r);
}
}  // namespace

// GKlib also traps SIGABRT and SIGTERM (its exits on an allocation failure or an error) for
// the span of each METIS call, so that they jump back and METIS returns an error code: it
// saves the process's handlers when a call starts and puts them back when it ends. Two calls
// at once would put them back out of order and leave GKlib's handler in place for good (an
// abort() anywhere later would then jump to a buffer that is not there). These two take the
// place of gk_sigtrap / gk_siguntrap the same way: the first call in installs GKlib's handler,
// the last one out restores what was there. Each thread keeps its own jump buffers, as in
// GKlib. Checked by VertexOrdering.ConcurrentCallsLeaveTheSignalHandlersAlone.
namespace {
constexpr int kJumpBuffers = 128;  // GKlib's MAX_JBUFS (gk_jbufs: 128 jmp_buf of 200 bytes)
}  // namespace
extern "C" {
extern __thread int gk_cur_jbufs;  // libmetis: this thread's innermost jump buffer (−1: none)
extern __thread jmp_buf gk_jbufs[kJumpBuffers];  // libmetis: this thread's jump buffers
void gk_sigthrow(int signum);      // libmetis: longjmp to it
int gk_malloc_init();              // libmetis: track this thread's METIS allocations…
void gk_malloc_cleanup(int showstats);  // …and free what a jump out left behind
int gk_sigtrap();
int gk_siguntrap();
}
namespace {
std::mutex trap_mutex;
int trapped = 0;  // METIS calls in progress, under trap_mutex
sighandler_t saved_abort = SIG_DFL, saved_terminate = SIG_DFL;
}  // namespace

extern "C" {
int gk_sigtrap() {
  if (gk_cur_jbufs + 1 >= kJumpBuffers) return 0;
  ++gk_cur_jbufs;
  std::lock_guard lock(trap_mutex);
  if (trapped++ == 0) {
    saved_abort = std::signal(SIGABRT, gk_sigthrow);
    saved_terminate = std::signal(SIGTERM, gk_sigthrow);
  }
  return 1;
}
int gk_siguntrap() {
  if (gk_cur_jbufs == -1) return 0;
  {
    std::lock_guard lock(trap_mutex);
    if (--trapped == 0) {
      std::signal(SIGABRT, saved_abort);
      std::signal(SIGTERM, saved_terminate);
    }
  }
  --gk_cur_jbufs;
  return 1;
}

void gk_randinit(std::uint64_t seed) {
  srandom_r(static_cast<unsigned>(seed), &thread_random.data);
}
std::uint32_t gk_randint32() { return next_random(); }
std::uint64_t gk_randint64() {
  const std::uint64_t high = next_random();  // GKlib's order: the first draw is the high word
  return (high << 32) | next_random();
}
}

namespace hdeform {

namespace {

// One cholmod_common for a call; METIS alone, as the factorizations use it (solver.cpp).
struct Common {
  cholmod_common c;
  Common() { cholmod_start(&c); }
  ~Common() { cholmod_finish(&c); }
  Common(const Common&) = delete;
  Common& operator=(const Common&) = delete;
};

// CHOLMOD's arrays are METIS's graph as they are (cholmod_copy's pattern without diagonal).
static_assert(sizeof(idx_t) == sizeof(int), "Debian's METIS: 32-bit idx_t, as CHOLMOD's int");

void check_metis(int status, const char* what) {
  if (status != METIS_OK)
    throw std::runtime_error(std::string("METIS ") + what + " failed (status " +
                             std::to_string(status) + ")");
}

// GKlib jumps out of its SIGABRT handler with longjmp to a buffer set by setjmp, which does
// not save the signal mask in glibc: after a trapped failure SIGABRT stays blocked on the
// thread, and the next failure's raise() returns into METIS with a null pointer. Each METIS
// call puts the thread's mask back (VertexOrdering.SplitOrderOutOfMemoryIsAnError).
struct KeepSignalMask {
  sigset_t mask;
  KeepSignalMask() { pthread_sigmask(SIG_SETMASK, nullptr, &mask); }
  ~KeepSignalMask() { pthread_sigmask(SIG_SETMASK, &mask, nullptr); }
  KeepSignalMask(const KeepSignalMask&) = delete;
  KeepSignalMask& operator=(const KeepSignalMask&) = delete;
};

// An adjacency graph in METIS's form: the neighbours of v are adjncy[xadj[v] .. xadj[v+1]).
struct Graph {
  std::vector<idx_t> xadj{0}, adjncy;
  idx_t n() const { return static_cast<idx_t>(xadj.size()) - 1; }
};

// The subgraph induced by the vertices v with part[v] == side; ids[i] = vertex of node i.
Graph induced(const idx_t* xadj, const idx_t* adjncy, const std::vector<idx_t>& part, idx_t side,
              std::vector<idx_t>& ids) {
  std::vector<idx_t> local(part.size(), -1);
  for (std::size_t v = 0; v < part.size(); ++v)
    if (part[v] == side) {
      local[v] = static_cast<idx_t>(ids.size());
      ids.push_back(static_cast<idx_t>(v));
    }
  Graph g;
  g.xadj.reserve(ids.size() + 1);
  for (idx_t v : ids) {
    for (idx_t e = xadj[v]; e < xadj[v + 1]; ++e)
      if (const idx_t w = local[adjncy[e]]; w >= 0) g.adjncy.push_back(w);
    g.xadj.push_back(static_cast<idx_t>(g.adjncy.size()));
  }
  return g;
}

// METIS_NodeND of a graph, as cholmod_metis calls it (default options); without edges, the
// identity (as cholmod_metis, which does not call METIS then).
std::vector<idx_t> node_nd(Graph& g) {
  idx_t n = g.n();
  std::vector<idx_t> perm(static_cast<std::size_t>(n)), iperm(perm.size());
  if (g.adjncy.empty()) {
    std::iota(perm.begin(), perm.end(), 0);
    return perm;
  }
  int status;
  {
    KeepSignalMask mask;
    status = METIS_NodeND(&n, g.xadj.data(), g.adjncy.data(), nullptr, nullptr, perm.data(),
                          iperm.data());
  }
  check_metis(status, "nested dissection");
  return perm;
}

// METIS_ComputeVertexSeparator as METIS_NodeND runs itself: Debian's 5.1.0 sets no trap
// around it (NodeND does), so an allocation failure inside would abort the process, or jump
// through another call's trap to a buffer this thread does not have. Same prologue as
// NodeND's (ometis.c): track the allocations, trap, and on a jump back free and return
// METIS_ERROR_MEMORY. Only trivially destructible objects here: the jump skips destructors.
int trapped_vertex_separator(idx_t* n, idx_t* xadj, idx_t* adjncy, idx_t* separator,
                             idx_t* part) {
  if (!gk_malloc_init()) return METIS_ERROR_MEMORY;
  if (!gk_sigtrap()) {
    gk_malloc_cleanup(0);
    return METIS_ERROR;
  }
  volatile int status = METIS_ERROR_MEMORY;  // read after a jump back
  if (sigsetjmp(gk_jbufs[gk_cur_jbufs], /*savemask=*/1) == 0)  // glibc: jmp_buf is sigjmp_buf
    status = METIS_ComputeVertexSeparator(n, xadj, adjncy, nullptr, nullptr, separator, part);
  gk_siguntrap();
  gk_malloc_cleanup(0);
  return status;
}

std::vector<int> metis_order(cholmod_sparse* A, cholmod_common* c) {
  std::vector<int> order(A->nrow);
  if (order.empty()) return order;
  if (order.size() < kSplitOrderFrom) {
    // postorder 0: each constraint set's analysis postorders its own elimination tree.
    KeepSignalMask mask;
    if (!cholmod_metis(A, nullptr, 0, /*postorder=*/0, order.data(), c))
      throw std::runtime_error("METIS ordering failed (CHOLMOD status " +
                               std::to_string(c->status) + ")");
    return order;
  }
  // METIS's own first level on one thread, its two halves on two: the halves are ordered
  // first, each by METIS_NodeND, then the separator (as METIS numbers it). Same fill as one
  // METIS_NodeND call, 0.6× its time on two cores (docs/benchmarks.md "Nested dissection
  // on two threads").
  cholmod_sparse* graph = cholmod_copy(A, /*stype=*/0, /*mode: pattern, no diagonal=*/-1, c);
  if (!graph) throw std::runtime_error("CHOLMOD could not form the ordering's graph");
  std::vector<idx_t> part(order.size()), ids[2];
  Graph half[2];
  try {
    const auto* xadj = static_cast<const idx_t*>(graph->p);
    const auto* adjncy = static_cast<const idx_t*>(graph->i);
    if (xadj[order.size()] == 0) {  // no edge: METIS would find no separator
      cholmod_free_sparse(&graph, c);
      std::iota(order.begin(), order.end(), 0);
      return order;
    }
    idx_t n = static_cast<idx_t>(order.size()), separator = 0;
    check_metis(trapped_vertex_separator(&n, static_cast<idx_t*>(graph->p),
                                         static_cast<idx_t*>(graph->i), &separator, part.data()),
                "vertex separator");
    for (idx_t side : {0, 1}) half[side] = induced(xadj, adjncy, part, side, ids[side]);
    cholmod_free_sparse(&graph, c);
  } catch (...) {
    cholmod_free_sparse(&graph, c);
    throw;
  }
  // The second half on a thread of the budget (run_beside.h), else after the first.
  std::vector<idx_t> perm[2];
  run_beside([&] { perm[0] = node_nd(half[0]); }, [&] { perm[1] = node_nd(half[1]); });
  std::size_t k = 0;
  for (int side : {0, 1})
    for (idx_t i : perm[side]) order[k++] = ids[side][static_cast<std::size_t>(i)];
  for (std::size_t v = 0; v < part.size(); ++v)
    if (part[v] == 2) order[k++] = static_cast<int>(v);
  return order;
}

}  // namespace

std::vector<int> nested_dissection(const SparseMatrix& A) {
  Common common;
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  return metis_order(&a, &common.c);
}

std::vector<int> nested_dissection(const EdgePattern& lower) {
  const std::size_t n = lower.start.empty() ? 0 : lower.start.size() - 1;
  if (lower.start.empty() || static_cast<std::size_t>(lower.start.back()) != lower.rows.size())
    throw std::logic_error("nested_dissection: malformed edge pattern");
  Common common;
  // A view, as viewAsCholmod makes one of L: CHOLMOD reads the arrays and never writes them.
  cholmod_sparse a{};
  a.nrow = a.ncol = n;
  a.nzmax = lower.rows.size();
  a.p = const_cast<int*>(lower.start.data());
  a.i = const_cast<int*>(lower.rows.data());
  a.stype = -1;  // the lower triangle of a symmetric pattern
  a.itype = CHOLMOD_INT;
  a.xtype = CHOLMOD_PATTERN;
  a.dtype = CHOLMOD_DOUBLE;
  a.sorted = 1;
  a.packed = 1;
  return metis_order(&a, &common.c);
}

std::vector<int> nested_dissection(const SparseMatrix& A, const SparseMatrix& B) {
  if (A.rows() != B.rows() || A.cols() != B.cols())
    throw std::logic_error("nested_dissection: the two patterns differ in size");
  Common common;
  cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
  cholmod_sparse b = Eigen::viewAsCholmod(B.selfadjointView<Eigen::Lower>());
  double one[2] = {1, 0};
  // Pattern only (values = FALSE): the union costs integers, never a sum of values.
  cholmod_sparse* u = cholmod_add(&a, &b, one, one, /*values=*/0, /*sorted=*/1, &common.c);
  if (!u) throw std::runtime_error("CHOLMOD could not form the union pattern");
  try {
    auto order = metis_order(u, &common.c);
    cholmod_free_sparse(&u, &common.c);
    return order;
  } catch (...) {
    cholmod_free_sparse(&u, &common.c);
    throw;
  }
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

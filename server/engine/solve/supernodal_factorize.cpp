#include "engine/solve/supernodal_factorize.h"

#include "engine/runtime/one_blas_thread.h"
#include "engine/runtime/two_threads.h"

#include <cblas.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <stdexcept>

extern "C" {
// LAPACK (OpenBLAS's): Cholesky of a dense block. The trailing length is gfortran's hidden
// argument for the character one.
void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info,
             std::size_t uplo_len);
}

namespace hdeform {

namespace {
// Column block width of the large updates and of the two-thread panel factorization.
constexpr int kUpdateBlock = 128;
constexpr int kPanelBlock = 128;
}  // namespace

// CHOLMOD's supernodal layout (cholmod_core.h): supernode s holds columns k1 = super[s] …
// k2−1 = super[s+1]−1; its rows are Ls[pi[s] … pi[s+1]), ascending, the first k2−k1 of them
// k1 … k2−1; its values the column-major nsrow × (k2−k1) block at Lx + px[s].

SupernodalFactorPlan::SupernodalFactorPlan(const cholmod_factor& L, std::size_t min_rows) {
  const int nsuper = static_cast<int>(L.nsuper);
  const int* super = static_cast<const int*>(L.super);
  const int* pi = static_cast<const int*>(L.pi);
  const int* Ls = static_cast<const int*>(L.s);
  super_of_.resize(L.n);
  for (int s = 0; s < nsuper; ++s)
    for (int k = super[s]; k < super[s + 1]; ++k) super_of_[static_cast<std::size_t>(k)] = s;
  // Left-looking: a supernode's work is its own dpotrf + dtrsm plus every update it pulls
  // from a descendant (descendant d with ndcol columns updating target t: its rows from the
  // first one in t, ndrow2 of them, ndrow1 inside t's columns).
  std::vector<double> work(static_cast<std::size_t>(nsuper), 0.0);
  for (int d = 0; d < nsuper; ++d) {
    const double ndcol = super[d + 1] - super[d];
    const int ndrow = pi[d + 1] - pi[d];
    max_rows_ = std::max<std::size_t>(max_rows_, static_cast<std::size_t>(ndrow));
    const double below = ndrow - ndcol;
    work[d] += ndcol * ndcol * ndcol / 3 + below * ndcol * ndcol;
    for (int p1 = static_cast<int>(ndcol); p1 < ndrow;) {
      const int t = super_of_[static_cast<std::size_t>(Ls[pi[d] + p1])];
      int p2 = p1;
      while (p2 < ndrow && Ls[pi[d] + p2] < super[t + 1]) ++p2;
      const std::size_t ndrow1 = p2 - p1, ndrow2 = ndrow - p1;
      max_update_ = std::max(max_update_, std::min<std::size_t>(ndrow1, kUpdateBlock) * ndrow2);
      work[t] += ndcol * static_cast<double>(ndrow1) * (static_cast<double>(ndrow2) * 2 - ndrow1);
      p1 = p2;
    }
  }
  for (double w : work) flops_ += w;
  part_of_.assign(static_cast<std::size_t>(nsuper), -1);
  if (L.n < min_rows) return;
  auto two_lane = [&](int s, double w) { return w >= kTwoLaneFlops && super[s + 1] - super[s] >= 2; };
  // The top's supernodes are factored one after another; a big one by both threads (its
  // columns in two halves), so on the top it costs about half its work.
  std::vector<double> top_work = work;
  for (int s = 0; s < nsuper; ++s)
    if (two_lane(s, work[static_cast<std::size_t>(s)])) top_work[static_cast<std::size_t>(s)] /= 2;
  split_ = split_supernodal_tree(L, work, 8, 0.8, &top_work);
  for (std::size_t p = 0; p < split_.parts.size(); ++p)
    for (int s : split_.parts[p]) part_of_[static_cast<std::size_t>(s)] = static_cast<int>(p);
  for (int s : split_.top)
    if (two_lane(s, work[static_cast<std::size_t>(s)])) two_lane_.push_back(s);
}

std::size_t SupernodalFactorPlan::memory_bytes() const {
  std::size_t ints = super_of_.capacity() + part_of_.capacity() + split_.top.capacity() +
                    two_lane_.capacity();
  for (const auto& p : split_.parts) ints += p.capacity();
  return ints * sizeof(int) + split_.work.capacity() * sizeof(double) + sizeof(*this);
}

namespace {

// The lower triangle of P A Pᵀ in compressed columns (CHOLMOD builds the same copy).
struct PermutedLower {
  std::vector<int> p, i;
  std::vector<double> x;
};

PermutedLower permuted_lower(const cholmod_sparse& A, const int* perm) {
  const int n = static_cast<int>(A.nrow);
  const int* Ap = static_cast<const int*>(A.p);
  const int* Ai = static_cast<const int*>(A.i);
  const int* Anz = static_cast<const int*>(A.nz);
  const double* Ax = static_cast<const double*>(A.x);
  std::vector<int> pinv(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) pinv[static_cast<std::size_t>(perm[k])] = k;
  const bool lower = A.stype < 0;
  auto end = [&](int j) { return A.packed ? Ap[j + 1] : Ap[j] + Anz[j]; };
  PermutedLower C;
  C.p.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int j = 0; j < n; ++j)
    for (int q = Ap[j]; q < end(j); ++q) {
      const int i = Ai[q];
      if (lower ? i < j : i > j) continue;  // the other triangle: CHOLMOD ignores it too
      ++C.p[static_cast<std::size_t>(std::min(pinv[i], pinv[j])) + 1];
    }
  for (int k = 0; k < n; ++k) C.p[k + 1] += C.p[k];
  C.i.resize(static_cast<std::size_t>(C.p[n]));
  C.x.resize(static_cast<std::size_t>(C.p[n]));
  std::vector<int> fill(C.p.begin(), C.p.end() - 1);
  for (int j = 0; j < n; ++j)
    for (int q = Ap[j]; q < end(j); ++q) {
      const int i = Ai[q];
      if (lower ? i < j : i > j) continue;
      const int a = pinv[i], b = pinv[j];
      const int at = fill[std::min(a, b)]++;
      C.i[at] = std::max(a, b);
      C.x[at] = Ax[q];
    }
  return C;
}

struct Factor {
  const int *super, *pi, *px, *Ls;
  double* Lx;
  const PermutedLower* C;
  const SupernodalFactorPlan* plan;
  const int* super_of;
  const int* part_of;
  // CHOLMOD's descendant lists: head[t] = the first supernode whose next update goes to t,
  // next[d] the one after d, lpos[d] the position in d's rows of the first row of that update.
  std::vector<int> head, next, lpos;
  // Per part: the supernodes whose next target is in the top, in the order they got there.
  std::vector<std::vector<int>> pending;
  std::atomic<int> failed{-1};
  std::atomic<bool> pattern_mismatch{false};
};

struct Scratch {
  std::vector<int> map, rel;
  std::vector<double> c;
};

// d's next update goes to the supernode of its row lpos[d] (if any): link it there. From a
// part, targets in the top are queued on the part (the top links them in part order).
void link_next(Factor& F, int d, int part) {
  const int ndrow = F.pi[d + 1] - F.pi[d];
  if (F.lpos[d] >= ndrow) return;
  const int t = F.super_of[F.Ls[F.pi[d] + F.lpos[d]]];
  if (part >= 0 && F.part_of[t] != part) {
    F.pending[static_cast<std::size_t>(part)].push_back(d);
    return;
  }
  F.next[d] = F.head[t];
  F.head[t] = d;
}

// Supernode s's columns [ka, kb) of P A Pᵀ into its panel x (those columns zeroed first);
// w.map set to s's rows. False (F.failed set) if A has an entry outside L's pattern.
bool gather_columns(Factor& F, int s, int ka, int kb, double* x, Scratch& w) {
  const int k1 = F.super[s];
  const int* rows = F.Ls + F.pi[s];
  const int nsrow = F.pi[s + 1] - F.pi[s];
  for (int i = 0; i < nsrow; ++i) w.map[static_cast<std::size_t>(rows[i])] = i;
  std::fill(x + static_cast<std::ptrdiff_t>(ka - k1) * nsrow,
            x + static_cast<std::ptrdiff_t>(kb - k1) * nsrow, 0.0);
  const PermutedLower& C = *F.C;
  for (int k = ka; k < kb; ++k) {
    double* col = x + static_cast<std::ptrdiff_t>(k - k1) * nsrow;
    for (int q = C.p[k]; q < C.p[k + 1]; ++q) {
      const int m = w.map[static_cast<std::size_t>(C.i[q])];
      // An entry outside the analysed pattern would land in another supernode's rows.
      if (m < 0 || m >= nsrow || rows[m] != C.i[q]) {
        F.pattern_mismatch.store(true);
        int expected = -1;
        F.failed.compare_exchange_strong(expected, k);
        return false;
      }
      col[m] = C.x[q];
    }
  }
  return true;
}

// The first position ≥ p1 in d's rows whose row is ≥ k (d's rows ascend).
int rows_before(const Factor& F, int d, int p1, int k) {
  const int* drows = F.Ls + F.pi[d];
  const int ndrow = F.pi[d + 1] - F.pi[d];
  while (p1 < ndrow && drows[p1] < k) ++p1;
  return p1;
}

// Panel x of s −= descendant d's update to s's columns [ka, kb) (w.map set to s's rows).
// Reads d's panel and lpos[d], writes neither.
void apply_update(const Factor& F, int d, int s, int ka, int kb, double* x, Scratch& w) {
  const int k1 = F.super[s];
  const int nsrow = F.pi[s + 1] - F.pi[s];
  const int* drows = F.Ls + F.pi[d];
  const int ndrow = F.pi[d + 1] - F.pi[d], ndcol = F.super[d + 1] - F.super[d];
  const int p1 = rows_before(F, d, F.lpos[d], ka);
  const int p2 = rows_before(F, d, p1, kb);
  const int ndrow1 = p2 - p1, ndrow2 = ndrow - p1;
  if (ndrow1 == 0) return;
  const double* L1 = F.Lx + F.px[d] + p1;  // rows p1… of d, leading dimension ndrow
  for (int i = 0; i < ndrow2; ++i) w.rel[static_cast<std::size_t>(i)] = w.map[drows[p1 + i]];
  double* c = w.c.data();
  if (static_cast<double>(ndcol) * ndrow1 * ndrow2 <= F.plan->small_update()) {
    // Small: in-house, one column of the update at a time, scattered as it is done. OpenBLAS
    // takes a process-wide lock for its buffer on every call, and two threads making
    // thousands of small calls serialised on it (bench Factorize/100000, docs/benchmarks.md).
    for (int j = 0; j < ndrow1; ++j) {
      std::fill(c + j, c + ndrow2, 0.0);
      for (int k = 0; k < ndcol; ++k) {
        const double* Lk = L1 + static_cast<std::ptrdiff_t>(k) * ndrow;
        const double a = Lk[j];
        for (int i = j; i < ndrow2; ++i) c[i] += Lk[i] * a;
      }
      double* col = x + static_cast<std::ptrdiff_t>(drows[p1 + j] - k1) * nsrow;
      for (int i = j; i < ndrow2; ++i) col[w.rel[static_cast<std::size_t>(i)]] -= c[i];
    }
    return;
  }
  // Large: dsyrk + dgemm in blocks of kUpdateBlock target columns, so the buffer is
  // ndrow2 × kUpdateBlock at most (the whole update would be ≈ 100 MB per thread at 1M).
  for (int j0 = 0; j0 < ndrow1; j0 += kUpdateBlock) {
    const int jb = std::min(kUpdateBlock, ndrow1 - j0), nr = ndrow2 - j0;
    const double* Lj = L1 + j0;
    cblas_dsyrk(CblasColMajor, CblasLower, CblasNoTrans, jb, ndcol, 1.0, Lj, ndrow, 0.0, c, nr);
    if (nr > jb)
      cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, nr - jb, jb, ndcol, 1.0, Lj + jb,
                  ndrow, Lj, ndrow, 0.0, c + jb, nr);
    for (int j = 0; j < jb; ++j) {
      double* col = x + static_cast<std::ptrdiff_t>(drows[p1 + j0 + j] - k1) * nsrow;
      const double* cj = c + static_cast<std::ptrdiff_t>(j) * nr;
      const int* rel = w.rel.data() + j0;
      for (int i = j; i < nr; ++i) col[rel[i]] -= cj[i];
    }
  }
}

// d has been applied to s: its next update starts after s's columns.
void advance(Factor& F, int d, int s, int part) {
  F.lpos[d] = rows_before(F, d, F.lpos[d], F.super[s + 1]);
  link_next(F, d, part);
}

// dpotrf of the b × b block at a (leading dimension ld), the block's first column being s's
// column k; false (F.failed set) if it is not positive definite.
bool factor_block(Factor& F, double* a, int b, int ld, int k) {
  int info = 0;
  dpotrf_("L", &b, a, &ld, &info, 1);
  // OpenBLAS's dpotrf takes a NaN pivot (its test is ajj <= 0): look at the diagonal too.
  for (int j = 0; info == 0 && j < b; ++j)
    if (!(a[static_cast<std::ptrdiff_t>(j) * ld + j] > 0)) info = j + 1;
  if (info == 0) return true;
  int expected = -1;
  F.failed.compare_exchange_strong(expected, k + info - 1);
  return false;
}

// Rows [r0, r1) of the panel x (leading dimension ld) times L_dd⁻ᵀ, L_dd the b × b lower
// triangle at diag.
void solve_rows(const double* diag, int b, double* x, int ld, int r0, int r1) {
  if (r1 > r0)
    cblas_dtrsm(CblasColMajor, CblasRight, CblasLower, CblasTrans, CblasNonUnit, r1 - r0, b, 1.0,
                diag, ld, x + r0, ld);
}

// s is factored: its own first update goes to the supernode of its first row below.
void link_factored(Factor& F, int s, int part) {
  F.lpos[s] = F.super[s + 1] - F.super[s];
  link_next(F, s, part);
}

// Factors supernode s on one thread. part: s's part (−1 for the top).
bool factor_supernode(Factor& F, int s, int part, Scratch& w) {
  const int k1 = F.super[s], k2 = F.super[s + 1], nscol = k2 - k1;
  const int nsrow = F.pi[s + 1] - F.pi[s];
  double* x = F.Lx + F.px[s];
  if (!gather_columns(F, s, k1, k2, x, w)) return false;
  for (int d = F.head[s]; d >= 0;) {
    const int next_d = F.next[d];
    apply_update(F, d, s, k1, k2, x, w);
    advance(F, d, s, part);
    d = next_d;
  }
  if (!factor_block(F, x, nscol, nsrow, k1)) return false;
  solve_rows(x, nscol, x, nsrow, nscol, nsrow);
  link_factored(F, s, part);
  return true;
}

// The column m in (c0, c1) that splits the lower trapezoid of columns [c0, c1) of an
// nrow-row panel into two halves of equal area (the work of an update or of a dtrsm-free
// trailing update is proportional to it); c1 when there is one column.
int balance_columns(int c0, int c1, int nrow) {
  if (c1 - c0 < 2) return c1;
  double total = 0;
  for (int j = c0; j < c1; ++j) total += nrow - j;
  double acc = 0;
  int m = c0;
  while (m < c1 - 1 && (acc += nrow - m) < total / 2) ++m;
  return std::max(m, c0 + 1);
}


}  // namespace

int supernodal_factorize(cholmod_factor& L, const cholmod_sparse& A,
                         const SupernodalFactorPlan& plan, int threads) {
  if (!L.is_super || L.itype != CHOLMOD_INT || !L.x || !L.Perm || A.stype == 0 ||
      A.nrow != L.n || A.ncol != L.n || A.itype != CHOLMOD_INT || A.xtype != CHOLMOD_REAL ||
      plan.super_of_.size() != L.n || plan.part_of_.size() != L.nsuper)
    throw std::logic_error("supernodal_factorize: preconditions not met");
  use_one_blas_thread();
  const int n = static_cast<int>(L.n);
  const int nsuper = static_cast<int>(L.nsuper);
  if (n == 0) {
    L.minor = L.n;
    return -1;
  }
  const PermutedLower C = permuted_lower(A, static_cast<const int*>(L.Perm));
  Factor F;
  F.super = static_cast<const int*>(L.super);
  F.pi = static_cast<const int*>(L.pi);
  F.px = static_cast<const int*>(L.px);
  F.Ls = static_cast<const int*>(L.s);
  F.Lx = static_cast<double*>(L.x);
  F.C = &C;
  F.plan = &plan;
  F.super_of = plan.super_of_.data();
  F.part_of = plan.part_of_.data();
  F.head.assign(static_cast<std::size_t>(nsuper), -1);
  F.next.assign(static_cast<std::size_t>(nsuper), -1);
  F.lpos.assign(static_cast<std::size_t>(nsuper), 0);
  const TreeSplit& split = plan.split_;
  const int K = static_cast<int>(split.parts.size());
  F.pending.resize(static_cast<std::size_t>(K));

  // Everything the threads use is allocated here: an exception (bad_alloc) must never leave
  // the helper thread's function.
  Scratch scratch[2];
  for (int t = 0; t < (K == 0 ? 1 : 2); ++t) {
    scratch[t].map.resize(static_cast<std::size_t>(n));
    scratch[t].rel.resize(plan.max_rows_);
    scratch[t].c.resize(plan.max_update_);
  }
  for (int p = 0; p < K; ++p)
    F.pending[static_cast<std::size_t>(p)].reserve(split.parts[static_cast<std::size_t>(p)].size());
  if (K == 0) {
    Scratch& w = scratch[0];
    for (int s = 0; s < nsuper; ++s)
      if (!factor_supernode(F, s, -1, w)) break;
  } else {
    std::vector<char> two_lane(static_cast<std::size_t>(nsuper), 0);
    for (int s : plan.two_lane_) two_lane[static_cast<std::size_t>(s)] = 1;
    std::atomic<int> next_part{0};
    Barrier2 bar;
    // Each thread of the team (1 or 2) runs this. Every split below (parts, the two halves of
    // a two-lane supernode's columns and rows) is fixed by the plan, and a team of one runs
    // both halves itself: the bits do not depend on the team nor on who ran what.
    auto body = [&](int tid, int team) {
      auto barrier = [&bar, team] {
        if (team > 1) bar.arrive_and_wait();
      };
      // Runs half 0 and half 1 of a step: one each, or both on a team of one.
      auto halves = [&](auto&& fn) {
        if (team > 1) {
          fn(tid);
        } else {
          fn(0);
          fn(1);
        }
      };
      Scratch& w = scratch[tid];
      for (int p; (p = next_part.fetch_add(1)) < K;)
        for (int s : split.parts[static_cast<std::size_t>(p)])
          if (F.failed.load(std::memory_order_relaxed) >= 0 || !factor_supernode(F, s, p, w))
            break;
      // From here on both threads pass the same barriers whatever happens: after a failure
      // (set by either thread at any time) they skip the work, never a barrier, so a
      // failure seen by one thread and not yet by the other cannot part them.
      auto ok = [&F] { return F.failed.load() < 0; };
      barrier();
      if (tid == 0 && ok()) {
        // The parts' updates to the top, linked in part order: the top's descendant lists do
        // not depend on which thread ran which part.
        for (int p = 0; p < K; ++p)
          for (int d : F.pending[static_cast<std::size_t>(p)]) {
            const int t = F.super_of[F.Ls[F.pi[d] + F.lpos[d]]];
            F.next[d] = F.head[t];
            F.head[t] = d;
          }
      }
      barrier();
      for (int s : split.top) {
        if (!two_lane[static_cast<std::size_t>(s)]) {
          if (tid == 0 && ok()) factor_supernode(F, s, -1, w);  // thread 1: at the next barrier
          continue;
        }
        barrier();  // the supernodes before s are factored and linked
        const int k1 = F.super[s], k2 = F.super[s + 1], nscol = k2 - k1;
        const int nsrow = F.pi[s + 1] - F.pi[s];
        double* x = F.Lx + F.px[s];
        // Assembly: each half gathers and updates its own columns of the panel.
        const int kmid = k1 + balance_columns(0, nscol, nsrow);
        halves([&](int h) {
          const int ka = h == 0 ? k1 : kmid, kb = h == 0 ? kmid : k2;
          if (!ok() || !gather_columns(F, s, ka, kb, x, w)) return;
          for (int d = F.head[s]; d >= 0; d = F.next[d]) apply_update(F, d, s, ka, kb, x, w);
        });
        barrier();
        if (tid == 0 && ok())
          for (int d = F.head[s]; d >= 0;) {
            const int next_d = F.next[d];
            advance(F, d, s, -1);
            d = next_d;
          }
        // Right-looking blocked Cholesky of the panel: the diagonal block on thread 0, the
        // rows below it and the trailing columns in halves.
        for (int c0 = 0; c0 < nscol; c0 += kPanelBlock) {
          const int c1 = std::min(nscol, c0 + kPanelBlock), b = c1 - c0;
          double* diag = x + static_cast<std::ptrdiff_t>(c0) * nsrow + c0;
          if (tid == 0 && ok()) factor_block(F, diag, b, nsrow, k1 + c0);
          barrier();
          const int rmid = c1 + (nsrow - c1) / 2;
          halves([&](int h) {
            if (!ok()) return;
            solve_rows(diag, b, x + static_cast<std::ptrdiff_t>(c0) * nsrow, nsrow,
                       h == 0 ? c1 : rmid, h == 0 ? rmid : nsrow);
          });
          barrier();
          if (c1 == nscol) break;  // the same for both: the plan's shape, not a failure
          const int cmid = balance_columns(c1, nscol, nsrow);
          halves([&](int h) {
            const int ca = h == 0 ? c1 : cmid, cb = h == 0 ? cmid : nscol;
            if (cb <= ca || !ok()) return;
            const double* Lc = x + static_cast<std::ptrdiff_t>(c0) * nsrow;  // block column
            double* T = x + static_cast<std::ptrdiff_t>(ca) * nsrow;
            cblas_dsyrk(CblasColMajor, CblasLower, CblasNoTrans, cb - ca, b, -1.0, Lc + ca, nsrow,
                        1.0, T + ca, nsrow);
            if (nsrow > cb)
              cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, nsrow - cb, cb - ca, b, -1.0,
                          Lc + cb, nsrow, Lc + ca, nsrow, 1.0, T + cb, nsrow);
          });
          barrier();
        }
        if (tid == 0 && ok()) link_factored(F, s, -1);
      }
      barrier();
    };
    auto run2 = [](void* ctx, int tid) { (*static_cast<decltype(body)*>(ctx))(tid, 2); };
    if (threads < 2 || !Helper::instance().run(run2, &body)) body(0, 1);
  }
  if (F.pattern_mismatch.load())
    throw std::logic_error("supernodal_factorize: the matrix has entries outside the analysed pattern");
  const int failed = F.failed.load();
  L.minor = failed >= 0 ? static_cast<std::size_t>(failed) : L.n;
  return failed;
}

}  // namespace hdeform

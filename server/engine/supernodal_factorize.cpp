#include "supernodal_factorize.h"

#include "two_threads.h"

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
      max_update_ = std::max(max_update_, ndrow1 * ndrow2);
      work[t] += ndcol * static_cast<double>(ndrow1) * (static_cast<double>(ndrow2) * 2 - ndrow1);
      p1 = p2;
    }
  }
  for (double w : work) flops_ += w;
  part_of_.assign(static_cast<std::size_t>(nsuper), -1);
  if (L.n < min_rows) return;
  split_ = split_supernodal_tree(L, work, 8);
  for (std::size_t p = 0; p < split_.parts.size(); ++p)
    for (int s : split_.parts[p]) part_of_[static_cast<std::size_t>(s)] = static_cast<int>(p);
}

std::size_t SupernodalFactorPlan::memory_bytes() const {
  std::size_t ints = super_of_.capacity() + part_of_.capacity() + split_.top.capacity();
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

// Factors supernode s: its columns of P A Pᵀ, minus its descendants' updates, then dpotrf and
// dtrsm. part: s's part (−1 for the top). False if its diagonal block is not positive definite.
bool factor_supernode(Factor& F, int s, int part, Scratch& w) {
  const int k1 = F.super[s], k2 = F.super[s + 1], nscol = k2 - k1;
  const int* rows = F.Ls + F.pi[s];
  const int nsrow = F.pi[s + 1] - F.pi[s];
  double* x = F.Lx + F.px[s];
  for (int i = 0; i < nsrow; ++i) w.map[static_cast<std::size_t>(rows[i])] = i;
  std::fill(x, x + static_cast<std::ptrdiff_t>(nsrow) * nscol, 0.0);
  const PermutedLower& C = *F.C;
  for (int k = k1; k < k2; ++k) {
    double* col = x + static_cast<std::ptrdiff_t>(k - k1) * nsrow;
    for (int q = C.p[k]; q < C.p[k + 1]; ++q) col[w.map[static_cast<std::size_t>(C.i[q])]] = C.x[q];
  }
  for (int d = F.head[s]; d >= 0;) {
    const int next_d = F.next[d];
    const int* drows = F.Ls + F.pi[d];
    const int ndrow = F.pi[d + 1] - F.pi[d], ndcol = F.super[d + 1] - F.super[d];
    const int p1 = F.lpos[d];
    int p2 = p1;
    while (p2 < ndrow && drows[p2] < k2) ++p2;
    const int ndrow1 = p2 - p1, ndrow2 = ndrow - p1;
    const double* L1 = F.Lx + F.px[d] + p1;  // rows p1… of d, leading dimension ndrow
    double* c = w.c.data();
    cblas_dsyrk(CblasColMajor, CblasLower, CblasNoTrans, ndrow1, ndcol, 1.0, L1, ndrow, 0.0, c,
                ndrow2);
    if (ndrow2 > ndrow1)
      cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, ndrow2 - ndrow1, ndrow1, ndcol, 1.0,
                  L1 + ndrow1, ndrow, L1, ndrow, 0.0, c + ndrow1, ndrow2);
    for (int i = 0; i < ndrow2; ++i) w.rel[static_cast<std::size_t>(i)] = w.map[drows[p1 + i]];
    for (int j = 0; j < ndrow1; ++j) {
      double* col = x + static_cast<std::ptrdiff_t>(drows[p1 + j] - k1) * nsrow;
      const double* cj = c + static_cast<std::ptrdiff_t>(j) * ndrow2;
      for (int i = j; i < ndrow2; ++i) col[w.rel[static_cast<std::size_t>(i)]] -= cj[i];
    }
    F.lpos[d] = p2;
    link_next(F, d, part);
    d = next_d;
  }
  int info = 0;
  dpotrf_("L", &nscol, x, &nsrow, &info, 1);
  // OpenBLAS's dpotrf takes a NaN pivot (its test is ajj <= 0): look at the diagonal too.
  for (int j = 0; info == 0 && j < nscol; ++j)
    if (!(x[static_cast<std::ptrdiff_t>(j) * nsrow + j] > 0)) info = j + 1;
  if (info != 0) {
    int expected = -1;
    F.failed.compare_exchange_strong(expected, k1 + info - 1);
    return false;
  }
  if (nsrow > nscol)
    cblas_dtrsm(CblasColMajor, CblasRight, CblasLower, CblasTrans, CblasNonUnit, nsrow - nscol,
                nscol, 1.0, x, nsrow, x + nscol, nsrow);
  F.lpos[s] = nscol;
  link_next(F, s, part);
  return true;
}

}  // namespace

int supernodal_factorize(cholmod_factor& L, const cholmod_sparse& A,
                         const SupernodalFactorPlan& plan, int threads) {
  if (!L.is_super || L.itype != CHOLMOD_INT || !L.x || !L.Perm || A.stype == 0 ||
      A.nrow != L.n || A.ncol != L.n || A.itype != CHOLMOD_INT || A.xtype != CHOLMOD_REAL ||
      plan.super_of_.size() != L.n)
    throw std::logic_error("supernodal_factorize: preconditions not met");
  const int n = static_cast<int>(L.n);
  const int nsuper = static_cast<int>(L.nsuper);
  if (n == 0) return -1;
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

  auto make_scratch = [&] {
    Scratch w;
    w.map.resize(static_cast<std::size_t>(n));
    w.rel.resize(plan.max_rows_);
    w.c.resize(plan.max_update_);
    return w;
  };
  if (K == 0) {
    Scratch w = make_scratch();
    for (int s = 0; s < nsuper; ++s)
      if (!factor_supernode(F, s, -1, w)) break;
  } else {
    std::atomic<int> next_part{0};
    auto parts = [&](int, int) {
      Scratch w = make_scratch();
      for (int p; (p = next_part.fetch_add(1)) < K;)
        for (int s : split.parts[static_cast<std::size_t>(p)]) {
          if (F.failed.load(std::memory_order_relaxed) >= 0) return;
          if (!factor_supernode(F, s, p, w)) return;
        }
    };
    auto run2 = [](void* ctx, int tid) { (*static_cast<decltype(parts)*>(ctx))(tid, 2); };
    if (threads < 2 || !Helper::instance().run(run2, &parts)) parts(0, 1);
    if (F.failed.load() < 0) {
      // The parts' updates to the top, linked in part order: the top's descendant lists do
      // not depend on which thread ran which part.
      for (int p = 0; p < K; ++p)
        for (int d : F.pending[static_cast<std::size_t>(p)]) {
          const int t = F.super_of[F.Ls[F.pi[d] + F.lpos[d]]];
          F.next[d] = F.head[t];
          F.head[t] = d;
        }
      Scratch w = make_scratch();
      for (int s : split.top)
        if (!factor_supernode(F, s, -1, w)) break;
    }
  }
  const int failed = F.failed.load();
  L.minor = failed >= 0 ? static_cast<std::size_t>(failed) : L.n;
  return failed;
}

}  // namespace hdeform

#include "engine/solve/supernodal_solve.h"

#include "engine/runtime/two_threads.h"
#include "engine/simd/supernodal_sweep.h"
#include "engine/solve/supernodal_tree.h"

#include <algorithm>
#include <atomic>

namespace hdeform {

bool supernodal_solvable(const cholmod_factor* L) {
  return L && L->is_super && L->is_ll && L->xtype == CHOLMOD_REAL &&
         L->dtype == CHOLMOD_DOUBLE && L->itype == CHOLMOD_INT && L->Perm && L->super &&
         L->pi && L->px && L->s && L->x;
}

void supernodal_solve3(const cholmod_factor& L, const double* B, std::ptrdiff_t ldb, double* X,
                       std::ptrdiff_t ldx, SupernodalWorkspace& ws) {
  const auto n = static_cast<std::ptrdiff_t>(L.n);
  if (n == 0) return;
  ws.reserve(static_cast<std::size_t>(n));
  double* y = ws.data();
  const int* perm = static_cast<const int*>(L.Perm);
  const SweepArgs<double> args{static_cast<const int*>(L.super), static_cast<const int*>(L.pi),
                               static_cast<const int*>(L.px), static_cast<const int*>(L.s),
                               static_cast<const double*>(L.x), y};
  const SweepKernels<double>& kern = sweep_kernels<double>();
  const int nsuper = static_cast<int>(L.nsuper);

  // y = P b, interleaved: y[3k + c] = B(Perm[k], c).
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    const std::ptrdiff_t r = perm[k];
    y[3 * k] = B[r];
    y[3 * k + 1] = B[r + ldb];
    y[3 * k + 2] = B[r + 2 * ldb];
  }
  kern.forward(args, nullptr, nsuper);
  kern.backward(args, nullptr, nsuper);
  // x = Pᵀ y (reads y only: X may alias B).
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    const std::ptrdiff_t r = perm[k];
    X[r] = y[3 * k];
    X[r + ldx] = y[3 * k + 1];
    X[r + 2 * ldx] = y[3 * k + 2];
  }
}

SupernodalSchedule::SupernodalSchedule(const cholmod_factor& L, std::size_t min_rows) {
  const int n = static_cast<int>(L.n);
  const int nsuper = static_cast<int>(L.nsuper);
  if (L.n < min_rows || nsuper < 2) return;
  const int* super = static_cast<const int*>(L.super);
  const int* pi = static_cast<const int*>(L.pi);
  const int* px = static_cast<const int*>(L.px);
  const int* Ls = static_cast<const int*>(L.s);
  // A solve reads every factor entry once per sweep: a supernode's work is its entries.
  std::vector<double> work(static_cast<std::size_t>(nsuper));
  for (int s = 0; s < nsuper; ++s) work[s] = static_cast<double>(px[s + 1] - px[s]);
  TreeSplit split = split_supernodal_tree(L, work, kMaxParts);
  if (!split.split()) return;
  parts_ = std::move(split.parts);
  top_ = std::move(split.top);
  const int K = static_cast<int>(parts_.size());
  std::vector<int> top_index(static_cast<std::size_t>(n), -1);
  for (int s : top_)
    for (int k = super[s]; k < super[s + 1]; ++k) {
      top_index[k] = static_cast<int>(top_cols_.size());
      top_cols_.push_back(k);
    }
  const int ntop = static_cast<int>(top_cols_.size());
  rows_.assign(Ls, Ls + L.ssize);
  for (int p = 0; p < K; ++p)
    for (int s : parts_[p])
      for (int i = pi[s] + (super[s + 1] - super[s]); i < pi[s + 1]; ++i)
        if (top_index[Ls[i]] >= 0) rows_[i] = n + p * ntop + top_index[Ls[i]];
  work_ = std::move(split.work);
  critical_ = split.critical;
}

std::size_t SupernodalSchedule::memory_bytes() const {
  std::size_t ints = top_.capacity() + rows_.capacity() + top_cols_.capacity();
  for (const auto& p : parts_) ints += p.capacity();
  return ints * sizeof(int) + work_.capacity() * sizeof(double);
}

namespace {

template <class T>
struct Sweep {
  SweepArgs<T> args;
  const SweepKernels<T>& kern;
  void forward_list(const std::vector<int>& list) const {
    kern.forward(args, list.data(), static_cast<int>(list.size()));
  }
  void backward_list(const std::vector<int>& list) const {
    kern.backward(args, list.data(), static_cast<int>(list.size()));
  }
  void forward_all(int nsuper) const { kern.forward(args, nullptr, nsuper); }
  void backward_all(int nsuper) const { kern.backward(args, nullptr, nsuper); }
};

}  // namespace

template <class T>
void supernodal_solve3(const cholmod_factor& L, const T* Lx, const SupernodalSchedule& sched,
                       const double* B, Stride3 sb, double* X, Stride3 sx,
                       SupernodalWorkspace& ws, int threads) {
  const auto n = static_cast<std::ptrdiff_t>(L.n);
  if (n == 0) return;
  const bool split = sched.split();
  const int K = sched.parts();
  const std::ptrdiff_t ntop = split ? sched.top_rows() : 0;
  ws.reserve(static_cast<std::size_t>(n + K * ntop));
  double* y = ws.data();
  const int* perm = static_cast<const int*>(L.Perm);
  const int nsuper = static_cast<int>(L.nsuper);
  const Sweep<T> sw{{static_cast<const int*>(L.super), static_cast<const int*>(L.pi),
                     static_cast<const int*>(L.px),
                     split ? sched.rows_.data() : static_cast<const int*>(L.s), Lx, y},
                    sweep_kernels<T>()};
  const int* top_cols = sched.top_cols_.data();
  // Work is claimed, not assigned: blocks of rows and parts go to whichever thread asks (the
  // caller from the front, the helper from the back), and each phase ends when its items are
  // done (Claims), so the helper may join late or never (Helper::offer) and the caller never
  // waits for it to wake.
  constexpr std::ptrdiff_t kBlock = 8192;
  const int nblocks = static_cast<int>((n + kBlock - 1) / kBlock);

  // y = P b, interleaved: y[3k + c] = B(Perm[k], c), for rows [k0, k1).
  auto permute_in = [&](std::ptrdiff_t k0, std::ptrdiff_t k1) {
    for (std::ptrdiff_t k = k0; k < k1; ++k) {
      const double* b = B + perm[k] * sb.row;
      y[3 * k] = b[0];
      y[3 * k + 1] = b[sb.col];
      y[3 * k + 2] = b[2 * sb.col];
    }
  };
  // x = Pᵀ y (reads y only: X may alias B), for rows [k0, k1).
  auto permute_out = [&](std::ptrdiff_t k0, std::ptrdiff_t k1) {
    for (std::ptrdiff_t k = k0; k < k1; ++k) {
      double* x = X + perm[k] * sx.row;
      x[0] = y[3 * k];
      x[sx.col] = y[3 * k + 1];
      x[2 * sx.col] = y[3 * k + 2];
    }
  };
  if (!split) {
    permute_in(0, n);
    sw.forward_all(nsuper);
    sw.backward_all(nsuper);
    permute_out(0, n);
    return;
  }
  // The permutations in blocks of kBlock rows, so that both threads can claim them.
  auto in_block = [&](int blk) { permute_in(blk * kBlock, std::min(n, (blk + 1) * kBlock)); };
  auto out_block = [&](int blk) { permute_out(blk * kBlock, std::min(n, (blk + 1) * kBlock)); };
  // Each thread (the caller, and the helper if it joins) runs this; every item's arithmetic
  // is the same whichever thread runs it, and only the caller touches the top.
  Claims in(nblocks), fwd(K), bwd(K), out(nblocks);
  std::atomic<int> top_done{0};
  auto body = [&](int tid) {
    in.run(tid, in_block);  // B is read (X may alias it) and y is complete
    fwd.run(tid, [&](int p) {
      double* buf = y + 3 * (n + p * ntop);
      std::fill(buf, buf + 3 * ntop, 0.0);
      sw.forward_list(sched.parts_[p]);
    });
    if (tid == 0) {
      for (int p = 0; p < K; ++p) {  // fixed order: the bits do not depend on the team
        const double* buf = y + 3 * (n + p * ntop);
        for (std::ptrdiff_t k = 0; k < ntop; ++k) {
          double* yr = y + 3 * static_cast<std::ptrdiff_t>(top_cols[k]);
          yr[0] += buf[3 * k];
          yr[1] += buf[3 * k + 1];
          yr[2] += buf[3 * k + 2];
        }
      }
      sw.forward_list(sched.top_);
      sw.backward_list(sched.top_);
      top_done.store(1, std::memory_order_release);
      top_done.notify_one();
    } else {
      await_value(top_done, 1);
    }
    bwd.run(tid, [&](int p) {
      double* buf = y + 3 * (n + p * ntop);  // the part reads the top's x from here
      for (std::ptrdiff_t k = 0; k < ntop; ++k) {
        const double* yr = y + 3 * static_cast<std::ptrdiff_t>(top_cols[k]);
        buf[3 * k] = yr[0];
        buf[3 * k + 1] = yr[1];
        buf[3 * k + 2] = yr[2];
      }
      sw.backward_list(sched.parts_[p]);
    });
    out.run(tid, out_block);
  };
  auto run2 = [](void* ctx, int tid) { (*static_cast<decltype(body)*>(ctx))(tid); };
  if (threads < 2)
    body(0);
  else
    Helper::instance().offer(run2, &body);
}

template void supernodal_solve3<double>(const cholmod_factor&, const double*,
                                        const SupernodalSchedule&, const double*, Stride3,
                                        double*, Stride3, SupernodalWorkspace&, int);
template void supernodal_solve3<float>(const cholmod_factor&, const float*,
                                       const SupernodalSchedule&, const double*, Stride3,
                                       double*, Stride3, SupernodalWorkspace&, int);

std::vector<float> factor_values_float(const cholmod_factor& L) {
  const double* x = static_cast<const double*>(L.x);
  return std::vector<float>(x, x + L.xsize);
}

}  // namespace hdeform

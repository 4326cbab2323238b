// The K_FF solve benchmarks of engine_bench (docs/benchmarks.md): Bandwidth/read and
// Solve/N/beta:b/{cholmod, fused_1t, fused_2t, fused_f32_1t, fused_f32_2t, fused_generic_*}, registered
// by engine_bench's main through register_solve_benchmarks(). Own fixtures (capsule,
// K_FF and its SupernodalFactorization per β), kept for the whole run so that interleaved
// repetitions do not rebuild them.
#include "engine/deform/deformer.h"
#include "engine/runtime/serial_openmp.h"
#include "engine/simd/cpu_features.h"
#include "engine/solve/supernodal_factorization.h"
#include "engine/solve/supernodal_solve.h"
#include "fixtures/procedural.h"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

namespace hdeform::bench {

void register_solve_benchmarks(bool smoke);

namespace {

constexpr int kSolveSizes[] = {10000, 100000};
constexpr double kSolveBetas[] = {0.0, 0.5};  // area units, as engine_bench
constexpr double kFraction = 0.05;            // fixed base / cap handle, as engine_bench

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct SolveCase {
  std::shared_ptr<const PreparedMesh> pm;
  std::vector<int> block_index;  // free vertex → row of K_FF, −1 if constrained
  int n = 0;
  std::map<double, std::unique_ptr<SupernodalFactorization>> factors;
  std::map<double, SparseMatrix> K_FF;
};

std::map<int, SolveCase>& cases() {
  static std::map<int, SolveCase> c;
  return c;
}

SolveCase& solve_case(int nominal) {
  SolveCase& c = cases()[nominal];
  if (c.pm) return c;
  procedural::CapsuleCase cc = procedural::capsule_case(nominal, kFraction);
  c.n = cc.mesh.num_vertices();
  c.block_index.assign(static_cast<std::size_t>(c.n), 0);
  for (int v : cc.base) c.block_index[v] = -1;
  for (int v : cc.cap) c.block_index[v] = -1;
  int nF = 0;
  for (int& b : c.block_index)
    if (b == 0) b = nF++;
  c.pm = PreparedMesh::create(std::move(cc.mesh));
  return c;
}

// K_FF as the engine builds it: the Laplacian's own pattern at β = 0, the union of both
// parts' patterns (explicit zeros kept) at β > 0.
const SparseMatrix& k_ff(SolveCase& c, double beta) {
  if (auto it = c.K_FF.find(beta); it != c.K_FF.end()) return it->second;
  const PreparedMesh& pm = *c.pm;
  const double b = pm.raw_beta(Beta{beta});
  const SparseMatrix K = b == 0.0 ? SparseMatrix(pm.L()) : SparseMatrix((1 - b) * pm.L() + b * pm.Reg());
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(K.nonZeros()));
  int nF = 0;
  for (int v : c.block_index) nF += v >= 0;
  for (Eigen::Index col = 0; col < K.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(K, col); it; ++it) {
      const int r = c.block_index[it.row()], k = c.block_index[col];
      if (r >= 0 && k >= 0) t.emplace_back(r, k, it.value());
    }
  SparseMatrix K_FF(nF, nF);
  K_FF.setFromTriplets(t.begin(), t.end());
  return c.K_FF[beta] = std::move(K_FF);
}

const SupernodalFactorization& factor(SolveCase& c, double beta) {
  auto& f = c.factors[beta];
  if (!f) f = std::make_unique<SupernodalFactorization>(k_ff(c, beta));
  return *f;
}

// Factorize/N/beta:b/{cholmod, ours_1t, ours_2t}: one numeric factorization of K_FF from a
// copy of one symbolic analysis (METIS on K_FF; the copy untimed): cholmod_factorize, or
// supernodal_factorize on one or two threads. Counters: GFlop/s (the plan's count), the
// split's parts and its estimated two-thread critical path (share of the flops).
// FactorizeCutoff/N/beta:b/small:V: ours_2t with SupernodalFactorPlan::set_small_update(V).
void BM_Factorize(benchmark::State& state, int nominal, double beta, int threads,
                  double small_update) {
  SolveCase& c = solve_case(nominal);
  const SparseMatrix& K = k_ff(c, beta);
  CholmodLLT sym;
  sym.analyzePattern(K);
  SupernodalFactorPlan plan(*sym.factor());
  if (small_update >= 0) plan.set_small_update(small_update);
  double sec = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto work = std::make_unique<CholmodLLT>();
    work->adopt_analysis(sym);
    state.ResumeTiming();
    const auto t0 = std::chrono::steady_clock::now();
    if (threads == 0) {
      SerialOpenMP serial;  // as the engine ran it (serial_openmp.h)
      work->factorize(K);
    } else {
      work->factorize_supernodal(K, plan, threads);
    }
    sec += seconds_since(t0);
    if (work->info() != Eigen::Success) state.SkipWithError("factorization failed");
    state.PauseTiming();  // the factor's release is not the factorization
    work.reset();
    state.ResumeTiming();
  }
  state.counters["nF"] = static_cast<double>(K.rows());
  state.counters["GFlops"] = plan.flops() * static_cast<double>(state.iterations()) / sec / 1e9;
  state.counters["flop_G"] = plan.flops() / 1e9;
  if (plan.split().split()) {
    state.counters["parts"] = static_cast<double>(plan.split().parts.size());
    state.counters["crit_path"] = plan.split().critical / plan.flops();
  }
}

// Memory-bandwidth probe: one thread streaming a buffer far bigger than any cache (256 MiB),
// summing it with four independent accumulators so the adds never limit the read. The
// solve's floor is reading the factor's values twice (forward and backward sweep):
// floor = 2 × factor value bytes / bandwidth. Built and first-touched untimed.
constexpr std::size_t kProbeDoubles = std::size_t{32} << 20;  // 256 MiB

const std::vector<double>& probe_buffer() {
  static const std::vector<double> buf = [] {
    std::vector<double> v(kProbeDoubles);
    std::iota(v.begin(), v.end(), 0.0);
    return v;
  }();
  return buf;
}

double stream_read(const std::vector<double>& v) {
  double a0 = 0, a1 = 0, a2 = 0, a3 = 0;
  for (std::size_t i = 0; i + 4 <= v.size(); i += 4) {
    a0 += v[i];
    a1 += v[i + 1];
    a2 += v[i + 2];
    a3 += v[i + 3];
  }
  return (a0 + a1) + (a2 + a3);
}

// Bytes per second of stream_read: the best of a few passes (once per process, untimed),
// for the Solve benchmarks' "× floor" counter.
double bandwidth_Bps() {
  static const double bw = [] {
    const auto& v = probe_buffer();
    double best = 0;
    for (int pass = 0; pass < 5; ++pass) {
      const auto t0 = std::chrono::steady_clock::now();
      benchmark::DoNotOptimize(stream_read(v));
      const double sec = seconds_since(t0);
      best = std::max(best, static_cast<double>(v.size() * sizeof(double)) / sec);
    }
    return best;
  }();
  return bw;
}

// The probe as its own benchmark (bytes_per_second), interleaved with the solves.
void BM_Bandwidth(benchmark::State& state) {
  const auto& v = probe_buffer();
  for (auto _ : state) benchmark::DoNotOptimize(stream_read(v));
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(v.size() * sizeof(double)));
}

enum class Variant { cholmod, fused };

// The kernels' build chosen for this CPU (cpu_features.h), restored after each
// Solve benchmark that set another.
const Isa best_isa = kernel_isa();

// Solve/N/beta:b/...: K_FF X = B, three random right-hand sides, on the same factor.
// cholmod = SupernodalFactorization::solve_cholmod (cholmod_solve, result copied to an Eigen matrix);
// fused_* = SupernodalFactorization::solve3 into a preallocated X (thread_local workspace, warmed
// untimed, as is the float copy). Counters: factor value MB as read, the single-thread
// read floor (ms) and x_floor = time per solve / floor.
void BM_Solve(benchmark::State& state, int nominal, double beta, Variant variant,
              SolvePrecision precision, int threads, Isa isa) {
  if (!set_kernel_isa(isa)) {
    state.SkipWithError("this CPU lacks the sweep kernels' instruction set");
    return;
  }
  SolveCase& c = solve_case(nominal);
  const SupernodalFactorization& f = factor(c, beta);
  std::srand(7);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(f.size(), 3);
  Eigen::MatrixXd X(B.rows(), 3);
  const cholmod_factor* L = f.factor();
  if (variant == Variant::fused) f.solve3(B.data(), X.data(), precision, threads);  // warm-up
  const double bw = bandwidth_Bps();
  const auto t0 = std::chrono::steady_clock::now();
  for (auto _ : state) {
    if (variant == Variant::fused) {
      f.solve3(B.data(), X.data(), precision, threads);
      benchmark::DoNotOptimize(X.data());
    } else {
      Eigen::MatrixXd Xc = f.solve_cholmod(B);
      benchmark::DoNotOptimize(Xc.data());
    }
  }
  const double per_solve = seconds_since(t0) / static_cast<double>(state.iterations());
  const double value_bytes = static_cast<double>(L->xsize) *
                             (precision == SolvePrecision::float32 ? sizeof(float) : sizeof(double));
  const double floor_s = 2 * value_bytes / bw;
  state.counters["n"] = c.n;
  state.counters["nF"] = f.size();
  state.counters["factor_values_MB"] = value_bytes / (1024.0 * 1024.0);
  state.counters["bandwidth_GBps"] = bw / 1e9;
  state.counters["floor_ms"] = floor_s * 1e3;
  state.counters["x_floor"] = per_solve / floor_s;
  const SupernodalSchedule& s = f.schedule();
  if (s.split()) {  // the split: shares of the factor entries
    double total = 0;
    for (int i = 0; i <= s.parts(); ++i) total += s.work(i);
    state.counters["parts"] = s.parts();
    state.counters["top"] = s.work(s.parts()) / total;
    state.counters["crit_path"] = s.critical_path() / total;
  }
  set_kernel_isa(best_isa);
}

benchmark::internal::Benchmark* policy(benchmark::internal::Benchmark* b, bool smoke) {
  b->Unit(benchmark::kMillisecond)->UseRealTime();
  if (smoke) return b->Iterations(1)->Repetitions(1);
  return b->Repetitions(5)->ReportAggregatesOnly(true);
}

}  // namespace

void register_solve_benchmarks(bool smoke) {
  policy(benchmark::RegisterBenchmark("Bandwidth/read", BM_Bandwidth), smoke);
  struct V {
    const char* name;
    Variant variant;
    SolvePrecision precision;
    int threads;
    Isa isa = best_isa;
  };
  const V variants[] = {
      {"cholmod", Variant::cholmod, SolvePrecision::float64, 1},
      {"fused_1t", Variant::fused, SolvePrecision::float64, 1},
      {"fused_2t", Variant::fused, SolvePrecision::float64, 2},
      {"fused_f32_1t", Variant::fused, SolvePrecision::float32, 1},
      {"fused_f32_2t", Variant::fused, SolvePrecision::float32, 2},
      // the baseline build of the sweep kernels, side by side with the AVX2 one
      {"fused_generic_1t", Variant::fused, SolvePrecision::float64, 1, Isa::generic},
      {"fused_generic_2t", Variant::fused, SolvePrecision::float64, 2, Isa::generic},
      {"fused_f32_generic_2t", Variant::fused, SolvePrecision::float32, 2, Isa::generic},
  };
  for (int n : kSolveSizes)
    for (double beta : kSolveBetas)
      for (int threads : {0, 1, 2}) {
        const std::string name = "Factorize/" + std::to_string(n) + "/beta:" +
                                 (beta == 0 ? std::string("0") : std::string("0.5")) + "/" +
                                 (threads == 0 ? "cholmod" : threads == 1 ? "ours_1t" : "ours_2t");
        policy(benchmark::RegisterBenchmark(name.c_str(), BM_Factorize, n, beta, threads, -1.0),
               smoke);
      }
  for (double beta : kSolveBetas)
    for (double v : {0.0, 4096.0, 16384.0, 65536.0, 262144.0, 1048576.0}) {
      const std::string name = std::string("FactorizeCutoff/100000/beta:") +
                               (beta == 0 ? "0" : "0.5") + "/small:" + std::to_string(static_cast<long>(v));
      policy(benchmark::RegisterBenchmark(name.c_str(), BM_Factorize, 100000, beta, 2, v), smoke);
    }
  for (int n : kSolveSizes)
    for (double beta : kSolveBetas)
      for (const V& v : variants) {
        const std::string name = "Solve/" + std::to_string(n) + "/beta:" +
                                 (beta == 0 ? std::string("0") : std::string("0.5")) + "/" + v.name;
        policy(benchmark::RegisterBenchmark(name.c_str(), BM_Solve, n, beta, v.variant,
                                            v.precision, v.threads, v.isa),
               smoke);
      }
}

}  // namespace hdeform::bench

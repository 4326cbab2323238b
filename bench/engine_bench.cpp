// hdeform engine benchmarks (Google Benchmark). How to run and the measured numbers:
// docs/benchmarks.md.
//
// Names: FAMILY/N/... with N the nominal vertex count of the procedural capsule (10000,
// 100000, 1000000), e.g. `--benchmark_filter=Update/100000/`, or BS/MODEL/... for the
// Botsch–Sorkine models. Benchmarks are registered size-major so that one size's fixtures
// (mesh, PreparedMesh, warm ConstraintSet, K_FF matrices, factors) are built once and
// freed before the next size is built.
//
// Extra flag (ours): --hdeform_smoke  one repetition everywhere (ctest bench-smoke).
#include "bench_common.h"
#include "engine/deform/deformer.h"
#include "engine/deform/keyframes.h"
#include "engine/deform/measures.h"
#include "engine/deform/skin_weights.h"
#include "engine/io/animation_glb.h"
#include "engine/io/mesh_io.h"
#include "engine/io/rig_glb.h"
#include "engine/io/selection.h"
#include "engine/operators/sparse_times3.h"
#include "engine/runtime/process_environment.h"
#include "engine/runtime/warm_cores.h"
#include "engine/simd/cpu_features.h"
#include "engine/solve/supernodal_factorization.h"
#include "engine/solve/supernodal_solve.h"
#include "engine/solve/vertex_ordering.h"
#include "fixtures/procedural.h"

#include <benchmark/benchmark.h>

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <numeric>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace hdeform::bench {
void register_solve_benchmarks(bool smoke);  // solve_bench.cpp
}

namespace {

using namespace hdeform;

constexpr int kSizes[] = {10000, 100000, 1000000};
constexpr double kBetas[] = {0.0, 0.5};  // area units (the engine's default)
constexpr double kFraction = 0.05;       // fixed base / cap handle: 5 % of the height each
bool g_smoke = false;

// ---------------------------------------------------------------------------------------
// Memory: /proc/self/status (kB → MB; -1 when absent), peak reset by bench::reset_peak.
double status_mb(const char* key) {
  const double kb = bench::status_kb(key);
  return kb < 0 ? -1 : kb / 1024.0;
}
using bench::reset_peak;
double mb(std::size_t bytes) { return static_cast<double>(bytes) / (1024.0 * 1024.0); }

// ---------------------------------------------------------------------------------------
// K_FF, K_FC and (Gᵀ W_β)_F built here from PreparedMesh::L()/Reg()/GtA()/GtDBD(), the
// same way the engine builds them, for the solver comparison and the phase breakdown.
struct System {
  double raw_beta = 0;
  SparseMatrix K_FF, K_FC;  // K_FF stored full (both triangles), as the engine does
  SparseMatrixR GtW_F;      // row-major, like the engine
  std::shared_ptr<const SupernodalFactorization> cholmod;  // analysed + factored (METIS, supernodal)
  using Simplicial = Eigen::SimplicialLLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>>;
  std::unique_ptr<Simplicial> simplicial;  // analysed + factored (AMD)
};

struct Case {
  std::string name;
  TriMesh mesh;
  Constraints constraints;
  std::shared_ptr<const PreparedMesh> pm;
  std::shared_ptr<ConstraintSet> cs;  // warm: β = 0 and β = 0.5 factored
  std::vector<int> region_of, block_index, free_, constrained;
  std::map<double, System> systems;
  std::optional<Eigen::Matrix4d> def;  // Botsch–Sorkine .def, if any
  // Memory while building: MB.
  double rss_before = 0, hwm_open = 0, hwm_beta = 0, rss_after = 0;
  std::size_t pm_bytes = 0, cs_bytes_open = 0, cs_bytes_beta = 0;
  double open_seconds = 0, beta_seconds = 0;
  // The wide order alone, as the service's background order computes it (Reg + METIS on
  // L ∪ Reg): its peak above the RSS before it (MB; BackgroundOrders::working_bytes), its time.
  double wide_order_mb = 0, wide_order_seconds = 0;
  PreparedMesh::BuildTimings open_pm;  // phases of the fixture's session open
  ConstraintSet::OpenTimings open_cs;
};

std::unique_ptr<Case> g_case;  // one at a time

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void finish_case(Case& c) {
  const int n = c.mesh.num_vertices();
  c.region_of.assign(n, -1);
  for (int v : c.constraints.fixed) c.region_of[v] = 0;
  for (std::size_t j = 0; j < c.constraints.handles.size(); ++j)
    for (int v : c.constraints.handles[j]) c.region_of[v] = static_cast<int>(j) + 1;
  c.block_index.assign(n, -1);
  for (int v = 0; v < n; ++v) {
    auto& block = c.region_of[v] < 0 ? c.free_ : c.constrained;
    c.block_index[v] = static_cast<int>(block.size());
    block.push_back(v);
  }
  // Build the session, measuring memory: peak during open (operators + analysis + β = 0
  // factorization + harmonic basis), then during the first β > 0 (wide blocks + METIS on
  // the wide pattern + numeric factorization).
  c.rss_before = status_mb("VmRSS");
  reset_peak();
  auto t0 = std::chrono::steady_clock::now();
  c.pm = PreparedMesh::create(c.mesh);
  c.cs = std::make_shared<ConstraintSet>(c.pm, c.constraints);
  c.open_seconds = seconds_since(t0);
  c.open_pm = c.pm->build_timings();
  c.open_cs = c.cs->open_timings();
  c.hwm_open = status_mb("VmHWM");
  c.pm_bytes = c.pm->memory_bytes();
  c.cs_bytes_open = c.cs->memory_bytes();
  {  // not adopted: the first β > 0 below still pays its own METIS
    const double rss = status_mb("VmRSS");
    reset_peak();
    t0 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(nested_dissection(c.pm->L(), c.pm->Reg()).data());
    c.wide_order_seconds = seconds_since(t0);
    c.wide_order_mb = status_mb("VmHWM") - rss;
  }
  reset_peak();
  t0 = std::chrono::steady_clock::now();
  c.cs->prepare(Beta{0.5});
  c.beta_seconds = seconds_since(t0);
  c.hwm_beta = status_mb("VmHWM");
  c.cs_bytes_beta = c.cs->memory_bytes();
  c.rss_after = status_mb("VmRSS");
}

std::string case_name(int nominal) { return "capsule" + std::to_string(nominal); }

Case& capsule(int nominal) {
  const std::string name = case_name(nominal);
  if (g_case && g_case->name == name) return *g_case;
  g_case.reset();  // free the previous size first
  auto c = std::make_unique<Case>();
  c->name = name;
  procedural::CapsuleCase cc = procedural::capsule_case(nominal, kFraction);
  c->mesh = std::move(cc.mesh);
  c->constraints.fixed = std::move(cc.base);
  c->constraints.handles = {std::move(cc.cap)};
  finish_case(*c);
  g_case = std::move(c);
  return *g_case;
}

std::string slurp(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot read " + path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

Case& botsch_sorkine(const std::string& model) {
  const std::string name = "bs-" + model;
  if (g_case && g_case->name == name) return *g_case;
  g_case.reset();
  auto c = std::make_unique<Case>();
  c->name = name;
  const std::string base = std::string(HDEFORM_BENCH_DATA) + "/botsch-sorkine/" + model;
  c->mesh = read_mesh(base + ".off").mesh;
  const auto labels = parse_sel(slurp(base + ".sel"), c->mesh.num_vertices(), model + ".sel");
  c->constraints.fixed = select_label(labels, 0);
  c->constraints.handles = {select_label(labels, 2)};
  c->def = parse_def(slurp(base + ".def"), model + ".def");
  finish_case(*c);
  g_case = std::move(c);
  return *g_case;
}

// The (free, ·) blocks of K and GtW (same as the engine's split()).
void split(const Case& c, const SparseMatrix& K, const SparseMatrix& GtW, System& s) {
  const auto nF = static_cast<Eigen::Index>(c.free_.size());
  const auto nC = static_cast<Eigen::Index>(c.constrained.size());
  std::vector<Eigen::Triplet<double>> ff, fc, gw;
  ff.reserve(K.nonZeros());
  for (Eigen::Index col = 0; col < K.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(K, col); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (c.region_of[r] >= 0) continue;
      if (c.region_of[col] < 0)
        ff.emplace_back(c.block_index[r], c.block_index[col], it.value());
      else
        fc.emplace_back(c.block_index[r], c.block_index[col], it.value());
    }
  gw.reserve(GtW.nonZeros());
  for (Eigen::Index col = 0; col < GtW.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(GtW, col); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (c.region_of[r] < 0) gw.emplace_back(c.block_index[r], static_cast<int>(col), it.value());
    }
  s.K_FF.resize(nF, nF);
  s.K_FF.setFromTriplets(ff.begin(), ff.end());
  s.K_FC.resize(nF, nC);
  s.K_FC.setFromTriplets(fc.begin(), fc.end());
  s.GtW_F.resize(nF, GtW.cols());
  s.GtW_F.setFromTriplets(gw.begin(), gw.end());
}

// K_FF etc. for β (area units); factorizations are built on demand.
System& system(Case& c, double beta) {
  auto it = c.systems.find(beta);
  if (it != c.systems.end()) return it->second;
  System& s = c.systems[beta];
  const PreparedMesh& pm = *c.pm;
  s.raw_beta = pm.raw_beta(Beta{beta});
  if (s.raw_beta == 0.0) {
    split(c, pm.L(), pm.GtA(), s);  // the Laplacian's own narrow pattern
  } else {
    const double b = s.raw_beta;
    // Wide pattern: union of both parts' patterns (explicit zeros kept), like the engine.
    const SparseMatrix K = (1 - b) * pm.L() + b * pm.Reg();
    const SparseMatrix GtW = (1 - b) * pm.GtA() + b * pm.GtDBD();
    split(c, K, GtW, s);
  }
  return s;
}
const SupernodalFactorization& cholmod(System& s) {
  if (!s.cholmod) s.cholmod = std::make_shared<SupernodalFactorization>(s.K_FF);
  return *s.cholmod;
}
System::Simplicial& simplicial(System& s) {
  if (!s.simplicial) {
    s.simplicial = std::make_unique<System::Simplicial>();
    s.simplicial->compute(s.K_FF);
    if (s.simplicial->info() != Eigen::Success) throw std::runtime_error("SimplicialLLT failed");
  }
  return *s.simplicial;
}

// A handle move that differs slightly every iteration: pull the cap sideways and tilt it.
HandleTransform move(const Case& c, int i) {
  const double wiggle = 1e-3 * (i % 97);
  if (c.def) {
    HandleTransform t = HandleTransform::from_matrix(*c.def, c.cs->centroid(0));
    t.translation += Eigen::Vector3d(wiggle, 0, 0);
    return t;
  }
  HandleTransform t;
  t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 + wiggle, Eigen::Vector3d::UnitX()));
  t.translation = Eigen::Vector3d(1.5 + wiggle, 0.0, -0.5);
  return t;
}

Eigen::MatrixXd random_rhs(Eigen::Index rows) {
  std::srand(7);
  return Eigen::MatrixXd::Random(rows, 3);
}

void size_counters(benchmark::State& state, const Case& c) {
  state.counters["n"] = c.mesh.num_vertices();
  state.counters["nF"] = static_cast<double>(c.free_.size());
}

// A copy of x made with the timer paused (the input a timed step consumes).
template <class T>
T copy_untimed(benchmark::State& state, const T& x) {
  state.PauseTiming();
  T copy = x;
  state.ResumeTiming();
  return copy;
}

// What the timed region built (smart pointers), kept alive up to here and then freed, in
// order, with the timer paused.
template <class... Ptr>
void free_untimed(benchmark::State& state, Ptr&&... p) {
  (benchmark::DoNotOptimize(p.get()), ...);
  state.PauseTiming();
  (p.reset(), ...);
  state.ResumeTiming();
}

// ---------------------------------------------------------------------------------------
// Benchmarks. `get` returns the case (built on first use, outside any timed region).
Case& get(const std::string& key) {
  if (key.rfind("bs-", 0) == 0) return botsch_sorkine(key.substr(3));
  return capsule(std::stoi(key.substr(7)));
}

// Medians of named phase times (ms) as counters `<name>_ms`.
struct PhaseMedians {
  std::map<std::string, std::vector<double>> ms;
  void add(const std::string& name, double value) { ms[name].push_back(value); }
  void add(const PreparedMesh::BuildTimings& t) {
    add("validate", t.validate_ms);
    add("geometry", t.geometry_ms);
    add("edges", t.edges_ms);
    add("laplacian", t.laplacian_ms);
    add("regularizer", t.regularizer_ms);
    add("components", t.components_ms);
    add("mesh_order", t.order_ms);  // PrepareOrder::with_operators: METIS beside the above
    add("operators_and_order", t.beside_ms);
  }
  void add(const ConstraintSet::OpenTimings& t) {
    add("checks", t.checks_ms);
    add("split", t.system.blocks_ms);
    add("GtA_beside", t.system.rest_ms);  // (GᵀA)_F, beside the order and factorization
    add("ordering", t.system.ordering_ms);
    add("restrict", t.system.restrict_ms);
    add("analysis", t.system.analysis_ms);
    add("factor", t.system.factor_ms);
    add("schedule", t.system.schedule_ms);
    add("basis", t.basis_ms);
  }
  void report(benchmark::State& state) const {
    for (auto [name, v] : ms) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      state.counters[name + "_ms"] = v.empty() ? 0.0 : v[v.size() / 2];
    }
  }
};

// PreparedMesh::create without the order: validation, G, A, L, interior edges.
void BM_Operators(benchmark::State& state, std::string key) {
  Case& c = get(key);
  PhaseMedians phases;
  for (auto _ : state) {
    auto pm = PreparedMesh::create(copy_untimed(state, c.mesh), PrepareOrder::on_first_use);
    phases.add(pm->build_timings());
    free_untimed(state, pm);
  }
  size_counters(state, c);
  phases.report(state);
  state.counters["nnz_L"] = static_cast<double>(c.pm->L().nonZeros());
  state.counters["nnz_Reg"] = static_cast<double>(c.pm->Reg().nonZeros());
  state.counters["prepared_MB"] = mb(c.pm_bytes);
}

// ConstraintSet construction: METIS analysis + β = 0 factorization of L_FF + harmonic basis.
void BM_ConstraintSet(benchmark::State& state, std::string key) {
  Case& c = get(key);
  PhaseMedians phases;
  for (auto _ : state) {
    auto cs = std::make_shared<ConstraintSet>(c.pm, c.constraints);
    phases.add(cs->open_timings());
    free_untimed(state, cs);
  }
  size_counters(state, c);
  phases.report(state);
  state.counters["cs_MB"] = mb(c.cs_bytes_open);
}

// Session open = operators (β = 0's order beside them) + ConstraintSet (target at 100K:
// ≤ 0.5 s), with the phases of both as counters (PreparedMesh::build_timings,
// ConstraintSet::open_timings: its ordering_ms is 0, the mesh has the order).
void BM_SessionOpen(benchmark::State& state, std::string key) {
  Case& c = get(key);
  PhaseMedians phases;
  for (auto _ : state) {
    auto pm = PreparedMesh::create(copy_untimed(state, c.mesh));
    auto cs = std::make_shared<ConstraintSet>(pm, c.constraints);
    phases.add(pm->build_timings());
    phases.add(cs->open_timings());
    free_untimed(state, cs, pm);
  }
  size_counters(state, c);
  phases.report(state);
}

// Medians of a β build's phases (ConstraintSet::last_build_timings) as counters.
struct BuildPhases {
  std::vector<double> blocks, K_FF, ordering, restrict, analysis, factor, schedule, rest;
  void add(const ConstraintSet::BuildTimings& t) {
    blocks.push_back(t.blocks_ms);
    K_FF.push_back(t.K_FF_ms);
    ordering.push_back(t.ordering_ms);
    restrict.push_back(t.restrict_ms);
    analysis.push_back(t.analysis_ms);
    factor.push_back(t.factor_ms);
    schedule.push_back(t.schedule_ms);
    rest.push_back(t.rest_ms);
  }
  void report(benchmark::State& state) {
    auto median = [](std::vector<double> v) {
      if (v.empty()) return 0.0;
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    state.counters["blocks_ms"] = median(blocks);
    state.counters["K_FF_ms"] = median(K_FF);
    state.counters["ordering_ms"] = median(ordering);
    state.counters["restrict_ms"] = median(restrict);
    state.counters["analysis_ms"] = median(analysis);
    state.counters["factor_ms"] = median(factor);
    state.counters["schedule_ms"] = median(schedule);
    state.counters["K_FC_GtW_ms"] = median(rest);
  }
};

// First β > 0 on a constraint set: wide blocks + METIS on the wide pattern + factorization.
void BM_BetaFirst(benchmark::State& state, std::string key) {
  Case& c = get(key);
  BuildPhases phases;
  for (auto _ : state) {
    state.PauseTiming();
    auto cs = std::make_shared<ConstraintSet>(c.pm, c.constraints);
    state.ResumeTiming();
    cs->prepare(Beta{0.5});
    phases.add(cs->last_build_timings());
    free_untimed(state, cs);
  }
  size_counters(state, c);
  phases.report(state);
  // Reg is not kept by the mesh: every first β > 0 assembles it again (part of blocks_ms).
  state.counters["regularizer_ms"] = c.pm->build_timings().regularizer_ms;
}

// First β > 0 on a mesh seen for the first time (no wide order yet: the service's first β
// change after an open): Reg + wide blocks + METIS on the wide pattern + factorization. The
// mesh and its β = 0 set are built untimed.
void BM_BetaFirstNewMesh(benchmark::State& state, std::string key) {
  Case& c = get(key);
  BuildPhases phases;
  for (auto _ : state) {
    state.PauseTiming();
    auto pm = PreparedMesh::create(c.mesh);
    auto cs = std::make_shared<ConstraintSet>(pm, c.constraints);
    state.ResumeTiming();
    cs->prepare(Beta{0.5});
    phases.add(cs->last_build_timings());
    free_untimed(state, cs, pm);
  }
  size_counters(state, c);
  phases.report(state);
}

// β change on a warm set: numeric factorization reusing the shared wide analysis (plus the
// two value combinations for K_FC and (GᵀW_β)_F). A new β every iteration; dropped after.
void BM_BetaRefactor(benchmark::State& state, std::string key) {
  Case& c = get(key);
  static int counter = 0;
  BuildPhases phases;
  for (auto _ : state) {
    const Beta beta{0.3 + 1e-4 * (++counter % 1000)};
    c.cs->prepare(beta);
    state.PauseTiming();
    phases.add(c.cs->last_build_timings());
    c.cs->drop_factorization(beta);
    state.ResumeTiming();
  }
  size_counters(state, c);
  phases.report(state);
  state.counters["cached"] = static_cast<double>(c.cs->num_cached_factorizations());
}

// Handle move with the factorization cached, as the service does it (one UpdateWorkspace and
// one Frame reused across moves):
//   full   exact solve + measures + energies + normals
//   exact  exact solve + measures + normals (the whole exact frame; target ≤ 10 ms at 100K)
//   drag   drag path (float32 factor + refinement) + normals, no measures (the "drag frame")
//   light  exact solve + measures only
//   alloc  `full` through the allocating update() (fresh buffers every move: the page faults)
//   drag_paced  `drag`, with 128 MB written and 50 ms of sleep between moves, as a 20 Hz
//          drag meets it in the service (the sleep costs the most: docs/benchmarks.md
//          "The paced drag")
//   drag_paced_warm  `drag_paced` with the cores kept warm from each move on, as the service
//          does while a drag is active (warm_cores.h)
enum class Move { full, exact, drag, light, alloc, drag_paced, drag_paced_warm };

// What a 20 Hz drag leaves between two moves: other work (encoding, the network, other
// sessions) through the caches, and 50 ms in which this thread's cores may idle. Untimed.
void between_paced_moves(benchmark::State& state) {
  state.PauseTiming();
  static std::vector<char> junk(std::size_t{128} << 20);
  static char pass = 0;
  std::memset(junk.data(), ++pass, junk.size());
  benchmark::DoNotOptimize(junk.data());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  state.ResumeTiming();
}

// `warmup` untimed moves first (the 1M steady state: first touches and the float32 copy of
// the factor are paid before the timed moves).
void BM_Update(benchmark::State& state, std::string key, double beta, Move mode, int warmup) {
  Case& c = get(key);
  c.cs->prepare(Beta{beta});
  UpdateOptions opt;
  if (mode == Move::light) opt.energies = opt.normals = false;
  const bool paced = mode == Move::drag_paced || mode == Move::drag_paced_warm;
  const bool drag = mode == Move::drag || paced;
  if (mode == Move::exact || drag) opt.energies = false;
  if (drag) {
    opt.measures = false;
    opt.precision = FramePrecision::drag;
  }
  UpdateWorkspace ws;
  Frame f;
  int i = 0;
  for (; i < warmup; ++i) {
    const HandleTransform t = move(c, i);
    c.cs->update(std::span(&t, 1), Beta{beta}, opt, ws, f);
  }
  long solves = 0;  // K_FF solves per move (the drag path's refinement steps)
  for (auto _ : state) {
    const HandleTransform t = move(c, i++);
    if (mode == Move::drag_paced_warm) WarmCores::instance().extend();
    if (mode == Move::alloc) {
      Frame fresh = c.cs->update(std::span(&t, 1), Beta{beta}, opt);
      benchmark::DoNotOptimize(fresh.positions.data());
    } else {
      c.cs->update(std::span(&t, 1), Beta{beta}, opt, ws, f);
      benchmark::DoNotOptimize(f.positions.data());
      solves += f.solves;
    }
    if (paced) between_paced_moves(state);
  }
  size_counters(state, c);
  if (mode != Move::alloc)
    state.counters["solves"] = static_cast<double>(solves) / static_cast<double>(state.iterations());
}

// The same 2-second motion (rest at 0 s, move(c, 0) at 2 s) exported two ways (issue 39): as
// a rig (skin weights from Φ, the current pose and 2 keys solved exactly and measured against
// their LBS, the skinned GLB) and as morph targets (ExportAnimation: 61 frames at 30 fps, each
// a full deformation). Counters: the GLB's bytes; the rig's LBS error at the pose (max, rms,
// fractions of the rest bbox diagonal). Engine work only (the service adds the base-order
// copies and the chunked send).
enum class Export { rig, morph };

void BM_Export(benchmark::State& state, std::string key, Export kind) {
  Case& c = get(key);
  c.cs->prepare(Beta{0});
  const PreparedMesh& pm = *c.pm;
  const Eigen::Vector3d pivot = c.cs->centroid(0);
  HandleTransform rest;
  rest.pivot = pivot;
  HandleTransform posed = move(c, 0);
  posed.pivot = pivot;
  const std::vector<Keyframe> keys = {{0.0, {rest}}, {2.0, {posed}}};
  const std::vector<Eigen::Vector3d> rest_pivots = {pivot};
  std::size_t bytes = 0;
  SkinError error;
  const double diagonal =
      (pm.mesh().V.colwise().maxCoeff() - pm.mesh().V.colwise().minCoeff()).norm();
  for (auto _ : state) {
    if (kind == Export::rig) {
      const SkinWeights w = skin_weights(c.cs->harmonic_basis(), 4);
      RigGlbInput in;
      in.V = pm.mesh().V;
      in.N = vertex_normals(in.V, pm.mesh().F);
      in.F = pm.mesh().F;
      in.joints = w.joint;
      in.weights = w.weight;
      in.bind = {pivot};
      const std::vector<const HandleTransform*> poses = {&posed, &rest, &posed};
      for (std::size_t k = 0; k < poses.size(); ++k) {
        const JointPose jp = joint_pose(*poses[k], pivot, pivot);
        const JointTrs trs{jp.translation, jp.rotation, jp.scale};
        if (k == 0) in.pose = {trs};
        else {
          in.key_times.push_back(keys[k - 1].time);
          in.keys.push_back({trs});
        }
        const HandleTransform played = as_transform(jp, pivot);
        const Frame f = c.cs->update(std::span(poses[k], 1), Beta{0},
                                     {.energies = false, .normals = false, .measures = false});
        const SkinError e = skin_error(skin_positions(in.V, w, std::span(&played, 1),
                                                      std::span(&pivot, 1)),
                                       f.positions);
        if (k == 0) error = e;
      }
      const std::string glb = rig_glb(in);
      bytes = glb.size();
      benchmark::DoNotOptimize(glb.data());
    } else {
      const std::vector<double> times = sample_times(0, 2, 30);
      AnimationGlb glb(pm.mesh().F, pm.n(), times, false, false);
      for (double t : times) {
        const std::vector<HandleTransform> pose = pose_at(keys, t, Easing::linear, rest_pivots);
        const Frame f = c.cs->update(pose, Beta{0}, {.energies = false, .measures = false});
        glb.add_frame(f.positions, f.normals);
      }
      const std::string out = glb.finish();
      bytes = out.size();
      benchmark::DoNotOptimize(out.data());
    }
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  if (kind == Export::rig) {
    state.counters["lbs_max"] = error.max / diagonal;
    state.counters["lbs_rms"] = error.rms / diagonal;
  }
  size_counters(state, c);
}

// Two threads updating the same set concurrently (a session per client): throughput.
void BM_UpdateConcurrent(benchmark::State& state, std::string key, double beta) {
  Case& c = get(key);
  c.cs->prepare(Beta{beta});
  int i = state.thread_index() * 1000;
  for (auto _ : state) {
    const HandleTransform t = move(c, i++);
    Frame f = c.cs->update(std::span(&t, 1), Beta{beta});
    benchmark::DoNotOptimize(f.positions.data());
  }
}

// The mesh's METIS order (nested_dissection of L), from 1 or 2 threads at once: two sessions
// opening different meshes. Each thread has its own METIS random stream
// (vertex_ordering.cpp), so the two calls need not wait for each other.
void BM_Ordering(benchmark::State& state, std::string key) {
  Case& c = get(key);
  for (auto _ : state) benchmark::DoNotOptimize(nested_dissection(c.pm->L()).data());
}

// Phases of update(), each on its own (the same operations the engine performs).
enum class Phase {
  guidance, rhs, solve, measures, measures_ef2, normals, normals_gather,
  // Candidate improvements, measured on the same data (not used by the engine):
  guidance_no_R,          // the engine's guidance without R_l (drag frames: no measures)
  guidance_no_R_generic,  // the same with the baseline build of the kernels (cpu_features.h)
  measures_generic,       // measures with the baseline build
  guidance_per_triangle,  // one sincos per triangle (the engine before 2026-12-03)
  // Eigen's products against the engine's sparse_times3.h kernels, on the same data:
  rhs_fused,        // (GᵀW)_F g − K_FC x_C with sparse_times3 (what update() runs)
  residual,         // b − K_FF x with Eigen (three passes over K_FF, one per column)
  residual_fused,   // the same with symmetric_residual3 (what the drag refinement runs)
  GX                // the G·X' product inside measure() on its own
};

using RowMajorX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// The single-handle guidance field as the engine computed it before one sincos per vertex
// (guidance.cpp): one sincos per triangle, R_l always written. The reference for
// Phase/N/guidance's time and for its `diff_vs_per_triangle` counter.
void guidance_per_triangle(const Triangles& F, const Vertices& normals, const Eigen::MatrixXd& Phi,
                           const HandleTransform& t, RowMajorX3& g,
                           std::vector<Eigen::Quaterniond>& R_l) {
  const Eigen::Index m = F.rows();
  g.resize(3 * m, 3);
  R_l.resize(static_cast<std::size_t>(m));
  Eigen::Quaterniond q = t.rotation.normalized();
  if (q.w() < 0) q.coeffs() *= -1.0;
  const double s = q.vec().norm();
  const double half_angle = std::atan2(s, q.w());
  const Eigen::Vector3d axis = s > 0 ? Eigen::Vector3d(q.vec() / s) : Eigen::Vector3d::UnitX();
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d S1 = t.stretch;
  const double* phi = Phi.data();
#pragma omp parallel for schedule(static)
  for (Eigen::Index l = 0; l < m; ++l) {
    const double h = (phi[F(l, 0)] + phi[F(l, 1)] + phi[F(l, 2)]) / 3.0;
    const double a = h * half_angle;
    const Eigen::Quaterniond R(std::cos(a), std::sin(a) * axis.x(), std::sin(a) * axis.y(),
                               std::sin(a) * axis.z());
    R_l[l] = R;
    const Eigen::Matrix3d M = R.toRotationMatrix() * ((1.0 - h) * I + h * S1);
    const Eigen::Vector3d n = normals.row(l).transpose();
    const Eigen::Vector3d Mn = M * n;
    double* gl = g.data() + 9 * l;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) gl[3 * r + c] = M(c, r) - n[r] * Mn[c];
  }
}

void BM_Phase(benchmark::State& state, std::string key, Phase phase, double beta) {
  Case& c = get(key);
  System& s = system(c, beta);
  const HandleTransform t = move(c, 0);
  GuidanceField g;
  std::vector<Eigen::Quaterniond> R_l;  // guidance_per_triangle's
  Vertices Rn;
  GuidanceScratch scratch;
  c.cs->guidance(std::span(&t, 1), g, &Rn, scratch);
  const Frame frame = c.cs->update(std::span(&t, 1), Beta{beta}, {false, false});
  Eigen::MatrixX3d x_C(static_cast<Eigen::Index>(c.constrained.size()), 3);
  for (std::size_t r = 0; r < c.constrained.size(); ++r)
    x_C.row(static_cast<Eigen::Index>(r)) = frame.positions.row(c.constrained[r]);
  Eigen::MatrixXd rhs = s.GtW_F * g - s.K_FC * x_C;
  const SupernodalFactorization* fac = phase == Phase::solve ? &cholmod(s) : nullptr;
  Eigen::VectorXf ef2;
  RowMajorX3 g_row = g;
  Eigen::MatrixX3d Y;
  Vertices face_w, N_reused;
  Eigen::MatrixXd fused = rhs;  // the kernels' output (sized: no allocation while timed)
  Eigen::MatrixXd x_F = rhs;    // any n_F × 3 positions will do for a residual
  for (Eigen::Index i = 0; i < x_F.rows(); ++i) x_F.row(i) *= 1e-3 * static_cast<double>(i % 97);
  const Isa isa = kernel_isa();
  if (phase == Phase::guidance_no_R_generic || phase == Phase::measures_generic)
    set_kernel_isa(Isa::generic);
  for (auto _ : state) {
    switch (phase) {
      case Phase::guidance:
        c.cs->guidance(std::span(&t, 1), g, &Rn, scratch);
        benchmark::DoNotOptimize(g.data());
        break;
      case Phase::guidance_no_R:
      case Phase::guidance_no_R_generic:
        c.cs->guidance(std::span(&t, 1), g, nullptr, scratch);
        benchmark::DoNotOptimize(g.data());
        break;
      case Phase::rhs:  // with Eigen, as update() did before sparse_times3
        fused.noalias() = s.GtW_F * g;
        fused.noalias() -= s.K_FC * x_C;
        benchmark::DoNotOptimize(fused.data());
        break;
      case Phase::solve: {
        Eigen::MatrixXd x = fac->solve(rhs);
        benchmark::DoNotOptimize(x.data());
        break;
      }
      case Phase::measures:
      case Phase::measures_generic:
      case Phase::measures_ef2: {
        Measures m = measure(*c.pm, frame.positions, g, Rn,
                             phase == Phase::measures_ef2 ? &ef2 : nullptr);
        benchmark::DoNotOptimize(m);
        break;
      }
      case Phase::guidance_per_triangle:
        guidance_per_triangle(c.pm->mesh().F, c.pm->normals(), c.cs->harmonic_basis(), t, g_row,
                              R_l);
        benchmark::DoNotOptimize(g_row.data());
        break;
      case Phase::rhs_fused:
        sparse_times3(s.GtW_F, g, fused);
        fused.noalias() -= s.K_FC * x_C;
        benchmark::DoNotOptimize(fused.data());
        break;
      case Phase::residual:
        fused.noalias() = rhs;
        fused.noalias() -= s.K_FF.transpose() * x_F;
        benchmark::DoNotOptimize(fused.data());
        break;
      case Phase::residual_fused:
        symmetric_residual3(s.K_FF, x_F, rhs, fused);
        benchmark::DoNotOptimize(fused.data());
        break;
      case Phase::GX:
        Y = c.pm->G() * frame.positions;
        benchmark::DoNotOptimize(Y.data());
        break;
      case Phase::normals: {
        Vertices N = vertex_normals(frame.positions, c.pm->mesh().F);
        benchmark::DoNotOptimize(N.data());
        break;
      }
      case Phase::normals_gather: {  // what update() runs: gathering, two cores, buffers reused
        vertex_normals(frame.positions, c.pm->mesh().F, c.pm->vertex_triangles(), face_w, N_reused);
        benchmark::DoNotOptimize(N_reused.data());
        break;
      }
    }
  }
  set_kernel_isa(isa);
  size_counters(state, c);
  if (phase == Phase::guidance) {  // the same field as one sincos per triangle, to rounding
    guidance_per_triangle(c.pm->mesh().F, c.pm->normals(), c.cs->harmonic_basis(), t, g_row, R_l);
    c.cs->guidance(std::span(&t, 1), g, &Rn, scratch);
    state.counters["diff_vs_per_triangle"] = (RowMajorX3(g) - g_row).cwiseAbs().maxCoeff();
  }
  // The kernels against Eigen's products: 0 (bit-identical sums, sparse_times3.h).
  if (phase == Phase::rhs_fused)
    state.counters["diff_vs_eigen"] = (fused - rhs).cwiseAbs().maxCoeff();
  if (phase == Phase::residual_fused) {
    const Eigen::MatrixXd eigen = rhs - s.K_FF.transpose() * x_F;
    state.counters["diff_vs_eigen"] = (fused - eigen).cwiseAbs().maxCoeff();
  }
}

// Solver comparison on the same K_FF: CHOLMOD supernodal (METIS; the engine's
// SupernodalFactorization) vs Eigen SimplicialLLT (AMD; the thesis's solver).
enum class Op { analyze_factor, factor, solve3 };

// The three right-hand sides solved with an analysed and factored solver.
template <class Solver>
void solve_once(const Solver& solver, const Eigen::MatrixXd& B) {
  Eigen::MatrixXd X = solver.solve(B);
  benchmark::DoNotOptimize(X.data());
}
// Solver/.../cholmod/solve3 and Solve/.../cholmod measure stock cholmod_solve, as before
// SupernodalFactorization::solve took the fused kernel (Phase/N/solve measures the engine's path).
void solve_once(const SupernodalFactorization& f, const Eigen::MatrixXd& B) {
  Eigen::MatrixXd X = f.solve_cholmod(B);
  benchmark::DoNotOptimize(X.data());
}

void solver_counters(benchmark::State& state, const Case& c, const System& s,
                     std::size_t factor_bytes) {
  size_counters(state, c);
  state.counters["nnz_K"] = static_cast<double>(s.K_FF.nonZeros());
  state.counters["factor_MB"] = mb(factor_bytes);
}

void BM_Cholmod(benchmark::State& state, std::string key, double beta, Op op) {
  Case& c = get(key);
  System& s = system(c, beta);
  const Eigen::MatrixXd B = random_rhs(s.K_FF.rows());
  const SupernodalFactorization& analysed = cholmod(s);
  for (auto _ : state) {
    switch (op) {
      case Op::analyze_factor:
        free_untimed(state, std::make_unique<SupernodalFactorization>(s.K_FF));
        break;
      case Op::factor:
        free_untimed(state, std::make_unique<SupernodalFactorization>(analysed, s.K_FF));
        break;
      case Op::solve3:
        solve_once(analysed, B);
        break;
    }
  }
  solver_counters(state, c, s, analysed.memory_bytes());
  state.counters["nnz_L"] = static_cast<double>(analysed.factor()->xsize);
}

// The same K_FF ordered as a ConstraintSet orders it: the mesh's nested dissection (computed
// untimed, once per mesh) restricted to F, instead of METIS on K_FF. analyze_factor and
// solve3 only (factor alone is the same numeric work as BM_Cholmod's).
void BM_MeshOrder(benchmark::State& state, std::string key, double beta, Op op) {
  Case& c = get(key);
  System& s = system(c, beta);
  const Eigen::MatrixXd B = random_rhs(s.K_FF.rows());
  const auto perm =
      restrict_order(s.raw_beta == 0 ? c.pm->order() : c.pm->wide_order(), c.free_);
  const SupernodalFactorization ordered(s.K_FF, false, &perm);
  for (auto _ : state) {
    if (op == Op::solve3)
      solve_once(ordered, B);
    else
      free_untimed(state, std::make_unique<SupernodalFactorization>(s.K_FF, false, &perm));
  }
  solver_counters(state, c, s, ordered.memory_bytes());
  state.counters["nnz_L"] = static_cast<double>(ordered.factor()->xsize);
}

void BM_Simplicial(benchmark::State& state, std::string key, double beta, Op op) {
  Case& c = get(key);
  System& s = system(c, beta);
  const Eigen::MatrixXd B = random_rhs(s.K_FF.rows());
  System::Simplicial& analysed = simplicial(s);
  for (auto _ : state) {
    switch (op) {
      case Op::analyze_factor: {
        auto f = std::make_unique<System::Simplicial>();
        f->compute(s.K_FF);
        free_untimed(state, std::move(f));
        break;
      }
      case Op::factor:
        analysed.factorize(s.K_FF);
        benchmark::DoNotOptimize(&analysed);
        break;
      case Op::solve3:
        solve_once(analysed, B);
        break;
    }
  }
  // Eigen's simplicial L: values (double) + row indices (int).
  solver_counters(state, c, s,
                  static_cast<std::size_t>(analysed.matrixL().nestedExpression().nonZeros()) * 12);
}

// Memory measured while the case was built (see finish_case). Iterations(1); the time
// column of this benchmark is meaningless.
void BM_Memory(benchmark::State& state, std::string key) {
  Case& c = get(key);
  for (auto _ : state) benchmark::DoNotOptimize(&c);
  size_counters(state, c);
  state.counters["rss_before_MB"] = c.rss_before;
  state.counters["peak_open_MB"] = c.hwm_open;             // VmHWM after session open
  state.counters["peak_beta_MB"] = c.hwm_beta;             // VmHWM during first β > 0
  state.counters["rss_after_MB"] = c.rss_after;
  state.counters["prepared_MB"] = mb(c.pm_bytes);          // PreparedMesh::memory_bytes
  state.counters["cs_open_MB"] = mb(c.cs_bytes_open);      // ConstraintSet, β = 0 only
  state.counters["cs_beta_MB"] = mb(c.cs_bytes_beta);      // + wide blocks + β = 0.5
  state.counters["open_s"] = c.open_seconds;
  PhaseMedians phases;  // one sample each: the fixture's own open
  phases.add(c.open_pm);
  phases.add(c.open_cs);
  phases.report(state);
  state.counters["beta_first_s"] = c.beta_seconds;
  state.counters["wide_order_MB"] = c.wide_order_mb;  // peak above RSS: Reg + METIS's graphs
  state.counters["wide_order_s"] = c.wide_order_seconds;
}

// ---------------------------------------------------------------------------------------
std::string beta_tag(double beta) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "beta:%g", beta);
  return buf;
}

// Repetition policy: medians of 5 for the fast benchmarks; 1M (and SimplicialLLT at 100K
// β > 0) run once; Iterations(1) where a single iteration takes seconds.
enum class Cost { fast, slow, huge };

benchmark::internal::Benchmark* policy(benchmark::internal::Benchmark* b, Cost cost) {
  b->Unit(benchmark::kMillisecond)->UseRealTime();
  if (g_smoke) return b->Iterations(1)->Repetitions(1);
  switch (cost) {
    case Cost::fast: return b->Repetitions(5)->ReportAggregatesOnly(true);
    case Cost::slow: return b->MinTime(0.5)->Repetitions(3)->ReportAggregatesOnly(true);
    case Cost::huge: return b->Iterations(1)->Repetitions(1);
  }
  return b;
}

template <typename... Args>
void reg(const std::string& name, Cost cost, Args&&... args) {
  policy(benchmark::RegisterBenchmark(name.c_str(), std::forward<Args>(args)...), cost);
}

void register_size(int n) {
  const std::string key = case_name(n);
  std::string N(1, '/');  // names: FAMILY/N[/...] (built in two steps: GCC 12's -Wrestrict)
  N += std::to_string(n);
  const bool big = n >= 1000000, small = n <= 10000;
  const Cost fast = big ? Cost::huge : Cost::fast;
  const Cost slow = big ? Cost::huge : (small ? Cost::fast : Cost::slow);

  reg("Memory" + N, Cost::huge, BM_Memory, key);
  reg("Operators" + N, slow, BM_Operators, key);
  reg("ConstraintSet" + N, slow, BM_ConstraintSet, key);
  reg("SessionOpen" + N, slow, BM_SessionOpen, key);
  reg("BetaFirst" + N, slow, BM_BetaFirst, key);
  reg("BetaFirstNewMesh" + N, slow, BM_BetaFirstNewMesh, key);
  reg("BetaRefactor" + N, slow, BM_BetaRefactor, key);
  for (double beta : kBetas) {
    for (auto [mode, tag] : {std::pair{Move::full, "full"}, {Move::exact, "exact"},
                             {Move::drag, "drag"}, {Move::light, "light"}, {Move::alloc, "alloc"},
                             {Move::drag_paced, "drag_paced"},
                             {Move::drag_paced_warm, "drag_paced_warm"}})
      reg("Update" + N + "/" + beta_tag(beta) + "/" + tag, fast, BM_Update, key, beta, mode, 0);
  }
  if (big)  // the 1M drag frame is measured in a steady state: 2 moves first, then 5 timed
    for (auto [mode, tag] : {std::pair{Move::exact, "exact"}, {Move::drag, "drag"}})
      benchmark::RegisterBenchmark(("Update" + N + "/beta:0/" + tag + "/steady").c_str(),
                                   BM_Update, key, 0.0, mode, g_smoke ? 0 : 2)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->Iterations(g_smoke ? 1 : 5)
          ->Repetitions(1);
  if (!big) {
    auto* b = benchmark::RegisterBenchmark(("UpdateConcurrent" + N + "/" + beta_tag(0.0)).c_str(),
                                           BM_UpdateConcurrent, key, 0.0);
    b->Unit(benchmark::kMillisecond)->UseRealTime()->Threads(1)->Threads(2);
    if (g_smoke) b->Iterations(1);
  }
  if (!big) {
    auto* b = benchmark::RegisterBenchmark(("Ordering" + N).c_str(), BM_Ordering, key);
    b->Unit(benchmark::kMillisecond)->UseRealTime()->Threads(1)->Threads(2);
    if (g_smoke) b->Iterations(1);
  }
  if (!big) {
    reg("Export" + N + "/rig", slow, BM_Export, key, Export::rig);
    reg("Export" + N + "/morph_30fps_2s", slow, BM_Export, key, Export::morph);
  }
  reg("Phase" + N + "/guidance", fast, BM_Phase, key, Phase::guidance, 0.0);
  reg("Phase" + N + "/measures", fast, BM_Phase, key, Phase::measures, 0.0);
  reg("Phase" + N + "/measures_generic", fast, BM_Phase, key, Phase::measures_generic, 0.0);
  reg("Phase" + N + "/measures+ef2", fast, BM_Phase, key, Phase::measures_ef2, 0.0);
  reg("Phase" + N + "/normals", fast, BM_Phase, key, Phase::normals, 0.0);
  reg("Phase" + N + "/normals_gather", fast, BM_Phase, key, Phase::normals_gather, 0.0);
  reg("Phase" + N + "/GX", fast, BM_Phase, key, Phase::GX, 0.0);
  reg("Phase" + N + "/guidance_no_R", fast, BM_Phase, key, Phase::guidance_no_R, 0.0);
  reg("Phase" + N + "/guidance_no_R_generic", fast, BM_Phase, key, Phase::guidance_no_R_generic,
      0.0);
  reg("Phase" + N + "/guidance_per_triangle", fast, BM_Phase, key, Phase::guidance_per_triangle,
      0.0);
  for (double beta : kBetas) {
    reg("Phase" + N + "/rhs/" + beta_tag(beta), fast, BM_Phase, key, Phase::rhs, beta);
    reg("Phase" + N + "/rhs_fused/" + beta_tag(beta), fast, BM_Phase, key, Phase::rhs_fused,
        beta);
    reg("Phase" + N + "/residual/" + beta_tag(beta), fast, BM_Phase, key, Phase::residual, beta);
    reg("Phase" + N + "/residual_fused/" + beta_tag(beta), fast, BM_Phase, key,
        Phase::residual_fused, beta);
    reg("Phase" + N + "/solve/" + beta_tag(beta), fast, BM_Phase, key, Phase::solve, beta);
  }
  for (double beta : kBetas) {
    const std::string B = beta_tag(beta);
    reg("Solver" + N + "/cholmod/" + B + "/analyze+factor", slow, BM_Cholmod, key, beta,
        Op::analyze_factor);
    reg("Solver" + N + "/cholmod/" + B + "/factor", slow, BM_Cholmod, key, beta, Op::factor);
    reg("Solver" + N + "/cholmod/" + B + "/solve3", fast, BM_Cholmod, key, beta, Op::solve3);
    reg("Solver" + N + "/mesh_order/" + B + "/analyze+factor", slow, BM_MeshOrder, key, beta,
        Op::analyze_factor);
    reg("Solver" + N + "/mesh_order/" + B + "/solve3", fast, BM_MeshOrder, key, beta,
        Op::solve3);
    // SimplicialLLT (AMD) at β > 0: 5 s per factorization at 100K, minutes at 1M (skipped).
    if (big && beta > 0) continue;
    const Cost sslow = beta > 0 && !small ? Cost::huge : slow;
    reg("Solver" + N + "/simplicial/" + B + "/analyze+factor", sslow, BM_Simplicial, key, beta,
        Op::analyze_factor);
    reg("Solver" + N + "/simplicial/" + B + "/factor", sslow, BM_Simplicial, key, beta,
        Op::factor);
    reg("Solver" + N + "/simplicial/" + B + "/solve3", fast, BM_Simplicial, key, beta,
        Op::solve3);
  }
}

void register_botsch_sorkine(const std::string& model) {
  const std::string key = "bs-" + model;
  const std::string P = "BS/" + model + "/";
  reg(P + "memory", Cost::huge, BM_Memory, key);
  reg(P + "open", Cost::fast, BM_SessionOpen, key);
  reg(P + "refactor", Cost::fast, BM_BetaRefactor, key);
  for (double beta : kBetas) {
    reg(P + "update/" + beta_tag(beta), Cost::fast, BM_Update, key, beta, Move::full, 0);
    reg(P + "cholmod/" + beta_tag(beta) + "/factor", Cost::fast, BM_Cholmod, key, beta,
        Op::factor);
    reg(P + "simplicial/" + beta_tag(beta) + "/factor", Cost::fast, BM_Simplicial, key, beta,
        Op::factor);
    reg(P + "cholmod/" + beta_tag(beta) + "/solve3", Cost::fast, BM_Cholmod, key, beta,
        Op::solve3);
    reg(P + "simplicial/" + beta_tag(beta) + "/solve3", Cost::fast, BM_Simplicial, key, beta,
        Op::solve3);
  }
}

}  // namespace

int main(int argc, char** argv) {
  hdeform::ensure_process_environment(argv);  // before any allocation or OpenMP loop
  if (!bench::initialize(argc, argv, g_smoke)) return 1;

  bench::register_solve_benchmarks(g_smoke);  // Bandwidth/read, Solve/N/… (solve_bench.cpp)
  for (const char* model : {"cactus", "bar", "cylinder", "plane"}) register_botsch_sorkine(model);
  for (int n : kSizes) register_size(n);

  benchmark::AddCustomContext("peak_reset", reset_peak() ? "clear_refs" : "unavailable");
  benchmark::AddCustomContext("note",
                              "SimplicialLLT at beta>0 is skipped at 1M vertices (minutes per "
                              "factorization); 1M benchmarks run one iteration");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

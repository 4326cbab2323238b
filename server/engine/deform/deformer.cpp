#include "engine/deform/deformer.h"

#include "engine/deform/guidance.h"
#include "engine/deform/harmonic.h"
#include "engine/mesh/validate.h"
#include "engine/mesh/vertex_normals.h"
#include "engine/operators/operator_assembly.h"
#include "engine/operators/sparse_times3.h"
#include "engine/operators/system_blocks.h"
#include "engine/runtime/elapsed_ms.h"
#include "engine/runtime/run_beside.h"
#include "engine/runtime/two_threads.h"
#include "engine/solve/permutation.h"
#include "engine/solve/solver.h"
#include "engine/solve/vertex_ordering.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <string>

namespace hdeform {

namespace {

std::size_t sparse_bytes(const SparseMatrix& A) {
  return static_cast<std::size_t>(A.nonZeros()) * (sizeof(double) + sizeof(int)) +
         static_cast<std::size_t>(A.outerSize() + 1) * sizeof(int);
}
std::size_t sparse_bytes(const SparseMatrixR& A) {
  return static_cast<std::size_t>(A.nonZeros()) * (sizeof(double) + sizeof(int)) +
         static_cast<std::size_t>(A.outerSize() + 1) * sizeof(int);
}

// B₃ D₃ (3|E_int| × 3m): row 3e+d has +len at 3a+d and −len at 3b+d.
SparseMatrix weighted_differences(const std::vector<InteriorEdge>& edges, Eigen::Index m) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(6 * edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e)
    for (int d = 0; d < 3; ++d) {
      t.emplace_back(static_cast<int>(3 * e) + d, 3 * edges[e].tri[0] + d, edges[e].length);
      t.emplace_back(static_cast<int>(3 * e) + d, 3 * edges[e].tri[1] + d, -edges[e].length);
    }
  SparseMatrix BD(3 * static_cast<Eigen::Index>(edges.size()), 3 * m);
  BD.setFromTriplets(t.begin(), t.end());
  return BD;
}

// Union-find over triangle corners: connected components by shared vertices.
std::vector<int> vertex_components(int n, const Triangles& F, int& count) {
  std::vector<int> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (Eigen::Index l = 0; l < F.rows(); ++l)
    for (int c = 1; c < 3; ++c) {
      const int a = find(F(l, 0)), b = find(F(l, c));
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  std::vector<int> label(static_cast<std::size_t>(n), -1), comp(static_cast<std::size_t>(n));
  count = 0;
  for (int v = 0; v < n; ++v) {
    const int r = find(v);
    if (label[r] < 0) label[r] = count++;
    comp[v] = label[r];
  }
  return comp;
}

// x's structure with values a·values(x) + b·y, y being the values of a matrix of x's
// structure. On the OpenMP team: every β change combines K_FF's and K_FC's (`K_FF_ms`).
template <typename Sparse>
Sparse combine(double a, const Sparse& x, double b, const std::vector<double>& y) {
  const Eigen::Index nnz = x.nonZeros();
  if (static_cast<std::size_t>(nnz) != y.size())
    throw std::logic_error("combine: the two parts' structures differ");
  Sparse out = x;
  double* o = out.valuePtr();
  const double* xv = x.valuePtr();
  const double* yv = y.data();
#pragma omp parallel for schedule(static)
  for (Eigen::Index k = 0; k < nnz; ++k) o[k] = a * xv[k] + b * yv[k];
  return out;
}

// The largest |value| a pass saw, and whether every value passed its check.
struct MaxAbs {
  double max = 0;
  bool ok = true;
};

// fn(i0, i1) → MaxAbs over [0, n) in chunks on both threads (for_chunks), combined.
template <class Fn>
MaxAbs chunks_max_abs(Eigen::Index n, Fn&& fn) {
  MaxAbs part[kChunks];
  for_chunks(n, [&](Eigen::Index i0, Eigen::Index i1, int c) { part[c] = fn(i0, i1); });
  MaxAbs all;
  for (const MaxAbs& p : part) all = {std::max(all.max, p.max), all.ok && p.ok};
  return all;
}

// x += dx (x column-major, dx row-major), returning max |dx| (NaN if dx has one): one pass,
// both threads.
double add_and_measure(const Rows3& dx, Eigen::MatrixXd& x) {
  const double* d = dx.data();
  double *y0 = x.col(0).data(), *y1 = x.col(1).data(), *y2 = x.col(2).data();
  const MaxAbs step = chunks_max_abs(x.rows(), [&](Eigen::Index k0, Eigen::Index k1) {
    MaxAbs r;
    for (Eigen::Index k = k0; k < k1; ++k) {
      const double* dk = d + 3 * k;
      y0[k] += dk[0];
      y1[k] += dk[1];
      y2[k] += dk[2];
      r.max = std::max({r.max, std::abs(dk[0]), std::abs(dk[1]), std::abs(dk[2])});
      r.ok = r.ok && !std::isnan(dk[0]) && !std::isnan(dk[1]) && !std::isnan(dk[2]);
    }
    return r;
  });
  return step.ok ? step.max : std::numeric_limits<double>::quiet_NaN();
}

std::string fmt_result_error(int handle, const HandleTransform& t) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "handle %d's transform (translation %g %g %g, largest scale entry %g) moves the "
                "surface out of range: the result is not finite or exceeds %g model units",
                handle, t.translation.x(), t.translation.y(), t.translation.z(),
                t.stretch.cwiseAbs().maxCoeff(), kMaxCoordinate);
  return buf;
}

}  // namespace

// ---------------------------------------------------------------------------------------
std::shared_ptr<const PreparedMesh> PreparedMesh::create(TriMesh mesh, PrepareOrder order) {
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  auto lap = [&t0] {  // ms since the previous lap
    const auto now = Clock::now();
    const double ms = elapsed_ms(t0, now);
    t0 = now;
    return ms;
  };
  ValidationResult checked = validate_mesh(mesh);
  std::shared_ptr<PreparedMesh> pm(new PreparedMesh());
  pm->unreferenced_ = std::move(checked.unreferenced);
  pm->mesh_ = std::move(mesh);
  BuildTimings& timings = pm->timings_;
  timings.validate_ms = lap();

  auto operators = [&pm, &lap] {
    const Vertices& V = pm->mesh_.V;
    const Triangles& F = pm->mesh_.F;
    BuildTimings& timings = pm->timings_;
    pm->areas_ = triangle_areas(V, F);
    pm->total_area_ = pm->areas_.sum();
    pm->normals_ = triangle_normals(V, F);
    pm->grads_ = hat_gradients(V, F);
    timings.geometry_ms = lap();
    pm->vertex_triangles_ = VertexTriangles::build(pm->n(), F);
    pm->edges_ = interior_edges(V, F, pm->vertex_triangles_);
    timings.edges_ms = lap();
    pm->L_ = assemble_laplacian(F, pm->grads_, pm->areas_, pm->vertex_triangles_);
    timings.laplacian_ms = lap();
    pm->component_ = vertex_components(pm->n(), F, pm->num_components_);
    timings.components_ms = lap();
  };
  auto keep_graph = [&pm, &checked] {  // for order() to order on first use
    pm->edge_graph_bytes_ =
        (checked.edges.start.capacity() + checked.edges.rows.capacity()) * sizeof(int);
    pm->edge_graph_ = std::move(checked.edges);
  };
  if (order == PrepareOrder::on_first_use) {
    operators();
    keep_graph();
    return pm;
  }
  // The same graph, so the same order, as order() computes on first use. A failed METIS
  // call (out of memory) fails no open: the graph is kept and order() tries again.
  const auto start = Clock::now();
  std::vector<int> computed;
  run_beside(operators, [&computed, &checked, &pm] {
    const auto t = Clock::now();
    try {
      computed = nested_dissection(checked.edges);
    } catch (const std::exception&) {
      computed.clear();
    }
    pm->timings_.order_ms = elapsed_ms(t);
  });
  timings.beside_ms = elapsed_ms(start);
  if (computed.empty()) {
    keep_graph();
  } else {
    pm->adopt_order(std::move(computed), /*wide=*/false);
  }
  return pm;
}

SparseMatrix PreparedMesh::Reg() const {
  const auto t0 = std::chrono::steady_clock::now();
  SparseMatrix reg = assemble_regularizer(mesh_.F, grads_, edges_, vertex_triangles_);
  reg_ms_.store(elapsed_ms(t0), std::memory_order_relaxed);
  return reg;
}


// Computes `order` once under `once` (the first caller pays and gets the time in *ms).
template <class Compute>
const std::vector<int>& PreparedMesh::lazy_order(std::once_flag& once, std::vector<int>& order,
                                                 std::atomic<bool>& ready, Compute compute,
                                                 double* ms) const {
  if (ms) *ms = 0;
  std::call_once(once, [&] {
    const auto t0 = std::chrono::steady_clock::now();
    order = compute();
    ready.store(true, std::memory_order_release);
    if (ms) *ms = elapsed_ms(t0);
  });
  return order;
}

const std::vector<int>& PreparedMesh::order(double* ms) const {
  return lazy_order(order_once_, order_, order_ready_,
                    [this] {
                      auto order = nested_dissection(edge_graph_);
                      edge_graph_ = EdgePattern{};
                      return order;
                    },
                    ms);
}

const std::vector<int>& PreparedMesh::wide_order(double* ms, const SparseMatrix* reg) const {
  return lazy_order(wide_order_once_, wide_order_, wide_order_ready_,
                    [&] {
                      return reg ? nested_dissection(L_, *reg) : nested_dissection(L_, Reg());
                    },
                    ms);
}

bool PreparedMesh::adopt_order(std::vector<int> order, bool wide) const {
  if (!is_permutation_of(order, n())) return false;
  bool taken = false;
  std::call_once(wide ? wide_order_once_ : order_once_, [&] {
    (wide ? wide_order_ : order_) = std::move(order);
    if (!wide) edge_graph_ = EdgePattern{};
    (wide ? wide_order_ready_ : order_ready_).store(true, std::memory_order_release);
    taken = true;
  });
  return taken;
}

PreparedMesh::BuildTimings PreparedMesh::build_timings() const {
  BuildTimings t = timings_;
  t.regularizer_ms = reg_ms_.load(std::memory_order_relaxed);
  return t;
}

SparseMatrix PreparedMesh::G() const {
  return assemble_gradient(mesh_.F, grads_, vertex_triangles_);
}
SparseMatrix PreparedMesh::GtA() const { return assemble_gta(mesh_.F, grads_, areas_, n()); }
SparseMatrix PreparedMesh::GtDBD() const { return assemble_gtdbd(mesh_.F, grads_, edges_, n()); }

double PreparedMesh::raw_beta(Beta beta) const {
  if (!std::isfinite(beta.value) || beta.value < 0.0 || beta.value >= 1.0)
    throw InvalidInput("beta must be in [0, 1), got " + std::to_string(beta.value));
  if (beta.units == BetaUnits::raw || beta.value == 0.0) return beta.value;
  // s scales the mesh to unit area; β′/(1−β′) = β / ((1−β) s)  (SPEC.md, decision Units).
  const double s = 1.0 / std::sqrt(total_area_);
  const double ratio = beta.value / ((1.0 - beta.value) * s);
  return ratio / (1.0 + ratio);
}

std::size_t PreparedMesh::memory_bytes() const {
  return sizeof(*this) + static_cast<std::size_t>(mesh_.V.size()) * sizeof(double) +
         static_cast<std::size_t>(mesh_.F.size()) * sizeof(int) + sparse_bytes(L_) +
         unreferenced_.size() * sizeof(int) +
         static_cast<std::size_t>(grads_.size()) * sizeof(double) +
         static_cast<std::size_t>(areas_.size() + normals_.size()) * sizeof(double) +
         edges_.size() * sizeof(InteriorEdge) + component_.size() * sizeof(int) +
         vertex_triangles_.memory_bytes() +
         (order_ready_.load(std::memory_order_acquire) ? order_.size() * sizeof(int)
                                                        : edge_graph_bytes_) +
         (wide_order_ready_.load(std::memory_order_acquire) ? wide_order_.size() * sizeof(int)
                                                             : 0);
}

// ---------------------------------------------------------------------------------------
struct BetaSystem : FactorBudget::Item {
  std::shared_ptr<const Factorization> factor;
  SparseMatrix K_FF;  // full symmetric: the drag path's residual (K_FFᵀ x = K_FF x, row-wise)
  SparseMatrix K_FC;
  SparseMatrixR GtW_F;
  std::size_t memory_bytes() const {
    return factor->memory_bytes() + sparse_bytes(K_FF) + sparse_bytes(K_FC) + sparse_bytes(GtW_F);
  }
};

struct ConstraintSet::WideBlocks {
  // K_β = (1−β)·area + β·reg, FF and FC, on area's structure (split_union gives both parts
  // one structure, so reg keeps only its values: one index structure fewer, ≈ 50 MB at 1M).
  // area.GtW_F is left empty, see build_system_locked.
  Blocks area;
  std::vector<double> reg_FF, reg_FC;
};

ConstraintSet::ConstraintSet(std::shared_ptr<const PreparedMesh> mesh, Constraints constraints)
    : mesh_(std::move(mesh)), constraints_(std::move(constraints)) {
  const auto open_start = std::chrono::steady_clock::now();
  const int n = mesh_->n();
  const int k = num_handles();
  if (k == 0) throw InvalidInput("constraints: at least one handle region is required");
  if (k == 1 && constraints_.fixed.empty())
    throw InvalidInput(
        "constraints: a single handle needs a fixed region (the harmonic field is undefined)");

  region_of_.assign(static_cast<std::size_t>(n), -1);
  auto claim = [&](const std::vector<int>& ids, int region, const std::string& what) {
    if (ids.empty()) throw InvalidInput("constraints: " + what + " is empty");
    for (int v : ids) {
      if (v < 0 || v >= n)
        throw InvalidInput("constraints: " + what + " has vertex id " + std::to_string(v) +
                           " out of range [0, " + std::to_string(n) + ")");
      if (region_of_[v] == region) continue;  // duplicate within one region: harmless
      if (region_of_[v] != -1) {
        const std::string other = region_of_[v] == 0
                                      ? "the fixed region"
                                      : "handle " + std::to_string(region_of_[v] - 1);
        throw InvalidInput("constraints: " + what + " overlaps " + other + " at vertex " +
                           std::to_string(v));
      }
      region_of_[v] = region;
    }
  };
  if (!constraints_.fixed.empty()) claim(constraints_.fixed, 0, "the fixed region");
  for (int j = 0; j < k; ++j)
    claim(constraints_.handles[j], j + 1, "handle " + std::to_string(j));  // 0-based, as the API
  for (int v : mesh_->unreferenced())
    if (region_of_[v] == -1) region_of_[v] = 0;  // pinned at rest, ids stay stable

  // Every component needs a constrained vertex, else K_FF is singular there.
  std::vector<char> anchored(static_cast<std::size_t>(mesh_->num_components()), 0);
  for (int v = 0; v < n; ++v)
    if (region_of_[v] >= 0) anchored[mesh_->component()[v]] = 1;
  for (int c = 0; c < mesh_->num_components(); ++c)
    if (!anchored[c]) {
      int first = 0, size = 0;
      for (int v = n - 1; v >= 0; --v)
        if (mesh_->component()[v] == c) first = v, ++size;
      throw InvalidInput("constraints: mesh component " + std::to_string(c) + " (" +
                         std::to_string(size) + " vertices, first vertex " +
                         std::to_string(first) +
                         ") has no constrained vertex; the system is singular there");
    }

  block_index_.assign(static_cast<std::size_t>(n), -1);
  for (int v = 0; v < n; ++v) {
    auto& block = region_of_[v] < 0 ? free_ : constrained_;
    block_index_[v] = static_cast<int>(block.size());
    block.push_back(v);
  }

  rest_diagonal_ =
      (mesh_->mesh().V.colwise().maxCoeff() - mesh_->mesh().V.colwise().minCoeff()).norm();
  centroids_.resize(static_cast<std::size_t>(k));
  for (int j = 0; j < k; ++j) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int v : constraints_.handles[j]) c += mesh_->mesh().V.row(v).transpose();
    centroids_[j] = c / static_cast<double>(constraints_.handles[j].size());
  }

  open_timings_.checks_ms = elapsed_ms(open_start);

  // β = 0 is always needed: its factorization of L_FF also yields the harmonic basis.
  const auto sys0 = system(0.0);
  open_timings_.system = last_build_timings();
  const auto basis_start = std::chrono::steady_clock::now();
  basis_ = hdeform::harmonic_basis(mesh_->L(), *sys0->factor, free_, constrained_, block_index_,
                          region_of_, k);
  open_timings_.basis_ms = elapsed_ms(basis_start);
}

ConstraintSet::~ConstraintSet() = default;

Eigen::Vector3d ConstraintSet::centroid(int handle) const { return centroids_.at(handle); }

std::shared_ptr<const BetaSystem> ConstraintSet::system(double raw_beta) const {
  auto hit = [&]() -> std::shared_ptr<const BetaSystem> {
    std::lock_guard lock(mutex_);
    if (auto it = by_beta_.find(raw_beta); it != by_beta_.end()) {
      FactorBudget::touch(*it->second);
      return it->second;
    }
    return nullptr;
  };
  if (auto sys = hit()) return sys;
  std::shared_ptr<const BetaSystem> sys;
  {
    std::lock_guard build(build_mutex_);
    if (auto again = hit()) return again;  // another thread built it meanwhile
    sys = build_system_locked(raw_beta);
    std::lock_guard lock(mutex_);
    by_beta_[raw_beta] = sys;
  }
  charge(sys, /*pinned=*/raw_beta == 0.0);
  return sys;
}

void ConstraintSet::charge(const std::shared_ptr<const BetaSystem>& sys, bool pinned) const {
  std::shared_ptr<FactorBudget> budget;
  {
    std::lock_guard lock(mutex_);
    budget = budget_;
  }
  if (budget) budget->charge(weak_from_this(), sys, sys->memory_bytes(), pinned);
}

void ConstraintSet::charge_to(std::shared_ptr<FactorBudget> budget) const {
  if (weak_from_this().expired())
    throw std::logic_error("ConstraintSet::charge_to: the set is not owned by a shared_ptr");
  std::vector<std::pair<std::shared_ptr<const BetaSystem>, bool>> systems;
  {
    std::lock_guard lock(mutex_);
    budget_ = std::move(budget);
    for (const auto& [b, sys] : by_beta_) systems.emplace_back(sys, b == 0.0);
    for (const auto& [key, fs] : by_field_) systems.emplace_back(fs.system, false);
  }
  for (const auto& [sys, pinned] : systems) charge(sys, pinned);
}

void ConstraintSet::evict(const FactorBudget::Item& item) const {
  std::shared_ptr<const BetaSystem> dropped;  // freed after the lock is released
  std::lock_guard lock(mutex_);
  for (auto it = by_beta_.begin(); it != by_beta_.end(); ++it)
    if (it->second.get() == &item && it->first != 0.0) {
      dropped = std::move(it->second);
      by_beta_.erase(it);
      return;
    }
  for (auto it = by_field_.begin(); it != by_field_.end(); ++it)
    if (it->second.system.get() == &item) {
      dropped = std::move(it->second.system);
      by_field_.erase(it);
      return;
    }
}

std::shared_ptr<const BetaSystem> ConstraintSet::build_system_locked(double raw_beta) const {
  using Clock = std::chrono::steady_clock;
  const auto nF = static_cast<Eigen::Index>(free_.size());
  const auto nC = static_cast<Eigen::Index>(constrained_.size());
  auto sys = std::make_shared<BetaSystem>();
  BuildTimings timings;
  if (raw_beta == 0.0) {
    // The Laplacian's own narrow pattern (SPEC: factoring β = 0 on the wide one is slower).
    // K_FF and K_FC first, on both cores; then the right-hand side's (GᵀA)_F on one core
    // beside what needs nothing of it: the order (METIS, paid by the mesh's first constraint
    // set), CHOLMOD's serial analysis and the two-thread factorization. At 1M vertices
    // (GᵀA)_F is ≈ 175 MB of fresh pages, the analysis ≈ 0.3 s of one core
    // (docs/benchmarks.md "The right-hand side beside the β = 0 factorization").
    const auto t0 = Clock::now();
    Blocks b = split(mesh_->L(), nullptr, BlockLayout{region_of_, block_index_, nF, nC});
    timings.blocks_ms = elapsed_ms(t0);
    run_beside(
        [&] {
          const std::vector<int> perm = free_order(/*wide=*/false, timings);
          // Its symbolic analysis is never reused (β > 0 has its own, wider pattern): not kept.
          sys->factor = factorize(b.FF, {.keep_analysis = false, .order = &perm});
        },
        [&] {
          const auto t1 = Clock::now();
          sys->GtW_F = free_rows_gta(mesh_->mesh().F, mesh_->gradients(), mesh_->areas(),
                                     mesh_->vertex_triangles(), free_);
          timings.rest_ms = elapsed_ms(t1);
        });
    sys->K_FF = std::move(b.FF);
    sys->K_FC = std::move(b.FC);
  } else {
    auto t0 = Clock::now();
    if (!wide_) {
      // Reg lives only while the wide blocks and the mesh's wide order are built: gone
      // before the factorization, whose peak is the 1M memory target's.
      const SparseMatrix Reg = mesh_->Reg();
      // Same structure for both parts: each is the other plus explicit zeros.
      auto w = std::make_shared<WideBlocks>();
      {
        Blocks reg;
        split_union(mesh_->L(), Reg, nullptr, nullptr,
                    BlockLayout{region_of_, block_index_, nF, nC}, w->area, reg);
        w->reg_FF.assign(reg.FF.valuePtr(), reg.FF.valuePtr() + reg.FF.nonZeros());
        w->reg_FC.assign(reg.FC.valuePtr(), reg.FC.valuePtr() + reg.FC.nonZeros());
      }
      {
        std::lock_guard lock(mutex_);  // memory_bytes() reads wide_ under mutex_ alone
        wide_ = std::move(w);
      }
      double order_ms = 0;
      mesh_->wide_order(&order_ms, &Reg);  // the mesh's first β > 0 pays METIS here
      timings.ordering_ms = order_ms;
    }
    timings.blocks_ms = elapsed_ms(t0) - timings.ordering_ms;
    t0 = Clock::now();
    sys->K_FF = combine(1.0 - raw_beta, wide_->area.FF, raw_beta, wide_->reg_FF);
    timings.K_FF_ms = elapsed_ms(t0);
    // The factorization (two threads) and the right-hand side's blocks need nothing from each
    // other: the blocks are built on the other core meanwhile.
    run_beside([&] { sys->factor = factor_wide(sys->K_FF, timings); },
               [&] {
                 const auto t1 = Clock::now();
                 sys->K_FC = combine(1.0 - raw_beta, wide_->area.FC, raw_beta, wide_->reg_FC);
                 // (GᵀW_β)_F straight from the gradients for this β: its two parts are not
                 // kept (they would be 2 × 0.45 GB at 1M) and no n × 3m Gᵀ A or
                 // Gᵀ D₃ᵀ B₃ D₃ is formed.
                 const PreparedMesh& pm = *mesh_;
                 sys->GtW_F = assemble_wide_free_rows(pm.mesh().F, pm.gradients(), pm.areas(),
                                                      pm.edges(), pm.vertex_triangles(), free_,
                                                      1.0 - raw_beta, raw_beta);
                 timings.rest_ms = elapsed_ms(t1);
               });
  }
  const Factorization::Timings& f = sys->factor->timings();
  timings.analysis_ms = f.analysis_ms;
  timings.factor_ms = f.factor_ms;
  timings.schedule_ms = f.schedule_ms;
  std::lock_guard lock(mutex_);
  last_build_ = timings;
  return sys;
}

ConstraintSet::BuildTimings ConstraintSet::last_build_timings() const {
  std::lock_guard lock(mutex_);
  return last_build_;
}

std::vector<int> ConstraintSet::free_order(bool wide, BuildTimings& timings) const {
  const auto t0 = std::chrono::steady_clock::now();
  double order_ms = 0;
  const auto& order = wide ? mesh_->wide_order(&order_ms) : mesh_->order(&order_ms);
  auto perm = restrict_order(order, free_);
  timings.ordering_ms += order_ms;  // build_system_locked may have paid it already
  timings.restrict_ms = elapsed_ms(t0) - order_ms;
  return perm;
}

std::shared_ptr<const Factorization> ConstraintSet::factor_wide(const SparseMatrix& K_FF,
                                                               BuildTimings& timings) const {
  if (!wide_symbolic_) {
    const auto perm = free_order(/*wide=*/true, timings);
    auto first = factorize(K_FF, {.keep_analysis = true, .order = &perm});
    std::lock_guard lock(mutex_);
    wide_symbolic_ = first;
    return first;
  }
  return wide_symbolic_->refactor(K_FF);
}

std::shared_ptr<const BetaSystem> ConstraintSet::local_system(const LocalBeta& field) const {
  const PreparedMesh& pm = *mesh_;
  if (field.beta.size() != pm.m())
    throw InvalidInput("local beta: expected " + std::to_string(pm.m()) +
                       " per-triangle values, got " + std::to_string(field.beta.size()));
  for (Eigen::Index l = 0; l < field.beta.size(); ++l)
    if (!std::isfinite(field.beta[l]) || field.beta[l] < 0 || field.beta[l] >= 1)
      throw InvalidInput("local beta of triangle " + std::to_string(l) +
                         " must be in [0, 1), got " + std::to_string(field.beta[l]));
  // FNV-1a over the field's bytes and units: a bucket key only; hits are verified.
  std::uint64_t key = 1469598103934665603ull ^ static_cast<std::uint64_t>(field.units);
  const auto* bytes = reinterpret_cast<const unsigned char*>(field.beta.data());
  for (std::size_t i = 0; i < static_cast<std::size_t>(field.beta.size()) * sizeof(double); ++i)
    key = (key ^ bytes[i]) * 1099511628211ull;
  auto find = [&]() -> std::shared_ptr<const BetaSystem> {
    const auto [lo, hi] = by_field_.equal_range(key);
    for (auto it = lo; it != hi; ++it)
      if (it->second.units == field.units && it->second.beta == field.beta) {
        FactorBudget::touch(*it->second.system);
        return it->second.system;
      }
    return nullptr;
  };
  {
    std::lock_guard lock(mutex_);
    if (auto hit = find()) return hit;
  }
  auto sys = build_field_system(field, key, find);
  if (sys.second) charge(sys.first, /*pinned=*/false);
  return sys.first;
}

// local_system's build: {the system, whether it was built here (not found meanwhile)}.
template <class Find>
std::pair<std::shared_ptr<const BetaSystem>, bool> ConstraintSet::build_field_system(
    const LocalBeta& field, std::uint64_t key, const Find& find) const {
  const PreparedMesh& pm = *mesh_;
  std::lock_guard build(build_mutex_);
  {
    std::lock_guard lock(mutex_);  // another thread may have built it meanwhile
    if (auto hit = find()) return {hit, false};
  }

  // Area units: the unit-area problem is the raw one with edge weights β_e / s.
  const double edge_scale = field.units == BetaUnits::area ? std::sqrt(pm.total_area()) : 1.0;
  const Eigen::Index m = pm.m();
  const auto E = static_cast<Eigen::Index>(pm.edges().size());
  Eigen::VectorXd wA(3 * m), wB(3 * E);
  for (Eigen::Index l = 0; l < m; ++l) wA.segment<3>(3 * l).setConstant(1.0 - field.beta[l]);
  for (Eigen::Index e = 0; e < E; ++e) {
    const InteriorEdge& edge = pm.edges()[e];
    wB.segment<3>(3 * e).setConstant(
        0.5 * (field.beta[edge.tri[0]] + field.beta[edge.tri[1]]) * edge_scale);
  }
  const SparseMatrix G = pm.G();
  const SparseMatrix J = gradient_jumps(G, pm.edges());
  const SparseMatrix GtW_reg =
      SparseMatrix(J.transpose()) * (wB.asDiagonal() * weighted_differences(pm.edges(), m));
  const SparseMatrix GtW = pm.GtA() * wA.asDiagonal() + GtW_reg;
  // Onto the β > 0 pattern (explicit zeros kept), so the shared analysis applies.
  const SparseMatrix K = (GtW * G) + 0.0 * (pm.L() + pm.Reg());
  const auto nF = static_cast<Eigen::Index>(free_.size());
  const auto nC = static_cast<Eigen::Index>(constrained_.size());
  Blocks b = split(K, &GtW, BlockLayout{region_of_, block_index_, nF, nC});
  auto sys = std::make_shared<BetaSystem>();
  BuildTimings timings;  // a field's build is not reported (last_build_timings is per β)
  sys->factor = factor_wide(b.FF, timings);
  sys->K_FF = std::move(b.FF);
  sys->K_FC = std::move(b.FC);
  sys->GtW_F = std::move(b.GtW_F);
  std::lock_guard lock(mutex_);
  // Bounded: a client sending ever new fields (a sweep, a slider on a local entry) would
  // otherwise grow this shared set by one factorization per field.
  while (by_field_.size() >= kMaxCachedFields) {
    auto oldest = by_field_.begin();
    for (auto it = by_field_.begin(); it != by_field_.end(); ++it)
      if (it->second.serial < oldest->second.serial) oldest = it;
    by_field_.erase(oldest);
  }
  by_field_.emplace(key, FieldSystem{field.beta, field.units, sys, field_serial_++});
  return {sys, true};
}

void ConstraintSet::prepare(Beta beta) const { system(mesh_->raw_beta(beta)); }

void ConstraintSet::guidance(std::span<const HandleTransform> transforms, GuidanceField& g,
                             Vertices* Rn, GuidanceScratch& scratch) const {
  guidance_field(mesh_->mesh().F, mesh_->normals(), basis_, transforms, g, Rn, scratch);
}

void ConstraintSet::check(std::span<const HandleTransform> transforms) const {
  if (static_cast<int>(transforms.size()) != num_handles())
    throw InvalidInput("expected " + std::to_string(num_handles()) +
                       " handle transform(s), got " + std::to_string(transforms.size()));
  for (const HandleTransform& t : transforms) t.validate();
}

Frame ConstraintSet::update(std::span<const HandleTransform> transforms, Beta beta,
                            const UpdateOptions& options) const {
  check(transforms);
  return solve(system(mesh_->raw_beta(beta)), transforms, options);
}

void ConstraintSet::update(std::span<const HandleTransform> transforms, Beta beta,
                           const UpdateOptions& options, UpdateWorkspace& ws, Frame& out) const {
  check(transforms);
  solve(system(mesh_->raw_beta(beta)), transforms, options, ws, out);
}

Frame ConstraintSet::update_transient(std::span<const HandleTransform> transforms, Beta beta,
                                      const UpdateOptions& options) const {
  check(transforms);
  const double raw = mesh_->raw_beta(beta);
  std::shared_ptr<const BetaSystem> sys;
  {
    std::lock_guard lock(mutex_);
    if (auto it = by_beta_.find(raw); it != by_beta_.end()) sys = it->second;
  }
  if (!sys) {
    {
      std::lock_guard build(build_mutex_);
      sys = build_system_locked(raw);
    }
    charge(sys, /*pinned=*/true);  // counted while this call holds it
  }
  return solve(sys, transforms, options);  // a transient sys is freed on return
}

Frame ConstraintSet::update_local(std::span<const HandleTransform> transforms,
                                  const LocalBeta& beta, const UpdateOptions& options) const {
  check(transforms);
  return solve(local_system(beta), transforms, options);
}

void ConstraintSet::update_local(std::span<const HandleTransform> transforms,
                                 const LocalBeta& beta, const UpdateOptions& options,
                                 UpdateWorkspace& ws, Frame& out) const {
  check(transforms);
  solve(local_system(beta), transforms, options, ws, out);
}

Frame ConstraintSet::solve(const std::shared_ptr<const BetaSystem>& sys,
                           std::span<const HandleTransform> transforms,
                           const UpdateOptions& options) const {
  UpdateWorkspace ws;
  Frame frame;
  solve(sys, transforms, options, ws, frame);
  return frame;
}

namespace {

// X = K_FF⁻¹ B (n×3, column-major, ld = n) at the given precision.
void solve3(const Factorization& factor, const Eigen::MatrixXd& B, Eigen::MatrixXd& X,
            SolvePrecision precision) {
  X.resize(B.rows(), 3);  // a no-op once sized: the solve itself allocates nothing
  factor.solve3(B.data(), X.data(), precision);
}

}  // namespace

void ConstraintSet::solve(const std::shared_ptr<const BetaSystem>& system,
                          std::span<const HandleTransform> transforms,
                          const UpdateOptions& options, UpdateWorkspace& ws, Frame& out) const {
  const BetaSystem& sys = *system;
  const bool with_measures = options.measures || options.energies;
  guidance(transforms, ws.g, with_measures ? &ws.Rn : nullptr, ws.guidance_scratch);

  const Vertices& X = mesh_->mesh().V;
  const auto nF = static_cast<Eigen::Index>(free_.size());
  const auto nC = static_cast<Eigen::Index>(constrained_.size());
  ws.x_C.resize(nC, 3);
  // Targets x'_v = p + M (x_v − p) + t (SPEC §Constraints), M and p once per handle: the
  // same arithmetic as HandleTransform::apply.
  std::vector<Eigen::Matrix3d>& M = ws.handle_M;  // reused: the move allocates nothing
  std::vector<Eigen::Vector3d>& p = ws.handle_p;
  M.resize(transforms.size());
  p.resize(transforms.size());
  for (std::size_t j = 0; j < transforms.size(); ++j) {
    M[j] = transforms[j].linear();
    p[j] = transforms[j].pivot.value_or(centroids_[j]);
  }
  for_chunks(nC, [&](Eigen::Index i0, Eigen::Index i1, int) {
    for (Eigen::Index i = i0; i < i1; ++i) {
      const int v = constrained_[i], j = region_of_[v] - 1;
      const Eigen::Vector3d x = X.row(v).transpose();
      if (j < 0)
        ws.x_C.row(i) = x.transpose();
      else
        ws.x_C.row(i) = (p[j] + M[j] * (x - p[j]) + transforms[j].translation).transpose();
    }
  });

  out.positions.resize(X.rows(), 3);
  out.solves = 0;
  if (nF > 0) {
    sparse_times3(sys.GtW_F, ws.g, ws.rhs);  // one pass, both cores (sparse_times3.h)
    ws.rhs.noalias() -= sys.K_FC * ws.x_C;    // K_FC: the few rows beside the regions
    if (options.precision == FramePrecision::exact) {
      solve3(*sys.factor, ws.rhs, ws.x_F, SolvePrecision::float64);
      out.solves = 1;
    } else {
      drag_solve(system, ws, out);
    }
    ws.warm = true;
    ws.warm_system = system;
  }
  // Scatter into vertex order and check the result in the same pass (both cores). NaN never
  // compares above the max: `ok` counts it apart.
  const MaxAbs reach = chunks_max_abs(nF + nC, [&](Eigen::Index i0, Eigen::Index i1) {
    MaxAbs r;
    for (Eigen::Index i = i0; i < i1; ++i) {
      const bool is_free = i < nF;
      const Eigen::Index k = is_free ? i : i - nF;
      const int v = is_free ? free_[k] : constrained_[k];
      const Eigen::MatrixXd& from = is_free ? ws.x_F : ws.x_C;
      for (int d = 0; d < 3; ++d) {
        const double x = from(k, d);
        out.positions(v, d) = x;
        r.ok = r.ok && std::isfinite(x);
        r.max = std::max(r.max, std::abs(x));
      }
    }
    return r;
  });
  if (!reach.ok || reach.max > kMaxCoordinate) {
    ws.warm = false;  // never start the next drag frame from a rejected solution
    throw_result_error(transforms);
  }
  out.exact = options.precision == FramePrecision::exact;
  out.has_measures = with_measures;
  if (out.has_measures) {
    // The measures' pass also leaves the normals' face weights: one pass over the triangles.
    out.measures = measure(*mesh_, out.positions, ws.g, ws.Rn,
                           options.energies ? &out.energies : nullptr,
                           options.normals ? &ws.face_w : nullptr);
  } else {
    out.measures = Measures{};
  }
  if (!options.energies) out.energies.resize(0);
  if (!options.normals)
    out.normals.resize(0, 3);
  else if (out.has_measures)
    vertex_normals_from_faces(mesh_->vertex_triangles(), ws.face_w, out.normals);
  else
    vertex_normals(out.positions, mesh_->mesh().F, mesh_->vertex_triangles(), ws.face_w, out.normals);
}

// Iterative refinement with the float32 factor M ≈ K_FF (SPEC §Drag frames). Each step
// x += M⁻¹(b − K_FF x), the residual in double, shrinks the error by the contraction
// δ ≈ ‖I − M⁻¹K_FF‖, so after a step of size s the error is ≈ δ·s. δ is measured as the ratio
// of two successive steps (kept per system in the workspace), and steps go on until
// kSafety·δ·s is below the tolerance. A drag frame starts from the previous solution of this
// system (warm: s is the frame-to-frame motion, so one step usually suffices) or from x = M⁻¹b.
void ConstraintSet::drag_solve(const std::shared_ptr<const BetaSystem>& system,
                               UpdateWorkspace& ws, Frame& out) const {
  const BetaSystem& sys = *system;
  const bool warm =
      ws.warm && ws.x_F.rows() == ws.rhs.rows() && ws.warm_system.lock() == system;
  constexpr int kMaxSteps = 4;
  constexpr double kMinContraction = 6e-8;  // float32's unit roundoff: δ is never below it
  // The max-norm step ratio underestimates δ for smooth, low-frequency moves (up to 7× on
  // the whole-deformation jumps of tests/engine/test_drag_path.cpp).
  constexpr double kSafety = 16;
  const double tol = kDragTolerance * rest_diagonal_;
  double delta = ws.contraction_system.lock() == system ? ws.contraction : -1;
  double previous = -1;  // size of the previous step (or of x after a cold start)
  out.solves = 0;
  if (!warm) {
    solve3(*sys.factor, ws.rhs, ws.x_F, SolvePrecision::float32);
    previous = ws.x_F.cwiseAbs().maxCoeff();
    out.solves = 1;
  }
  for (int k = 0; k < kMaxSteps; ++k) {
    symmetric_residual3(sys.K_FF, ws.x_F, ws.rhs, ws.residual);
    ws.correction.resize(ws.residual.rows(), 3);  // a no-op once sized
    sys.factor->solve3_rows(ws.residual.data(), ws.correction.data(), SolvePrecision::float32);
    const double step = add_and_measure(ws.correction, ws.x_F);
    ++out.solves;
    if (delta < 0 && previous > 0 && step > 0)
      delta = std::clamp(step / previous, kMinContraction, 1.0);
    if (delta >= 0 && kSafety * delta * step <= tol) break;
    if (step == 0) break;  // x is a fixed point of the refinement: nothing left to gain
    previous = step;
  }
  ws.contraction = delta;
  ws.contraction_system = system;
}

std::size_t UpdateWorkspace::memory_bytes() const {
  const auto doubles = g.size() + Rn.size() + x_C.size() + rhs.size() + x_F.size() +
                       residual.size() + correction.size() + face_w.size();
  return static_cast<std::size_t>(doubles) * sizeof(double) +
         guidance_scratch.turn.capacity() * sizeof(guidance_scratch.turn[0]);
}

void ConstraintSet::throw_result_error(std::span<const HandleTransform> transforms) const {
  // Name the handle whose transform moves its region farthest: the likely culprit.
  int worst = 0;
  double reach = -1;
  for (int j = 0; j < num_handles(); ++j) {
    const HandleTransform& t = transforms[static_cast<std::size_t>(j)];
    const double r = t.translation.cwiseAbs().maxCoeff() + t.stretch.cwiseAbs().maxCoeff();
    if (!(r <= reach)) worst = j, reach = r;  // NaN counts as the worst
  }
  const HandleTransform& t = transforms[static_cast<std::size_t>(worst)];
  throw InvalidInput(fmt_result_error(worst, t));
}

std::size_t ConstraintSet::base_bytes_locked() const {
  std::size_t bytes = sizeof(*this) + static_cast<std::size_t>(basis_.size()) * sizeof(double) +
                      (free_.size() + constrained_.size() + 2 * region_of_.size()) * sizeof(int);
  if (wide_)
    bytes += sparse_bytes(wide_->area.FF) + sparse_bytes(wide_->area.FC) +
             (wide_->reg_FF.size() + wide_->reg_FC.size()) * sizeof(double);
  return bytes;
}

std::size_t ConstraintSet::memory_bytes() const {
  std::lock_guard lock(mutex_);
  std::size_t bytes = base_bytes_locked();
  for (const auto& [b, sys] : by_beta_) bytes += sys->memory_bytes();
  for (const auto& [key, fs] : by_field_)
    bytes += fs.system->memory_bytes() + static_cast<std::size_t>(fs.beta.size()) * sizeof(double);
  return bytes;
}

std::size_t ConstraintSet::base_bytes() const {
  std::lock_guard lock(mutex_);
  return base_bytes_locked();
}

std::size_t ConstraintSet::num_cached_factorizations() const {
  std::lock_guard lock(mutex_);
  return by_beta_.size();
}

bool ConstraintSet::is_cached(Beta beta) const {
  const double raw = mesh_->raw_beta(beta);
  std::lock_guard lock(mutex_);
  return by_beta_.count(raw) > 0;
}

void ConstraintSet::drop_factorization(Beta beta) {
  const double raw = mesh_->raw_beta(beta);
  if (raw == 0.0) return;  // the harmonic basis' own factorization stays
  std::lock_guard lock(mutex_);
  by_beta_.erase(raw);
}

}  // namespace hdeform

// The engine's face (SPEC.md, all sections): an immutable PreparedMesh shared between
// sessions, a ConstraintSet that owns its factorizations, and a cheap update().
#pragma once

#include "engine/deform/factor_budget.h"
#include "engine/deform/guidance.h"
#include "engine/deform/measures.h"
#include "engine/mesh/mesh.h"
#include "engine/mesh/transform.h"
#include "engine/mesh/validate.h"
#include "engine/mesh/vertex_normals.h"
#include "engine/operators/operators.h"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

namespace hdeform {

// SPEC (decision) Units: `area` builds the operators on the mesh scaled to unit total
// area (scale-invariant β, the default); `raw` is the thesis's formula in model units.
enum class BetaUnits { area, raw };

struct Beta {
  double value = 0;  // 0 ≤ value < 1
  BetaUnits units = BetaUnits::area;
};

// When PreparedMesh::create computes order() (β = 0's nested dissection).
enum class PrepareOrder {
  // Beside the operators, on a thread of run_beside's budget, from validation's edge graph:
  // for a caller that factors next (the CLI, a restore without a stored order). At 1M
  // vertices METIS's first separator would otherwise hold one core while the other idles.
  with_operators,
  // On order()'s first call, or never if adopt_order() gives it: for a caller that may
  // have it stored, or whose user picks regions first (the service's open).
  on_first_use,
};

// Rest-pose operators of one mesh. Immutable after create(): share it freely.
class PreparedMesh {
 public:
  // Validates the mesh (throws InvalidInput naming the problem) and builds the per-triangle
  // gradients, areas and normals, the interior edges, L and the regularizer, straight into
  // compressed storage on all OpenMP threads (operator_assembly.h), and β = 0's order when
  // asked. Cost O(m), plus METIS's with the order.
  static std::shared_ptr<const PreparedMesh> create(
      TriMesh mesh, PrepareOrder order = PrepareOrder::with_operators);

  const TriMesh& mesh() const { return mesh_; }
  int n() const { return mesh_.num_vertices(); }
  int m() const { return mesh_.num_triangles(); }
  // G, Gᵀ A and Gᵀ D₃ᵀ B₃ D₃ are not stored (the engine needs them only to build a local β
  // field's system or the first β > 0 blocks): each call assembles it from the per-triangle
  // gradients, O(m), in parallel. The same bits as the stored copies had.
  SparseMatrix G() const;                                         // 3m × n
  const TriangleGradients& gradients() const { return grads_; }  // G's blocks, per triangle
  const Eigen::VectorXd& areas() const { return areas_; }        // a_l (units²)
  const Vertices& normals() const { return normals_; }           // n_l at rest
  const std::vector<InteriorEdge>& edges() const { return edges_; }
  const VertexTriangles& vertex_triangles() const { return vertex_triangles_; }
  const SparseMatrix& L() const { return L_; }                   // Gᵀ A G
  // Gᵀ D₃ᵀ B₃ D₃ G, assembled on each call (O(m), all OpenMP threads; the same bits every
  // time). Not kept: only a constraint set's first β > 0 (its wide blocks) and a local β
  // field need it, and at 1M it would hold ≈ 0.23 GB for as long as the mesh lives.
  SparseMatrix Reg() const;
  // Nested dissection of the edge graph (β = 0: L's pattern, with the edges whose cotangent
  // weights cancel, which L leaves out) and of L ∪ Reg's (β > 0), each computed on
  // its first call (thread-safe; METIS, on two threads from kSplitOrderFrom vertices) and
  // kept: every constraint set on this mesh orders its K_FF by it (vertex_ordering.h). ms:
  // the time the call spent computing it (0 when it was already there). reg: Reg() if the
  // caller has it at hand (else wide_order assembles it when it needs it).
  const std::vector<int>& order(double* ms = nullptr) const;
  const std::vector<int>& wide_order(double* ms = nullptr, const SparseMatrix* reg = nullptr) const;
  // Whether order() / wide_order() is there (its next call returns at once).
  bool has_order() const { return order_ready_.load(std::memory_order_acquire); }
  bool has_wide_order() const { return wide_order_ready_.load(std::memory_order_acquire); }
  // An order computed before for this mesh (kept by the service with the mesh), taken
  // instead of a METIS call: true when taken; false when that order is already there or
  // `order` is not a permutation of 0..n−1 (the next call then computes it). Any permutation
  // orders the solve correctly (only the fill depends on it), and the same order gives the
  // same factor bits as the call that computed it.
  bool adopt_order(std::vector<int> order, bool wide) const;
  SparseMatrix GtA() const;                                      // Gᵀ A (n × 3m)
  SparseMatrix GtDBD() const;                                    // Gᵀ D₃ᵀ B₃ D₃ (n × 3m)
  double total_area() const { return total_area_; }
  // Vertices no triangle uses: kept (ids stay stable) and pinned at rest.
  const std::vector<int>& unreferenced() const { return unreferenced_; }
  // Connected component of each vertex (triangle adjacency), and their count.
  const std::vector<int>& component() const { return component_; }
  int num_components() const { return num_components_; }

  // The thesis's (raw) β′ for β in the given units: β′/(1−β′) = β/((1−β)·s), with s the
  // factor that scales the mesh to unit area. Throws InvalidInput unless 0 ≤ β < 1.
  double raw_beta(Beta beta) const;
  std::size_t memory_bytes() const;
  // Where create() spent its time (ms, wall; docs/benchmarks.md "Session open and memory"):
  // validation, per-triangle geometry (areas, normals, gradients), the vertex→triangle
  // table and interior edges, L, the connected components; and Reg's last build (0 until
  // the first Reg() call, which is not part of create()). order_ms: the order computed beside
  // those four (PrepareOrder::with_operators; else 0), its own time on its thread, and
  // beside_ms the four and the order together (0 without it).
  struct BuildTimings {
    double validate_ms = 0, geometry_ms = 0, edges_ms = 0, laplacian_ms = 0,
           regularizer_ms = 0, components_ms = 0, order_ms = 0, beside_ms = 0;
  };
  BuildTimings build_timings() const;

 private:
  PreparedMesh() = default;
  BuildTimings timings_;
  TriMesh mesh_;
  SparseMatrix L_;
  mutable std::atomic<double> reg_ms_{0};  // the last Reg() call's time
  mutable std::once_flag order_once_, wide_order_once_;
  mutable std::vector<int> order_, wide_order_;  // written once, under their once_flag
  mutable std::atomic<bool> order_ready_{false}, wide_order_ready_{false};
  // Validation's edge graph, what order() orders; freed (under order_once_) once the
  // order is there, computed or adopted. Its bytes are counted until then.
  mutable EdgePattern edge_graph_;
  std::size_t edge_graph_bytes_ = 0;
  template <class Compute>
  const std::vector<int>& lazy_order(std::once_flag& once, std::vector<int>& order,
                                     std::atomic<bool>& ready, Compute compute,
                                     double* ms) const;
  TriangleGradients grads_;
  Eigen::VectorXd areas_;
  Vertices normals_;
  std::vector<InteriorEdge> edges_;
  VertexTriangles vertex_triangles_;
  double total_area_ = 0;
  std::vector<int> unreferenced_;
  std::vector<int> component_;
  int num_components_ = 0;
};

// Fixed set F₀ and handle regions H₁..H_k by vertex id (SPEC.md §Constraints).
struct Constraints {
  std::vector<int> fixed;
  std::vector<std::vector<int>> handles;
};

// Local regularization (beyond the thesis, its "future work"): a β per triangle,
// W = diag(1 − β_l) A + D₃ᵀ diag(β_e) B₃ D₃ with β_e the mean of the edge's two triangles.
// In `area` units each β_l means what a uniform β means (SPEC decision Units).
struct LocalBeta {
  Eigen::VectorXd beta;  // one per triangle, each in [0, 1)
  BetaUnits units = BetaUnits::area;
};

// How the K_FF solve of a frame is done (SPEC.md §Drag frames).
//   exact:  the double solve (every result that is kept or reported: CLI, Sweep, GetMesh,
//           the frame that ends a drag).
//   drag:   factor values read as float32 (half the bytes) with accumulation in double,
//           corrected by iterative refinement with K_FF in double; the positions stay within
//           kDragTolerance × bbox diagonal of the exact solve (tests/engine/test_drag_path).
enum class FramePrecision { exact, drag };

// The drag path's bound on max_i ‖x_i − x_i^exact‖∞, as a fraction of the rest bbox diagonal.
inline constexpr double kDragTolerance = 1e-6;

struct UpdateOptions {
  bool energies = true;  // fill Frame::energies (implies the measures' pass)
  bool normals = true;   // fill Frame::normals
  bool measures = true;  // fill Frame::measures (a pass over the triangles)
  FramePrecision precision = FramePrecision::exact;
};

struct Frame {
  Vertices positions;        // X' (n×3), model units
  Vertices normals;          // area-weighted vertex normals of X' (unit), if requested
  Eigen::VectorXf energies;  // per-triangle ‖r_l‖²_F (e_f²), if requested
  Measures measures;         // valid when has_measures
  bool has_measures = false;
  bool exact = true;  // false: a drag-path frame (FramePrecision::drag)
  int solves = 0;     // K_FF solves the frame took (drag: 1 per refinement step, + 1 cold)
};

struct BetaSystem;  // deformer.cpp: K_FF factorization, K_FC, (Gᵀ W_β)_F for one β

// The buffers of one caller's moves (a session or a worker owns one; not thread-safe):
// update() reuses them, so once their sizes are reached a move allocates no memory and
// touches no fresh page. Also remembers the last drag solution, the
// warm start of the next drag frame on the same system.
class UpdateWorkspace {
 public:
  std::size_t memory_bytes() const;

 private:
  friend class ConstraintSet;
  GuidanceField g;
  Vertices Rn;  // R_l n_l per triangle: filled only for frames with measures
  GuidanceScratch guidance_scratch;
  std::vector<Eigen::Matrix3d> handle_M;  // per handle: M_j = R_j S_j and the pivot p_j
  std::vector<Eigen::Vector3d> handle_p;
  Eigen::MatrixXd x_C, rhs, x_F;
  Rows3 residual, correction;  // the drag refinement's, row-major (Factorization::solve3_rows)
  Vertices face_w;  // per-triangle normal weights (vertex_normals' scratch)
  std::weak_ptr<const BetaSystem> warm_system;  // x_F solves this system (drag path)
  bool warm = false;
  std::weak_ptr<const BetaSystem> contraction_system;  // the drag refinement's measured δ
  double contraction = -1;
};

class Factorization;  // solver.h

// Results are checked against this bound (model units): beyond it float32 outputs (frames,
// GLB) overflow and the measures' squares are no longer finite.
inline constexpr double kMaxCoordinate = 1e30;

// One constraint set on one mesh: validates it, solves the harmonic basis fields once,
// and caches the factorization of K_FF per β. Thread-safe: update() may be called
// concurrently (factorizations are built once under a lock). Charged to a FactorBudget
// (charge_to), its cached systems are evicted least recently used and rebuilt on demand.
class ConstraintSet final : public std::enable_shared_from_this<ConstraintSet>,
                            public FactorBudget::Owner {
 public:
  // Throws InvalidInput: ids out of range, overlapping or empty regions, a single handle
  // with no fixed vertex, a component without a constrained vertex.
  ConstraintSet(std::shared_ptr<const PreparedMesh> mesh, Constraints constraints);
  ~ConstraintSet();

  const PreparedMesh& mesh() const { return *mesh_; }
  const Constraints& constraints() const { return constraints_; }
  int num_handles() const { return static_cast<int>(constraints_.handles.size()); }
  // Centroid of H_j at rest: the default pivot.
  Eigen::Vector3d centroid(int handle) const;
  // Φ (n × k): Φ_j = 1 on H_j, 0 on the other constrained vertices, harmonic elsewhere.
  const Eigen::MatrixXd& harmonic_basis() const { return basis_; }

  // Builds (or finds) the factorization for β so a later update() is only a solve.
  // Logically const: it only fills the factorization cache (thread-safe).
  void prepare(Beta beta) const;
  // Deformed mesh for one transform per handle. Cost: guidance O(m), one sparse
  // product, one triangular-solve pair (plus a numeric factorization on a new β).
  // Throws InvalidInput for a wrong transform count, an invalid transform, or transforms
  // whose result leaves the representable range (non-finite or beyond ±kMaxCoordinate:
  // the message names the handle).
  Frame update(std::span<const HandleTransform> transforms, Beta beta,
               const UpdateOptions& options = {}) const;
  // The same into `out` with `ws`'s buffers: with both reused from the previous move of the
  // same set, nothing is allocated. On a throw `out` holds no valid frame.
  void update(std::span<const HandleTransform> transforms, Beta beta,
              const UpdateOptions& options, UpdateWorkspace& ws, Frame& out) const;

  // update() for a one-off β (sweeps, automatic β): a factorization that is not cached
  // already is built for this call only and freed when it returns, so callers never grow
  // (or drop from) the cache that other sessions share. Peak memory: one factorization.
  Frame update_transient(std::span<const HandleTransform> transforms, Beta beta,
                         const UpdateOptions& options = {}) const;

  // The same with a per-triangle β field (one factorization per distinct field, cached;
  // at most kMaxCachedFields fields are kept, the oldest dropped first).
  Frame update_local(std::span<const HandleTransform> transforms, const LocalBeta& beta,
                     const UpdateOptions& options = {}) const;
  void update_local(std::span<const HandleTransform> transforms, const LocalBeta& beta,
                    const UpdateOptions& options, UpdateWorkspace& ws, Frame& out) const;
  static constexpr std::size_t kMaxCachedFields = 4;

  // Guidance per triangle (SPEC §Harmonic guidance field): g (3m×3) and R_l n_l (m×3).
  // `Rn` may be null (only the measures read it); `scratch` is reused across calls.
  void guidance(std::span<const HandleTransform> transforms, GuidanceField& g, Vertices* Rn,
                GuidanceScratch& scratch) const;

  // Charges every cached system to `budget` (β = 0 pinned: the harmonic basis came from
  // it), and every later one as it is built. The set must be owned by a shared_ptr.
  void charge_to(std::shared_ptr<FactorBudget> budget) const;
  // FactorBudget::Owner: drops a cached per-β or per-field system (never β = 0).
  void evict(const FactorBudget::Item& item) const override;

  std::size_t memory_bytes() const;
  // memory_bytes() without the cached per-β and per-field systems (what a FactorBudget
  // charges): the basis, indices and the β > 0 blocks.
  std::size_t base_bytes() const;
  std::size_t num_cached_factorizations() const;
  // Whether β's system is cached now (not evicted, not yet built).
  bool is_cached(Beta beta) const;
  // Drops a cached β factorization (β = 0 stays: the harmonic basis came from it). Only
  // for benchmarks and tests: a shared set's other users would have to rebuild it.
  void drop_factorization(Beta beta);
  // Where the last system build went (ms, wall; docs/benchmarks.md "β change"): the blocks
  // (β = 0: K_FF and K_FC; β > 0: the wide ones, first β > 0 only), K_FF's values for β, the
  // mesh's nested dissection (0 unless this build computed it: once per mesh and pattern)
  // and its restriction to F, the factorization (symbolic analysis, numeric, schedule), and
  // rest_ms: what was built beside the factorization (β = 0: (GᵀA)_F; β > 0: K_FC and
  // (Gᵀ W_β)_F).
  struct BuildTimings {
    double blocks_ms = 0, K_FF_ms = 0, ordering_ms = 0, restrict_ms = 0, analysis_ms = 0,
           factor_ms = 0, schedule_ms = 0, rest_ms = 0;
  };
  BuildTimings last_build_timings() const;
  // Where the constructor spent its time (ms, wall): the constraint checks and block
  // indices, the β = 0 system (its BuildTimings), the harmonic basis.
  struct OpenTimings {
    double checks_ms = 0, basis_ms = 0;
    BuildTimings system;
  };
  const OpenTimings& open_timings() const { return open_timings_; }

 private:
  std::size_t base_bytes_locked() const;  // base_bytes under mutex_
  OpenTimings open_timings_;
  std::shared_ptr<const BetaSystem> system(double raw_beta) const;
  // Builds the system for raw β; build_mutex_ must be held (it guards wide_ and
  // wide_symbolic_, which this may create).
  std::shared_ptr<const BetaSystem> build_system_locked(double raw_beta) const;
  std::shared_ptr<const BetaSystem> local_system(const LocalBeta& beta) const;
  template <class Find>
  std::pair<std::shared_ptr<const BetaSystem>, bool> build_field_system(
      const LocalBeta& field, std::uint64_t key, const Find& find) const;
  // The mesh's order (wide: β > 0's) restricted to F; its two times go into timings.
  std::vector<int> free_order(bool wide, BuildTimings& timings) const;
  // Numeric factorization of a K_FF on the β > 0 pattern, sharing its symbolic analysis.
  // (The first one orders K_FF by the mesh's wide_order and records that in timings.)
  std::shared_ptr<const Factorization> factor_wide(const SparseMatrix& K_FF,
                                                   BuildTimings& timings) const;
  void check(std::span<const HandleTransform> transforms) const;  // count, validity
  // Throws InvalidInput naming the handle that likely made a result non-finite or beyond
  // kMaxCoordinate.
  [[noreturn]] void throw_result_error(std::span<const HandleTransform> transforms) const;
  void solve(const std::shared_ptr<const BetaSystem>& sys,
             std::span<const HandleTransform> transforms, const UpdateOptions& options,
             UpdateWorkspace& ws, Frame& out) const;
  // x_F = K_FF⁻¹ ws.rhs into ws.x_F on the drag path (float32 factor + refinement).
  void drag_solve(const std::shared_ptr<const BetaSystem>& sys, UpdateWorkspace& ws,
                  Frame& out) const;
  Frame solve(const std::shared_ptr<const BetaSystem>& sys,
              std::span<const HandleTransform> transforms, const UpdateOptions& options) const;
  struct WideBlocks;  // the β > 0 pattern, split into its (1 − β) and β parts

  std::shared_ptr<const PreparedMesh> mesh_;
  Constraints constraints_;
  std::vector<int> free_, constrained_;  // vertex ids of F and C, ascending
  std::vector<int> block_index_;         // position of each vertex within F or C
  std::vector<int> region_of_;           // −1 free, 0 fixed (F₀ or unreferenced), j+1 handle j
  Eigen::MatrixXd basis_;
  std::vector<Eigen::Vector3d> centroids_;
  double rest_diagonal_ = 0;  // bbox diagonal at rest: the drag tolerance's unit
  // Lock order: build_mutex_, then mutex_. wide_ and wide_symbolic_ are written with both
  // held, so holding either one is enough to read them.
  mutable std::mutex mutex_;
  mutable std::mutex build_mutex_;  // one factorization at a time; lookups stay cheap
  mutable std::map<double, std::shared_ptr<const BetaSystem>> by_beta_;
  // Local β fields by hash, each kept with its field: a hit is verified value by value,
  // so a colliding field (the set is shared between sessions) never gets another's system.
  struct FieldSystem {
    Eigen::VectorXd beta;
    BetaUnits units;
    std::shared_ptr<const BetaSystem> system;
    std::uint64_t serial;
  };
  mutable std::multimap<std::uint64_t, FieldSystem> by_field_;
  mutable std::uint64_t field_serial_ = 0;  // insertion order, to drop the oldest field
  mutable std::shared_ptr<const WideBlocks> wide_;                 // built on first β > 0
  mutable std::shared_ptr<const Factorization> wide_symbolic_;  // analysis shared by β > 0
  mutable BuildTimings last_build_;  // guarded by mutex_
  mutable std::shared_ptr<FactorBudget> budget_;  // guarded by mutex_; null: unbounded
  // Charges a system just built (no lock of this set held).
  void charge(const std::shared_ptr<const BetaSystem>& sys, bool pinned) const;
};

}  // namespace hdeform

#include "engine/deform/local_beta.h"  // the per-triangle β fields that update_local takes

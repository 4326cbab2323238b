// The solver's orderings of a newly opened mesh (PreparedMesh::order for β = 0, wide_order
// for β > 0), computed while nobody waits for them. A session's first SetConstraints pays
// METIS on L's pattern and its first β > 0 METIS on the wide one (≈ 3 s and 4 s at 1M
// vertices, docs/benchmarks.md "Orders in the background"); one thread at the lowest
// priority (SCHED_IDLE: it runs on cores nothing else wants) computes them after the open,
// and the PreparedMesh adopts them, so the OrderingStore keeps them with the mesh.
//
// A warm cache, not a change of any session: nothing a client sees depends on it but the
// time of those first calls. A call that comes first computes the order itself, and the
// background one is dropped. Bounded: one thread, a queue of at most max_queued meshes (the
// oldest goes), and the working memory charged to the factorization budget only where there
// is room for it (else skipped: it never evicts a cached system).
#pragma once

#include "service/session/mesh_library.h"

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>

namespace hdeform {
class FactorBudget;
}

namespace hdeform::service {

class BackgroundOrders {
 public:
  struct Options {
    // Meshes from this many vertices on get their orders in the background; 0 = none
    // (--background-order-from). Below 20K vertices METIS takes < 0.1 s.
    std::size_t from_vertices = 20000;
    std::size_t max_queued = 16;  // meshes waiting; a new one beyond it drops the oldest
    // SCHED_IDLE (else the default policy: for tests that must not wait for idle cores).
    bool lowest_priority = true;
  };
  struct Stats {
    std::uint64_t computed = 0;     // orders adopted by their mesh (two per mesh)
    std::uint64_t superseded = 0;   // orders a call computed first (or the store had)
    std::uint64_t closed = 0;       // meshes no session or cache entry held at their turn
    std::uint64_t no_room = 0;      // meshes the budget had no room for
    std::uint64_t queue_full = 0;   // meshes dropped from a full queue
    std::uint64_t failed = 0;       // orders METIS or an allocation failed (logged)
    bool busy = false;              // an order is being computed now
    std::size_t queued = 0;         // meshes waiting
    bool idle_priority = false;     // the worker runs at SCHED_IDLE
  };

  BackgroundOrders(const Options& options, std::shared_ptr<FactorBudget> budget);
  ~BackgroundOrders();  // join()
  BackgroundOrders(const BackgroundOrders&) = delete;
  BackgroundOrders& operator=(const BackgroundOrders&) = delete;

  // After a session's open: queues the mesh if it is large enough and lacks an order.
  // Holds it weakly: a mesh no session holds and the cache has evicted before its turn is
  // never ordered (one still cached is: a later session on it takes the orders).
  // Cheap and non-blocking (a lock and a push).
  void enqueue(const std::shared_ptr<const MeshRef>& mesh);
  // Drops the queue and starts no other order; returns at once. The order in progress, if
  // any, runs on (METIS cannot be interrupted): a server stores its sessions meanwhile.
  void stop();
  // stop(), then waits for the order in progress: at most one order's time, ≈ 4–6 s at 1M
  // vertices on 2 idle cores, longer on busy ones (it runs at SCHED_IDLE).
  void join();
  Stats stats() const;
  // Working memory of the wide order (Reg, METIS's graph and its copies; the β = 0 one
  // needs less), by the mesh's size: the bytes charged to the budget while a mesh's orders
  // are computed (engine_bench Memory/N wide_order_MB, docs/benchmarks.md).
  static std::size_t working_bytes(std::size_t vertices);
  // Measured 449 / 453 bytes per vertex at 100K / 1M (the peak above the RSS before: a
  // lower bound, freed heap is reused), charged with a third more.
  static constexpr std::size_t kWorkingBytesPerVertex = 600;

 private:
  void run();
  void order(const MeshRef& mesh);
  bool stopping() const;

  const Options options_;
  const std::shared_ptr<FactorBudget> budget_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::weak_ptr<const MeshRef>> queue_;
  bool stopping_ = false;
  Stats stats_;
  std::thread thread_;
};

}  // namespace hdeform::service

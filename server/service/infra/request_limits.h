// Per-request caps (hdeform-server flags): every request's work and memory is bounded by
// these, and a request beyond one gets RESOURCE_EXHAUSTED naming the cap and its flag.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>

namespace hdeform::service {

struct RequestLimits {
  std::size_t max_handles = 64;              // --max-handles: handle regions per session
  std::size_t max_selectors = 256;           // --max-selectors: selectors per region
  std::size_t max_selector_ids = 4'000'000;  // --max-selector-ids: ids in one ids/base_ids selector
  std::size_t max_local_beta = 16;           // --max-local-beta: local β entries
  std::size_t max_sweep_betas = 64;          // --max-sweep-betas: β values in one Sweep
  std::size_t max_concurrent_sweeps = 1;     // --max-sweeps: Sweeps running at once (server)
  std::size_t max_watchers = 64;             // --max-watchers: WatchSession streams per session
  // --max-delta-watchers: of those, MESHOPT_DELTA ones per session (each encodes every frame
  // for itself and keeps 8 bytes per vertex: N of them cost N encodes per frame)
  std::size_t max_delta_watchers = 8;
  std::size_t max_pending_updates = 16;      // --max-pending-updates: coalescing UpdateHandles
                                             // waiting per session
  std::chrono::milliseconds max_lease{60'000};  // --max-lease-ms: longest GrabHandles lease
  std::size_t max_history = 1000;            // --max-history: steps kept per session
  std::size_t max_snapshots = 64;            // --max-snapshots: named snapshots per session
  std::size_t max_animation_frames = 600;    // --max-animation-frames: samples per export
  std::size_t max_animation_bytes = 256u << 20;  // --max-animation-bytes: an export's GLB
  // Admission: a call that would wait behind this many is refused at arrival, before any
  // work, so a flood queues nothing unbounded.
  std::size_t max_queued_calls = 1024;  // --max-queued-calls: waiting for a solver thread (server)
  std::size_t max_session_queue = 32;  // --max-session-queue: waiting on one session's strand
};

// Throws ServiceError RESOURCE_EXHAUSTED "WHAT: COUNT exceeds the limit of LIMIT (FLAG)".
void check_limit(std::size_t count, std::size_t limit, const std::string& what,
                 const char* flag);

}  // namespace hdeform::service

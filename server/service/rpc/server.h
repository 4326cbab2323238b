// hdeform-server's core, usable in-process (the CLI without --server) or listening on TCP.
#pragma once

#include "service/infra/request_limits.h"
#include "service/session/background_orders.h"

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace hdeform::service {

struct ServerOptions {
  // "HOST:PORT" to listen on; empty = in-process only (no TCP port). Port 0 = any free port.
  std::string listen_address = "127.0.0.1:50051";
  std::string mesh_dir;                 // mesh library; empty = the bundled data/ folder
  int workers = 2;                      // solver threads
  std::size_t max_sessions = 64;
  std::size_t max_vertices = 2'000'000;
  std::size_t max_upload_bytes = 256u << 20;
  std::size_t cache_bytes = 4ull << 30;  // prepared meshes + factorizations (LRU)
  std::chrono::seconds session_ttl{3600};
  RequestLimits request;  // per-request caps (request_limits.h)
  // A new mesh's β = 0 and β > 0 orders are computed in the background, at the lowest CPU
  // priority, from this many vertices on (--background-order-from; 0 = never):
  // background_orders.h.
  std::size_t background_order_from = 20000;
  // A CreateSession's new mesh is ordered (β = 0) beside its operators, so the open answers
  // later and its first SetConstraints sooner (--order-on-open): for batch clients that
  // set constraints at once (the in-process CLI). Off: its user picks regions meanwhile.
  bool order_on_open = false;
  // Upload bytes held by unfinished CreateSession calls, all clients together
  // (--max-upload-inflight-mb); a new upload beyond it gets RESOURCE_EXHAUSTED.
  std::size_t max_upload_inflight_bytes = 1ull << 30;
  // An upload that sends nothing for this long is ended with DEADLINE_EXCEEDED
  // (--upload-stall-timeout); its bytes are released.
  std::chrono::milliseconds upload_stall_timeout{30'000};
  // gRPC's own bounds: streams one connection may have open at once (--max-concurrent-streams;
  // more wait in the client), and the memory gRPC may use for its buffers (--grpc-memory-mb;
  // beyond it new calls are refused with RESOURCE_EXHAUSTED by gRPC).
  int max_concurrent_streams = 100;
  std::size_t grpc_memory_bytes = 1ull << 30;
  // Durable session state (docs/deployment.md "State"): a folder for SQLite + mesh files
  // (--state-dir), or a Redis URL (--state-redis); both empty = sessions live in memory only.
  std::string state_dir;
  std::string state_redis;
  // Operator token (--admin-token): opens every session, lists all. Empty = none. Never logged.
  std::string admin_token;
  // TLS on the gRPC port (--tls-cert, --tls-key, --tls-client-ca): PEM files. Cert and key
  // together turn TLS on (both or neither); with a client CA, every client must present a
  // certificate signed by it. Checked at start-up (the constructor throws naming the file).
  // The in-process channel is never affected.
  std::string tls_cert_file, tls_key_file, tls_client_ca_file;
};

class DeformService;  // deform_service.h

class Server {
 public:
  explicit Server(const ServerOptions& options);  // starts serving; throws on bind failure
  ~Server();                                      // graceful shutdown
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  int port() const;  // bound TCP port, or 0 when in-process only
  // What --cache-mb accounts now: the cache's own entries (prepared meshes, constraint sets
  // without their factorizations) and the factorizations charged to it.
  struct MemoryStats {
    std::size_t limit = 0, cache_bytes = 0, factor_bytes = 0, factor_pinned_bytes = 0;
    std::uint64_t factor_evictions = 0;
  };
  MemoryStats memory_stats() const;
  // The background orders (background_orders.h): computed, skipped, queued, busy.
  BackgroundOrders::Stats background_orders() const;
  // Session restores that ran outside the worker pool (on a gRPC thread): should stay 0.
  std::size_t restores_off_pool() const;
  // The prepared mesh the cache holds for a mesh hash (nullptr: none): its build timings
  // and orders, for tests and tools.
  std::shared_ptr<const PreparedMesh> prepared_mesh(const std::string& mesh_hash) const;
  std::shared_ptr<grpc::Channel> in_process_channel();
  void shutdown(std::chrono::milliseconds deadline = std::chrono::milliseconds(2000));
  void wait();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hdeform::service

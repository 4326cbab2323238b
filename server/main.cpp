// hdeform-server: the gRPC service on TCP (and optionally the gRPC-Web/HTTP gateway with
// the web viewer). Every flag also reads an HDEFORM_* environment variable.
#include "common/ready_file.h"
#include "engine/runtime/process_environment.h"
#include "engine/runtime/run_beside.h"
#include "engine/runtime/warm_cores.h"
#include "service/access/access.h"
#include "service/rpc/server.h"
#include "service/state/state_backend.h"

#include "gateway/http_gateway.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>
#include <pthread.h>
#include <sys/resource.h>
#include <string>
#include <thread>
#include <unistd.h>

namespace {

std::string default_web_root() {
#if defined(HDEFORM_DEFAULT_WEB_ROOT)
  const std::string root = HDEFORM_DEFAULT_WEB_ROOT;
#elif defined(HDEFORM_SOURCE_DIR)
  const std::string root = std::string(HDEFORM_SOURCE_DIR) + "/web-viewer/dist";
#else
  const std::string root;
#endif
  std::error_code ec;
  return !root.empty() && std::filesystem::is_directory(root, ec) ? root : std::string();
}

std::string host_port(const std::string& host, int port) {
  const bool v6 = host.find(':') != std::string::npos && host.front() != '[';
  return (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

// Debian's soft limit of 1024 descriptors is below the gateway's 1024 waiting + 4096 active
// connections plus gRPC's own: take the hard limit (no privilege needed).
void raise_open_file_limit() {
  rlimit lim{};
  if (::getrlimit(RLIMIT_NOFILE, &lim) == 0 && lim.rlim_cur < lim.rlim_max) {
    lim.rlim_cur = lim.rlim_max;
    ::setrlimit(RLIMIT_NOFILE, &lim);
  }
}

// The per-user data folder (XDG base directories): where sessions survive a restart.
std::string default_state_dir() {
  if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg == '/')
    return std::string(xdg) + "/hdeform";
  if (const char* home = std::getenv("HOME"); home && *home)
    return std::string(home) + "/.local/share/hdeform";
  return "hdeform-state";
}

}  // namespace

int main(int argc, char** argv) {
  hdeform::ensure_process_environment(argv);  // before any allocation or OpenMP loop
  const int parent_at_start = getppid();
  CLI::App app{"hdeform-server: interactive harmonic surface deformation over gRPC"};
  app.footer(
      "Each option also reads the environment variable shown as Env: (e.g. HDEFORM_BIND, "
      "HDEFORM_PORT, HDEFORM_HTTP_PORT, HDEFORM_STATE_REDIS); the command line wins over "
      "the variable, and an empty variable counts as unset.");
  int port = 50051;
  std::string bind = "127.0.0.1";
  std::string mesh_dir;
  std::size_t max_sessions = 64;
  std::size_t max_vertices = 2'000'000;
  std::size_t max_upload_mb = 256;
  std::size_t cache_mb = 4096;
  long session_ttl = 3600;
  int workers = 2;
  std::string log_level = "info";
  int http_port = -1;
  std::string web_root = default_web_root();

  app.add_option("--port", port, "gRPC TCP port (0 = any free port)")
      ->envname("HDEFORM_PORT")
      ->capture_default_str();
  app.add_option("--bind", bind, "address to listen on")
      ->envname("HDEFORM_BIND")
      ->capture_default_str();
  app.add_option("--mesh-dir", mesh_dir, "mesh library folder (default: the bundled data/)")
      ->envname("HDEFORM_MESH_DIR");
  app.add_option("--max-sessions", max_sessions, "most concurrent sessions")
      ->envname("HDEFORM_MAX_SESSIONS")
      ->capture_default_str();
  app.add_option("--max-vertices", max_vertices, "largest mesh accepted (vertices)")
      ->envname("HDEFORM_MAX_VERTICES")
      ->capture_default_str();
  app.add_option("--max-upload-mb", max_upload_mb, "largest upload accepted (MiB)")
      ->envname("HDEFORM_MAX_UPLOAD_MB")
      ->capture_default_str();
  app.add_option("--cache-mb", cache_mb, "prepared meshes + factorizations cache budget (MiB)")
      ->envname("HDEFORM_CACHE_MB")
      ->capture_default_str();
  std::size_t background_order_from = 20000;
  app.add_option("--background-order-from", background_order_from,
                 "compute a new mesh's orderings (beta = 0 and > 0) in the background, on idle "
                 "cores, from this many vertices on, so its first SetConstraints and beta > 0 "
                 "skip METIS (0 = never)")
      ->envname("HDEFORM_BACKGROUND_ORDER_FROM")
      ->capture_default_str();
  bool order_on_open = false;
  app.add_flag("--order-on-open", order_on_open,
               "order a new session's mesh (beta = 0) beside its operators: the open answers "
               "later, its first SetConstraints sooner (for batch clients)")
      ->envname("HDEFORM_ORDER_ON_OPEN");
  app.add_option("--session-ttl", session_ttl, "idle session lifetime (seconds)")
      ->envname("HDEFORM_SESSION_TTL")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--workers", workers, "solver threads")
      ->envname("HDEFORM_WORKERS")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  int beside_threads = -1;
  app.add_option("--beside-threads", beside_threads,
                 "threads that requests may start at once beside their worker (the second "
                 "half of a large mesh's ordering, a system's right-hand side blocks); beyond "
                 "it a request does both parts on its worker, in turn (-1 = the machine's "
                 "cores)")
      ->envname("HDEFORM_BESIDE_THREADS")
      ->check(CLI::Range(-1, 256))
      ->capture_default_str();
  int warm_cores_ms = -1;
  app.add_option("--warm-cores-ms", warm_cores_ms,
                 "keep the cores from idling this long after each drag move, so the next "
                 "frame is not slowed by halted cores (0 = off; -1 = 250, or off under a "
                 "cgroup CPU quota)")
      ->envname("HDEFORM_WARM_CORES_MS")
      ->check(CLI::Range(-1, 10000))
      ->capture_default_str();
  hdeform::service::RequestLimits request;
  std::size_t max_upload_inflight_mb = 1024;
  std::size_t grpc_memory_mb = 1024;
  int max_concurrent_streams = 100;
  double upload_stall_timeout = 30;
  app.add_option("--max-handles", request.max_handles, "handle regions per session")
      ->envname("HDEFORM_MAX_HANDLES")
      ->capture_default_str();
  app.add_option("--max-selectors", request.max_selectors, "selectors per region")
      ->envname("HDEFORM_MAX_SELECTORS")
      ->capture_default_str();
  app.add_option("--max-selector-ids", request.max_selector_ids,
                 "vertex ids in one ids/base_ids selector")
      ->envname("HDEFORM_MAX_SELECTOR_IDS")
      ->capture_default_str();
  app.add_option("--max-local-beta", request.max_local_beta, "local beta entries per session")
      ->envname("HDEFORM_MAX_LOCAL_BETA")
      ->capture_default_str();
  app.add_option("--max-sweep-betas", request.max_sweep_betas, "beta values in one Sweep")
      ->envname("HDEFORM_MAX_SWEEP_BETAS")
      ->capture_default_str();
  app.add_option("--max-sweeps", request.max_concurrent_sweeps,
                 "Sweeps running at once (each holds one transient factorization)")
      ->envname("HDEFORM_MAX_SWEEPS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-watchers", request.max_watchers, "WatchSession streams per session")
      ->envname("HDEFORM_MAX_WATCHERS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-delta-watchers", request.max_delta_watchers,
                 "WatchSession streams per session asking MESHOPT_DELTA frames (each encodes "
                 "every frame for itself)")
      ->envname("HDEFORM_MAX_DELTA_WATCHERS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-queued-calls", request.max_queued_calls,
                 "calls waiting for a solver thread, all sessions together; more are refused "
                 "(RESOURCE_EXHAUSTED) on arrival")
      ->envname("HDEFORM_MAX_QUEUED_CALLS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-session-queue", request.max_session_queue,
                 "calls waiting on one session (its changes run one at a time); more are "
                 "refused (RESOURCE_EXHAUSTED) on arrival")
      ->envname("HDEFORM_MAX_SESSION_QUEUE")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-concurrent-streams", max_concurrent_streams,
                 "gRPC streams (calls) one connection may have open at once; more wait")
      ->envname("HDEFORM_MAX_CONCURRENT_STREAMS")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--grpc-memory-mb", grpc_memory_mb,
                 "memory gRPC may use for its buffers (MiB); beyond it new calls are refused")
      ->envname("HDEFORM_GRPC_MEMORY_MB")
      ->check(CLI::Range(16, 1 << 20))
      ->capture_default_str();
  app.add_option("--max-pending-updates", request.max_pending_updates,
                 "coalescing UpdateHandles (pipelined clients) waiting per session")
      ->envname("HDEFORM_MAX_PENDING_UPDATES")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option_function<std::int64_t>(
         "--max-lease-ms",
         [&request](std::int64_t ms) { request.max_lease = std::chrono::milliseconds(ms); },
         "longest handle grab a client may ask (GrabHandles lease_ms); a vanished client's "
         "grab ends at most this long after its last update")
      ->envname("HDEFORM_MAX_LEASE_MS")
      ->check(CLI::Range(std::int64_t{100}, std::int64_t{3'600'000}))
      ->default_str("60000");
  app.add_option("--max-history", request.max_history,
                 "history steps kept per session (the oldest go first)")
      ->envname("HDEFORM_MAX_HISTORY")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-snapshots", request.max_snapshots, "named snapshots per session")
      ->envname("HDEFORM_MAX_SNAPSHOTS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-animation-frames", request.max_animation_frames,
                 "sampled frames in one ExportAnimation (each is a solve)")
      ->envname("HDEFORM_MAX_ANIMATION_FRAMES")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-animation-bytes", request.max_animation_bytes,
                 "size of one ExportAnimation or ExportRig GLB (bytes; checked before any solve)")
      ->envname("HDEFORM_MAX_ANIMATION_BYTES")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-upload-inflight-mb", max_upload_inflight_mb,
                 "upload bytes held by unfinished uploads, all clients together (MiB)")
      ->envname("HDEFORM_MAX_UPLOAD_INFLIGHT_MB")
      ->capture_default_str();
  app.add_option("--upload-stall-timeout", upload_stall_timeout,
                 "seconds an upload may send nothing before it is ended")
      ->envname("HDEFORM_UPLOAD_STALL_TIMEOUT")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  std::string state_dir = default_state_dir(), state_redis, admin_token;
  bool no_state = false;
  int state_redis_wait = 30;
  // One store at most, checked after parsing: CLI11's excludes() would also count
  // HDEFORM_NO_STATE=false.
  auto* state_dir_opt =
      app.add_option("--state-dir", state_dir,
                     "folder for durable sessions (SQLite + uploaded meshes); default: "
                     "$XDG_DATA_HOME/hdeform or ~/.local/share/hdeform")
          ->envname("HDEFORM_STATE_DIR")
          ->capture_default_str();
  app.add_flag("--no-state", no_state,
               "keep sessions in memory only (lost on restart); not with --state-dir or "
               "--state-redis")
      ->envname("HDEFORM_NO_STATE");
  app.add_option("--state-redis", state_redis,
                 "keep session state in Redis (redis://[:PASSWORD@]HOST[:PORT][/DB]) so that "
                 "replicas can take over each other's sessions; not with --state-dir; an "
                 "empty value is none")
      ->envname("HDEFORM_STATE_REDIS");
  app.add_option("--state-redis-wait", state_redis_wait,
                 "seconds to keep trying at start while the --state-redis server cannot be "
                 "reached (0 = fail at once); a refused password fails at once")
      ->envname("HDEFORM_STATE_REDIS_WAIT")
      ->check(CLI::Range(0, 600))
      ->capture_default_str();
  // No capture_default_str and never logged: the value is a secret. Prefer the variable
  // (a command line is visible to every local user in `ps`).
  app.add_option("--admin-token", admin_token,
                 "operator token: opens every session, lists all (prefer the variable)")
      ->envname("HDEFORM_ADMIN_TOKEN");
  std::string ready_file;
  app.add_option("--ready-file", ready_file,
                 "once serving, write {\"grpc\": host:port, \"http\": host:port|null} here "
                 "(atomically): how a parent learns the ports of --port 0");
  bool with_parent = false;
  app.add_flag("--exit-with-parent", with_parent,
               "shut down (as on SIGTERM) when the process that started this one exits");
  bool gen_token = false;
  app.add_flag("--gen-token", gen_token,
               "print a new random operator token (256 bits, hex) and exit");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")
      ->envname("HDEFORM_LOG_LEVEL")
      ->check(CLI::IsMember(
          {"trace", "debug", "info", "warn", "warning", "err", "error", "critical", "off"}))
      ->capture_default_str();
  app.add_option("--http-port", http_port,
                 "gRPC-Web + web viewer HTTP port (-1 = off, 0 = any free port)")
      ->envname("HDEFORM_HTTP_PORT")
      ->capture_default_str();
  app.add_option("--web-root", web_root, "built web viewer served on --http-port")
      ->envname("HDEFORM_WEB_ROOT");
  std::string tls_cert, tls_key, tls_client_ca;
  auto* tls_cert_opt =
      app.add_option("--tls-cert", tls_cert,
                     "TLS certificate chain (PEM): TLS on the gRPC port and HTTPS on --http-port")
          ->envname("HDEFORM_TLS_CERT")
          ->check(CLI::ExistingFile);
  auto* tls_key_opt = app.add_option("--tls-key", tls_key, "TLS private key (PEM, unencrypted)")
                          ->envname("HDEFORM_TLS_KEY")
                          ->check(CLI::ExistingFile);
  app.add_option("--tls-client-ca", tls_client_ca,
                 "CA certificates (PEM): require client certificates signed by them")
      ->envname("HDEFORM_TLS_CLIENT_CA")
      ->check(CLI::ExistingFile)
      ->needs(tls_cert_opt);
  tls_cert_opt->needs(tls_key_opt);
  tls_key_opt->needs(tls_cert_opt);
  hdeform::gateway::GatewayOptions http;
  double header_timeout = 10, idle_timeout = 60, stall_timeout = 30;
  app.add_option("--http-max-requests", http.max_connections,
                 "HTTP requests in progress (streams included); above it 503")
      ->envname("HDEFORM_HTTP_MAX_REQUESTS")
      ->capture_default_str();
  app.add_option("--http-max-idle", http.max_idle_connections,
                 "HTTP connections waiting for a request; above it the oldest is closed")
      ->envname("HDEFORM_HTTP_MAX_IDLE")
      ->capture_default_str();
  app.add_option("--http-header-timeout", header_timeout,
                 "seconds a new HTTP connection has to send a whole request header")
      ->envname("HDEFORM_HTTP_HEADER_TIMEOUT")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--http-idle-timeout", idle_timeout,
                 "seconds a keep-alive HTTP connection may wait between requests")
      ->envname("HDEFORM_HTTP_IDLE_TIMEOUT")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--http-stall-timeout", stall_timeout,
                 "seconds a request body or a response may make no progress")
      ->envname("HDEFORM_HTTP_STALL_TIMEOUT")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--allowed-hosts", http.allowed_hosts,
                 "Host names the HTTP port answers besides localhost names and IP addresses "
                 "(comma-separated; .NAME for subdomains; * for any, only behind a proxy that "
                 "checks Host); others get 421, which stops DNS rebinding")
      ->envname("HDEFORM_ALLOWED_HOSTS")
      ->delimiter(',');
  CLI11_PARSE(app, argc, argv);
  {
    const char* redis = "--state-redis / HDEFORM_STATE_REDIS";
    const char* dir = "--state-dir / HDEFORM_STATE_DIR";
    const bool has_dir = state_dir_opt->count() > 0;
    if (no_state && (has_dir || !state_redis.empty()))
      return app.exit(
          CLI::ExcludesError("--no-state / HDEFORM_NO_STATE", has_dir ? dir : redis));
    if (has_dir && !state_redis.empty()) return app.exit(CLI::ExcludesError(redis, dir));
  }

  spdlog::set_level(spdlog::level::from_str(log_level));
  raise_open_file_limit();

  // SIGINT/SIGTERM are taken by sigwait() below: block them before any thread starts.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  if (with_parent) {
    try {
      hdeform::exit_with_parent(parent_at_start);
    } catch (const std::exception& e) {
      spdlog::critical("{}", e.what());
      return 1;
    }
  }

  hdeform::service::ServerOptions options;
  options.listen_address = host_port(bind, port);
  options.mesh_dir = mesh_dir;
  options.workers = workers;
  options.max_sessions = max_sessions;
  options.max_vertices = max_vertices;
  options.max_upload_bytes = max_upload_mb << 20;
  options.cache_bytes = cache_mb << 20;
  options.session_ttl = std::chrono::seconds(session_ttl);
  options.background_order_from = background_order_from;
  options.order_on_open = order_on_open;
  options.request = request;
  options.max_upload_inflight_bytes = max_upload_inflight_mb << 20;
  options.grpc_memory_bytes = grpc_memory_mb << 20;
  options.max_concurrent_streams = max_concurrent_streams;
  options.upload_stall_timeout =
      std::chrono::milliseconds(static_cast<long>(upload_stall_timeout * 1000));
  if (!no_state) {
    if (!state_redis.empty()) options.state_redis = state_redis;
    else options.state_dir = state_dir;
  }
  if (gen_token) {
    std::cout << hdeform::service::new_token() << std::endl;
    return 0;
  }
  // Compose passes an unset variable as empty: that means no operator token, said plainly.
  if (admin_token.empty()) {
    spdlog::info("no operator token (--admin-token / HDEFORM_ADMIN_TOKEN empty): every session "
                 "opens only with its own tokens");
  } else if (auto why = hdeform::service::operator_token_problem(admin_token); !why.empty()) {
    spdlog::critical("--admin-token / HDEFORM_ADMIN_TOKEN refused: {}", why);
    return 2;
  }
  options.admin_token = admin_token;
  options.tls_cert_file = tls_cert;
  options.tls_key_file = tls_key;
  options.tls_client_ca_file = tls_client_ca;

  // A replica may start before its Redis (compose, orchestrators): wait for it here, where
  // SIGINT/SIGTERM (blocked above) can still end the wait.
  if (!options.state_redis.empty() && state_redis_wait > 0) {
    auto pause = [&signals](std::chrono::milliseconds d) {
      const timespec ts{static_cast<std::time_t>(d.count() / 1000),
                        static_cast<long>(d.count() % 1000) * 1'000'000};
      const int sig = sigtimedwait(&signals, nullptr, &ts);
      if (sig <= 0) return true;  // timed out (or another signal)
      spdlog::info("signal {}: shutting down while waiting for Redis", sig);
      return false;
    };
    try {
      if (!hdeform::service::wait_for_redis_state(
              options.state_redis, std::chrono::seconds(state_redis_wait), pause))
        return 0;
    } catch (const std::exception& e) {
      spdlog::critical("{}", e.what());
      return 1;
    }
  }

  if (beside_threads >= 0) hdeform::set_beside_thread_limit(beside_threads);
  spdlog::info("at most {} threads beside the workers", hdeform::beside_threads().limit);

  auto& warm = hdeform::WarmCores::instance();
  if (warm_cores_ms >= 0) warm.set_window(std::chrono::milliseconds(warm_cores_ms));
  if (warm.window().count() > 0)
    spdlog::info("cores kept warm for {} ms after each drag move", warm.window().count());
  else
    spdlog::info("cores not kept warm between drag moves{}",
                 warm_cores_ms < 0 ? " (the cgroup has a CPU quota)" : "");

  std::unique_ptr<hdeform::service::Server> server;
  try {
    server = std::make_unique<hdeform::service::Server>(options);
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    return 1;
  }
  std::cout << "hdeform-server listening on " << host_port(bind, server->port()) << std::endl;

  std::unique_ptr<hdeform::gateway::HttpGateway> gateway;
  if (http_port >= 0) {
    hdeform::gateway::GatewayOptions g = http;
    auto ms = [](double seconds) {
      return std::chrono::milliseconds(static_cast<long>(seconds * 1000));
    };
    g.header_timeout = ms(header_timeout);
    g.idle_timeout = ms(idle_timeout);
    g.stall_timeout = ms(stall_timeout);
    g.address = bind;
    g.port = http_port;
    g.web_root = web_root;
    g.tls_cert_file = tls_cert;
    g.tls_key_file = tls_key;
    g.tls_client_ca_file = tls_client_ca;
    g.max_body_bytes = options.max_upload_bytes + (16u << 20);
    g.max_inflight_body_bytes = options.max_upload_inflight_bytes;
    try {
      gateway = std::make_unique<hdeform::gateway::HttpGateway>(g, server->in_process_channel());
    } catch (const std::exception& e) {
      spdlog::critical("HTTP gateway: {}", e.what());
      server->shutdown();
      return 1;
    }
    std::cout << (tls_cert.empty() ? "hdeform-server http on " : "hdeform-server https on ")
              << host_port(bind, gateway->port())
              << (web_root.empty() ? " (API only)" : " (viewer: " + web_root + ")") << std::endl;
  }

  if (!ready_file.empty()) {
    try {
      hdeform::write_ready_file(ready_file, host_port(bind, server->port()),
                                gateway ? host_port(bind, gateway->port()) : "");
    } catch (const std::exception& e) {
      spdlog::critical("{}", e.what());
      if (gateway) gateway->stop();
      server->shutdown();
      return 1;
    }
  }

  int sig = 0;
  sigwait(&signals, &sig);
  spdlog::info("signal {}: shutting down", sig);
  // Long work stops cooperatively (parsing, sweeps, automatic β poll the stop flag), but a
  // single CHOLMOD factorization or METIS order cannot be interrupted: never let one hold
  // the process longer than this after SIGTERM (the state is flushed before a background
  // order is waited for). A second signal exits at once.
  std::thread([] {
    std::this_thread::sleep_for(std::chrono::seconds(5));
    spdlog::warn("shutdown took over 5 s (a factorization or an order still running); exiting");
    std::_Exit(0);
  }).detach();
  std::thread([signals] {
    int again = 0;
    sigwait(&signals, &again);
    std::_Exit(1);
  }).detach();
  if (gateway) gateway->stop();
  gateway.reset();
  server->shutdown(std::chrono::milliseconds(2000));
  server.reset();
  spdlog::info("bye");
  return 0;
}

#include "service/rpc/server.h"

#include "common/tls_files.h"
#include "service/access/access.h"
#include "service/rpc/deform_service.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <climits>
#include <mutex>
#include <stdexcept>

namespace hdeform::service {

namespace {
int clamp_int(std::size_t bytes) {
  return static_cast<int>(std::min<std::size_t>(bytes, static_cast<std::size_t>(INT_MAX)));
}

// Reads and checks the TLS files; returns the gRPC server credentials (insecure without TLS).
std::shared_ptr<grpc::ServerCredentials> server_credentials(const ServerOptions& o) {
  const auto files =
      load_tls_files("hdeform-server", o.tls_cert_file, o.tls_key_file, o.tls_client_ca_file);
  if (!files) return grpc::InsecureServerCredentials();
  grpc::SslServerCredentialsOptions ssl(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  ssl.pem_key_cert_pairs.push_back({files->private_key, files->cert_chain});
  if (!files->client_ca.empty()) {
    ssl.pem_root_certs = files->client_ca;
    ssl.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return grpc::SslServerCredentials(ssl);
}
}  // namespace

struct Server::Impl {
  std::unique_ptr<DeformService> service;
  std::unique_ptr<grpc::Server> server;
  int port = 0;
  std::mutex mutex;
  bool stopped = false;
};

Server::Server(const ServerOptions& options) : impl_(std::make_unique<Impl>()) {
  if (!options.admin_token.empty()) {
    if (auto why = operator_token_problem(options.admin_token); !why.empty()) {
      throw std::invalid_argument(why);
    }
  }
  // TLS files first: a bad file fails before anything starts.
  const auto credentials = options.listen_address.empty() ? grpc::InsecureServerCredentials()
                                                          : server_credentials(options);
  impl_->service = std::make_unique<DeformService>(options);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  if (!options.listen_address.empty())
    builder.AddListeningPort(options.listen_address, credentials, &impl_->port);
  builder.RegisterService(impl_->service.get());
  // Uploads arrive in ≤ 4 MiB chunks, but a snapshot with its mesh is one message; frames
  // of 1M vertices (positions + normals + energies) are ≈ 32 MB.
  builder.SetMaxReceiveMessageSize(
      clamp_int(std::max<std::size_t>(64u << 20, options.max_upload_bytes + (16u << 20))));
  builder.SetMaxSendMessageSize(
      clamp_int(std::max<std::size_t>(256u << 20, options.max_upload_bytes + (16u << 20))));
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, options.max_concurrent_streams);
  grpc::ResourceQuota quota("hdeform-server");
  quota.Resize(options.grpc_memory_bytes);
  builder.SetResourceQuota(quota);
  impl_->server = builder.BuildAndStart();
  if (!impl_->server) {
    impl_->service.reset();
    throw std::runtime_error("hdeform-server: cannot listen on '" + options.listen_address + "'");
  }
  if (!options.listen_address.empty() && impl_->port == 0) {
    impl_->server->Shutdown();
    impl_->service.reset();
    throw std::runtime_error("hdeform-server: cannot bind '" + options.listen_address + "'");
  }
  if (impl_->server->GetHealthCheckService())
    impl_->server->GetHealthCheckService()->SetServingStatus(true);
  const bool tls = !options.listen_address.empty() && !options.tls_cert_file.empty();
  spdlog::info("gRPC service started ({}{}; {} worker(s))",
               options.listen_address.empty() ? std::string("in-process only")
                                              : "port " + std::to_string(impl_->port),
               !tls                                    ? ""
               : options.tls_client_ca_file.empty() ? ", TLS"
                                                     : ", TLS with client certificates",
               options.workers);
}

Server::~Server() {
  shutdown();
  impl_->server.reset();
  impl_->service.reset();
}

int Server::port() const { return impl_->port; }

Server::MemoryStats Server::memory_stats() const {
  Cache& cache = impl_->service->cache();
  const Cache::Stats c = cache.stats();
  const FactorBudget::Stats f = cache.factor_budget()->stats();
  return {c.budget, c.bytes, f.charged, f.pinned, f.evictions};
}

BackgroundOrders::Stats Server::background_orders() const {
  return impl_->service->sessions().background_orders();
}

std::size_t Server::restores_off_pool() const {
  return impl_->service->sessions().restores_off_pool();
}

std::shared_ptr<const PreparedMesh> Server::prepared_mesh(const std::string& mesh_hash) const {
  return impl_->service->cache().find<PreparedMesh>("mesh/" + mesh_hash);
}

std::shared_ptr<grpc::Channel> Server::in_process_channel() {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  args.SetMaxSendMessageSize(-1);
  return impl_->server->InProcessChannel(args);
}

void Server::shutdown(std::chrono::milliseconds deadline) {
  {
    std::lock_guard lock(impl_->mutex);
    if (impl_->stopped) return;
    impl_->stopped = true;
  }
  spdlog::info("gRPC service shutting down");
  if (impl_->server->GetHealthCheckService())
    impl_->server->GetHealthCheckService()->SetServingStatus(false);
  impl_->service->begin_shutdown();  // open streams end: Shutdown need not wait for them
  impl_->server->Shutdown(std::chrono::system_clock::now() + deadline);  // drains the calls
  impl_->service->stop_workers();
  impl_->service->close_sessions();  // flushes what the drained calls answered
}

void Server::wait() { impl_->server->Wait(); }

}  // namespace hdeform::service

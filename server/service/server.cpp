#include "server.h"

#include "deform_service.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>

namespace hdeform::service {

namespace {
int clamp_int(std::size_t bytes) {
  return static_cast<int>(std::min<std::size_t>(bytes, static_cast<std::size_t>(INT_MAX)));
}

// ---- TLS files ---------------------------------------------------------------------------
// gRPC reports a bad certificate or key only as "cannot bind" (its log says a little more),
// so the files are read and checked here first, and every error names the file.

[[noreturn]] void tls_error(const std::string& what, const std::string& path,
                            const std::string& why) {
  ERR_clear_error();
  throw std::runtime_error("hdeform-server: " + what + " '" + path + "': " + why);
}

// The whole file (PEM files are small: at most 16 MiB is read).
std::string read_tls_file(const std::string& what, const std::string& path) {
  constexpr std::size_t kMaxBytes = 16u << 20;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) tls_error(what, path, std::string("cannot open: ") + std::strerror(errno));
  std::string bytes;
  char buffer[8192];
  std::size_t n = 0;
  while (bytes.size() <= kMaxBytes && (n = std::fread(buffer, 1, sizeof buffer, f)) > 0) {
    bytes.append(buffer, n);
  }
  const int error = std::ferror(f) ? errno : 0;
  std::fclose(f);
  if (error != 0) tls_error(what, path, std::string("cannot read: ") + std::strerror(error));
  if (bytes.size() > kMaxBytes) tls_error(what, path, "larger than 16 MiB; not a PEM file");
  return bytes;
}

// Never ask for a pass phrase (OpenSSL's default would prompt on the terminal).
int no_pass_phrase(char*, int, int, void*) { return 0; }

struct Bio {
  explicit Bio(const std::string& bytes)
      : bio(BIO_new_mem_buf(bytes.data(), static_cast<int>(bytes.size()))) {}
  ~Bio() { BIO_free(bio); }
  BIO* bio;
};

// Reads and checks the TLS files; returns the gRPC server credentials (insecure without TLS).
std::shared_ptr<grpc::ServerCredentials> server_credentials(const ServerOptions& o) {
  if (o.tls_cert_file.empty() && o.tls_key_file.empty()) {
    if (!o.tls_client_ca_file.empty()) {
      throw std::runtime_error("hdeform-server: --tls-client-ca needs --tls-cert and --tls-key");
    }
    return grpc::InsecureServerCredentials();
  }
  if (o.tls_cert_file.empty() || o.tls_key_file.empty()) {
    throw std::runtime_error(std::string("hdeform-server: TLS needs both --tls-cert and --tls-key (") +
                             (o.tls_cert_file.empty() ? "--tls-cert" : "--tls-key") + " is missing)");
  }
  const std::string cert_what = "TLS certificate (--tls-cert)";
  const std::string key_what = "TLS private key (--tls-key)";
  const std::string ca_what = "TLS client CA (--tls-client-ca)";
  grpc::SslServerCredentialsOptions ssl(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
  pair.cert_chain = read_tls_file(cert_what, o.tls_cert_file);
  pair.private_key = read_tls_file(key_what, o.tls_key_file);

  Bio cert_bio(pair.cert_chain), key_bio(pair.private_key);
  std::unique_ptr<X509, decltype(&X509_free)> cert(
      PEM_read_bio_X509(cert_bio.bio, nullptr, no_pass_phrase, nullptr), X509_free);
  if (!cert) tls_error(cert_what, o.tls_cert_file, "no PEM certificate in it");
  std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(
      PEM_read_bio_PrivateKey(key_bio.bio, nullptr, no_pass_phrase, nullptr), EVP_PKEY_free);
  if (!key) {
    tls_error(key_what, o.tls_key_file,
              "no PEM private key in it (or it is encrypted: pass phrases are not supported)");
  }
  if (X509_check_private_key(cert.get(), key.get()) != 1) {
    tls_error(key_what, o.tls_key_file,
              "does not match the certificate in '" + o.tls_cert_file + "'");
  }
  if (!o.tls_client_ca_file.empty()) {
    ssl.pem_root_certs = read_tls_file(ca_what, o.tls_client_ca_file);
    Bio ca_bio(ssl.pem_root_certs);
    std::unique_ptr<X509, decltype(&X509_free)> ca(
        PEM_read_bio_X509(ca_bio.bio, nullptr, no_pass_phrase, nullptr), X509_free);
    if (!ca) tls_error(ca_what, o.tls_client_ca_file, "no PEM certificate in it");
    ssl.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  ERR_clear_error();
  ssl.pem_key_cert_pairs.push_back(pair);  // a copy: the BIOs above still point into `pair`
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
  impl_->service->close_sessions();  // ends WatchSession streams
  impl_->server->Shutdown(std::chrono::system_clock::now() + deadline);
  impl_->service->stop_workers();
}

void Server::wait() { impl_->server->Wait(); }

}  // namespace hdeform::service

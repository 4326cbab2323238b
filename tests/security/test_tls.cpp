// Issue 9: TLS on both doors. A test PKI is made with the openssl command in a temporary
// folder (a CA, a server certificate for 127.0.0.1/localhost, a client certificate, and an
// unrelated CA with its own client certificate). The gRPC port of the real Server and the
// HTTPS gateway in front of it must accept exactly the clients they should, close silent or
// plain-text peers, refuse bad files at start-up naming the file, and pass Authorization on.
#include "service_fixture.h"

#include "gateway/grpc_web.h"
#include "gateway/http_gateway.h"

#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>

#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

using namespace hdeform::testing;
namespace fs = std::filesystem;
namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;
using namespace std::chrono_literals;

namespace {

// Runs a shell command; returns its exit status and its output (stdout + whatever it sends
// to stderr when the command redirects it).
std::pair<int, std::string> run(const std::string& command) {
  std::string out;
  FILE* p = ::popen(command.c_str(), "r");
  if (!p) return {-1, "popen failed"};
  char buffer[4096];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, p)) > 0) out.append(buffer, n);
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

constexpr const char* kOpensslConfig = R"([req]
distinguished_name = dn
prompt = no
[dn]
CN = unused
[ca_ext]
basicConstraints = critical,CA:TRUE
keyUsage = critical,keyCertSign,cRLSign
subjectKeyIdentifier = hash
[server_ext]
basicConstraints = CA:FALSE
keyUsage = critical,digitalSignature
extendedKeyUsage = serverAuth
subjectAltName = IP:127.0.0.1,DNS:localhost
[client_ext]
basicConstraints = CA:FALSE
keyUsage = critical,digitalSignature
extendedKeyUsage = clientAuth
)";

// The test PKI, made once per process (each test runs in its own process under ctest).
struct Pki {
  fs::path dir;

  Pki() : dir(fs::temp_directory_path() / ("hdeform-tls-" + std::to_string(::getpid()))) {
    fs::create_directories(dir);
    std::ofstream(dir / "openssl.cnf") << kOpensslConfig;
    make_ca("ca");
    make_ca("other-ca");
    make_leaf("server", "ca", "127.0.0.1", "server_ext", 2);
    make_leaf("client", "ca", "hdeform-test-client", "client_ext", 3);
    make_leaf("other-client", "other-ca", "hdeform-other-client", "client_ext", 4);
    std::ofstream(dir / "not-pem.txt") << "this is not a PEM file\n";
  }
  ~Pki() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }

  std::string path(const std::string& file) const { return (dir / file).string(); }
  std::string pem(const std::string& file) const { return slurp(path(file)); }

 private:
  void openssl(const std::string& args) const {
    const auto [status, out] =
        run(std::string(HDEFORM_OPENSSL) + " " + args + " -config " + path("openssl.cnf") + " 2>&1");
    ASSERT_EQ(status, 0) << args << "\n" << out;
  }
  static std::string ec_key() { return "-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes"; }
  void make_ca(const std::string& name) const {
    openssl("req -x509 " + ec_key() + " -keyout " + path(name + ".key") + " -out " +
            path(name + ".pem") + " -days 2 -subj /CN=hdeform-test-" + name + " -extensions ca_ext");
  }
  void make_leaf(const std::string& name, const std::string& ca, const std::string& cn,
                 const std::string& ext, int serial) const {
    openssl("req -new " + ec_key() + " -keyout " + path(name + ".key") + " -out " +
            path(name + ".csr") + " -subj /CN=" + cn);
    // `x509 -req` reads extensions from -extfile, not -config; the same file serves.
    const auto [status, out] = run(std::string(HDEFORM_OPENSSL) + " x509 -req -in " +
                                   path(name + ".csr") + " -CA " + path(ca + ".pem") + " -CAkey " +
                                   path(ca + ".key") + " -set_serial " + std::to_string(serial) +
                                   " -days 2 -extfile " + path("openssl.cnf") + " -extensions " +
                                   ext + " -out " + path(name + ".pem") + " 2>&1");
    ASSERT_EQ(status, 0) << out;
  }
};

const Pki& pki() {
  static const Pki instance;
  return instance;
}

// ---- the gRPC door ---------------------------------------------------------------------------

std::unique_ptr<hdeform::service::Server> tls_server(bool require_client_cert) {
  hdeform::service::ServerOptions o;
  o.listen_address = "127.0.0.1:0";
  o.workers = 1;
  o.tls_cert_file = pki().path("server.pem");
  o.tls_key_file = pki().path("server.key");
  if (require_client_cert) o.tls_client_ca_file = pki().path("ca.pem");
  return std::make_unique<hdeform::service::Server>(o);
}

std::shared_ptr<grpc::ChannelCredentials> ssl_credentials(const std::string& ca,
                                                          const std::string& client = "") {
  grpc::SslCredentialsOptions o;
  o.pem_root_certs = pki().pem(ca + ".pem");
  if (!client.empty()) {
    o.pem_cert_chain = pki().pem(client + ".pem");
    o.pem_private_key = pki().pem(client + ".key");
  }
  return grpc::SslCredentials(o);
}

// ListMeshes on a fresh channel; OK with at least one mesh, or the failure.
grpc::Status list_meshes(const std::string& target,
                         const std::shared_ptr<grpc::ChannelCredentials>& credentials) {
  auto stub = pb::Deformation::NewStub(grpc::CreateChannel(target, credentials));
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + 20s);
  pb::ListMeshesResponse reply;
  const grpc::Status status = stub->ListMeshes(&ctx, pb::ListMeshesRequest(), &reply);
  if (status.ok() && reply.meshes_size() == 0) return {grpc::StatusCode::INTERNAL, "no meshes"};
  return status;
}

std::string local(int port) { return "127.0.0.1:" + std::to_string(port); }

// ---- the HTTPS door --------------------------------------------------------------------------

// The real Server (in-process only: the gateway uses its in-process channel) behind an HTTPS
// gateway.
struct TlsDoor {
  std::unique_ptr<hdeform::service::Server> server;
  std::unique_ptr<hdeform::gateway::HttpGateway> gateway;

  explicit TlsDoor(hdeform::gateway::GatewayOptions o = {}, bool require_client_cert = false) {
    hdeform::service::ServerOptions so;
    so.listen_address.clear();
    so.workers = 1;
    server = std::make_unique<hdeform::service::Server>(so);
    o.port = 0;
    o.tls_cert_file = pki().path("server.pem");
    o.tls_key_file = pki().path("server.key");
    if (require_client_cert) o.tls_client_ca_file = pki().path("ca.pem");
    gateway = std::make_unique<hdeform::gateway::HttpGateway>(o, server->in_process_channel());
  }
  ~TlsDoor() {
    gateway.reset();
    server->shutdown(500ms);
  }
  int port() const { return gateway->port(); }
};

// One TLS connection to the gateway that verifies the server as 127.0.0.1 against `ca`,
// optionally presenting a client certificate. Blocking calls; the server closes on failure.
class HttpsClient {
 public:
  HttpsClient(int port, const std::string& ca = "ca", const std::string& client = "")
      : port_(port) {
    ctx_.load_verify_file(pki().path(ca + ".pem"));
    ctx_.set_verify_mode(asio::ssl::verify_peer);
    if (!client.empty()) {
      ctx_.use_certificate_chain_file(pki().path(client + ".pem"));
      ctx_.use_private_key_file(pki().path(client + ".key"), asio::ssl::context::pem);
    }
    // After the context is complete: a stream copies its certificate and verify mode.
    stream_.emplace(ioc_, ctx_);
    stream_->set_verify_callback(asio::ssl::host_name_verification("127.0.0.1"));
  }

  beast::error_code connect() {
    beast::error_code ec;
    beast::get_lowest_layer(*stream_).connect(
        tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port_)), ec);
    return ec;
  }
  beast::error_code handshake() {
    beast::error_code ec;
    stream_->handshake(asio::ssl::stream_base::client, ec);
    return ec;
  }
  // connect + handshake + one request; any failure is returned.
  beast::error_code open_and_request(http::request<http::string_body> req,
                                     http::response<http::string_body>* res) {
    if (auto ec = connect()) return ec;
    if (auto ec = handshake()) return ec;
    return request(std::move(req), res);
  }
  beast::error_code request(http::request<http::string_body> req,
                            http::response<http::string_body>* res) {
    req.set(http::field::host, local(port_));
    req.prepare_payload();
    beast::error_code ec;
    http::write(*stream_, req, ec);
    if (ec) return ec;
    *res = {};
    http::read(*stream_, buffer_, *res, ec);
    return ec;
  }
  // Blocks until the server ends the connection; returns how it ended.
  beast::error_code read_until_closed() {
    char byte;
    beast::error_code ec;
    while (!ec) stream_->read_some(asio::buffer(&byte, 1), ec);
    return ec;
  }

 private:
  int port_;
  asio::io_context ioc_;
  asio::ssl::context ctx_{asio::ssl::context::tls_client};
  std::optional<beast::ssl_stream<beast::tcp_stream>> stream_;
  beast::flat_buffer buffer_;
};

http::request<http::string_body> get(const std::string& target) {
  return {http::verb::get, target, 11};
}

// A gRPC-Web ListMeshes request (an empty message in one data frame).
http::request<http::string_body> grpc_web_list_meshes() {
  http::request<http::string_body> req{http::verb::post, "/hdeform.v1.Deformation/ListMeshes", 11};
  req.set(http::field::content_type, "application/grpc-web+proto");
  req.set("x-grpc-web", "1");
  const std::string message = pb::ListMeshesRequest().SerializeAsString();
  const auto prefix = hdeform::gateway::grpc_web::frame_prefix(
      hdeform::gateway::grpc_web::kDataFlag, static_cast<std::uint32_t>(message.size()));
  req.body() = std::string(prefix.data(), prefix.size()) + message;
  return req;
}

struct GrpcWebReply {
  std::vector<std::string> messages;
  std::string trailers;
};

GrpcWebReply parse_grpc_web(std::string_view body) {
  GrpcWebReply out;
  while (body.size() >= 5) {
    const auto flag = static_cast<std::uint8_t>(body[0]);
    const std::uint32_t length = (std::uint32_t(std::uint8_t(body[1])) << 24) |
                                 (std::uint32_t(std::uint8_t(body[2])) << 16) |
                                 (std::uint32_t(std::uint8_t(body[3])) << 8) | std::uint8_t(body[4]);
    if (body.size() < 5 + std::size_t(length)) break;
    const std::string payload(body.substr(5, length));
    if (flag & hdeform::gateway::grpc_web::kTrailerFlag) {
      out.trailers += payload;
    } else {
      out.messages.push_back(payload);
    }
    body.remove_prefix(5 + length);
  }
  return out;
}

// curl against the gateway: exit status and output (body, or curl's error message).
std::pair<int, std::string> curl(const std::string& args) {
  return run(std::string(HDEFORM_CURL) + " -sS --max-time 20 " + args + " 2>&1");
}

// The message of the exception `fn` throws ("" if none).
std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return {};
}

}  // namespace

// ---- gRPC port -------------------------------------------------------------------------------

TEST(TlsGrpc, SecureClientTrustingTheCaListsMeshes) {
  auto server = tls_server(false);
  const auto port = server->port();
  ASSERT_GT(port, 0);
  auto status = list_meshes(local(port), ssl_credentials("ca"));
  EXPECT_TRUE(status.ok()) << status.error_message();
  // The certificate also names localhost.
  status = list_meshes("localhost:" + std::to_string(port), ssl_credentials("ca"));
  EXPECT_TRUE(status.ok()) << status.error_message();
}

TEST(TlsGrpc, InsecureClientIsRefused) {
  auto server = tls_server(false);
  const auto status = list_meshes(local(server->port()), grpc::InsecureChannelCredentials());
  EXPECT_FALSE(status.ok());
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
}

TEST(TlsGrpc, ClientTrustingAnotherCaRefusesTheServer) {
  auto server = tls_server(false);
  const auto status = list_meshes(local(server->port()), ssl_credentials("other-ca"));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
}

TEST(TlsGrpc, ClientCaRequiresAClientCertificateFromIt) {
  auto server = tls_server(true);
  const auto target = local(server->port());
  auto status = list_meshes(target, ssl_credentials("ca"));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << "no client certificate";
  status = list_meshes(target, ssl_credentials("ca", "other-client"));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << "certificate from another CA";
  status = list_meshes(target, ssl_credentials("ca", "client"));
  EXPECT_TRUE(status.ok()) << status.error_message();
}

// ---- HTTPS door ------------------------------------------------------------------------------

TEST(TlsGateway, HealthzAndGrpcWebOverHttps) {
  TlsDoor door;
  const auto url = "https://" + local(door.port());
  auto [status, out] = curl("--cacert " + pki().path("ca.pem") + " " + url + "/healthz");
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(out, "ok\n");
  // The name in the certificate, not only its IP address.
  std::tie(status, out) = curl("--cacert " + pki().path("ca.pem") + " --resolve localhost:" +
                               std::to_string(door.port()) + ":127.0.0.1 https://localhost:" +
                               std::to_string(door.port()) + "/healthz");
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(out, "ok\n");
  // Clients without the CA do not trust the server.
  std::tie(status, out) = curl(url + "/healthz");
  EXPECT_NE(status, 0) << out;
  {
    HttpsClient untrusting(door.port(), "other-ca");
    ASSERT_FALSE(untrusting.connect());
    EXPECT_TRUE(untrusting.handshake());
  }

  // gRPC-Web, then /healthz again on the same (keep-alive) TLS connection.
  HttpsClient client(door.port());
  http::response<http::string_body> res;
  auto ec = client.open_and_request(grpc_web_list_meshes(), &res);
  ASSERT_FALSE(ec) << ec.message();
  EXPECT_EQ(res.result_int(), 200u);
  const auto reply = parse_grpc_web(res.body());
  EXPECT_NE(reply.trailers.find("grpc-status:0"), std::string::npos) << reply.trailers;
  ASSERT_EQ(reply.messages.size(), 1u);
  pb::ListMeshesResponse meshes;
  ASSERT_TRUE(meshes.ParseFromString(reply.messages[0]));
  EXPECT_GT(meshes.meshes_size(), 0);
  ec = client.request(get("/healthz"), &res);
  ASSERT_FALSE(ec) << ec.message();
  EXPECT_EQ(res.body(), "ok\n");
}

TEST(TlsGateway, PlainHttpToTheTlsPortGetsNoAnswer) {
  TlsDoor door;
  {
    asio::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(door.port())});
    auto req = get("/healthz");
    req.set(http::field::host, local(door.port()));
    http::write(socket, req);
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    beast::error_code ec;
    http::read(socket, buffer, res, ec);
    EXPECT_TRUE(ec) << "plain HTTP answered " << res.result_int();
  }
  auto [status, out] = curl("http://" + local(door.port()) + "/healthz");
  EXPECT_NE(status, 0) << out;
  // TLS clients are still served.
  std::tie(status, out) =
      curl("--cacert " + pki().path("ca.pem") + " https://" + local(door.port()) + "/healthz");
  EXPECT_EQ(out, "ok\n");
}

TEST(TlsGateway, SilentPeersAreClosedWithinTheHeaderTimeout) {
  hdeform::gateway::GatewayOptions o;
  o.header_timeout = 2000ms;
  TlsDoor door(o);

  // TCP only, never a ClientHello.
  asio::io_context ioc;
  tcp::socket silent(ioc);
  auto t0 = std::chrono::steady_clock::now();
  silent.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(door.port())});
  pollfd p{silent.native_handle(), POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 15000), 1) << "not closed";
  char byte;
  EXPECT_LE(::recv(silent.native_handle(), &byte, 1, 0), 0) << "the server sent bytes";
  auto elapsed = std::chrono::steady_clock::now() - t0;
  EXPECT_GE(elapsed, 1500ms);
  EXPECT_LT(elapsed, 6s);

  // A handshake that starts late, then no request: the handshake and the header share one
  // header_timeout, so the connection ends ~2 s after connecting (not 1.2 s + 2 s).
  HttpsClient client(door.port());
  t0 = std::chrono::steady_clock::now();
  ASSERT_FALSE(client.connect());
  std::this_thread::sleep_for(1200ms);
  ASSERT_FALSE(client.handshake());
  EXPECT_TRUE(client.read_until_closed());
  elapsed = std::chrono::steady_clock::now() - t0;
  EXPECT_GE(elapsed, 1500ms);
  EXPECT_LT(elapsed, 2900ms);

  // Others are served meanwhile and afterwards.
  const auto [status, out] =
      curl("--cacert " + pki().path("ca.pem") + " https://" + local(door.port()) + "/healthz");
  EXPECT_EQ(out, "ok\n");
}

TEST(TlsGateway, ClientCaRequiresAClientCertificateFromIt) {
  TlsDoor door({}, true);
  const auto url = "https://" + local(door.port()) + "/healthz";
  const auto ca = "--cacert " + pki().path("ca.pem") + " ";
  auto [status, out] = curl(ca + url);
  EXPECT_NE(status, 0) << "no client certificate: " << out;
  std::tie(status, out) = curl(ca + "--cert " + pki().path("other-client.pem") + " --key " +
                               pki().path("other-client.key") + " " + url);
  EXPECT_NE(status, 0) << "certificate from another CA: " << out;
  std::tie(status, out) = curl(ca + "--cert " + pki().path("client.pem") + " --key " +
                               pki().path("client.key") + " " + url);
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(out, "ok\n");

  // The same with a gRPC-Web call. (Under TLS 1.3 the client's handshake may complete before
  // the server checks its certificate: the refusal then shows on the request.)
  {
    HttpsClient anonymous(door.port());
    http::response<http::string_body> res;
    EXPECT_TRUE(anonymous.open_and_request(grpc_web_list_meshes(), &res));
  }
  HttpsClient client(door.port(), "ca", "client");
  http::response<http::string_body> res;
  const auto ec = client.open_and_request(grpc_web_list_meshes(), &res);
  ASSERT_FALSE(ec) << ec.message();
  EXPECT_NE(parse_grpc_web(res.body()).trailers.find("grpc-status:0"), std::string::npos);
}

// ---- start-up errors -------------------------------------------------------------------------

TEST(TlsStartup, BadFilesGiveAnErrorNamingTheFile) {
  const std::string missing = (pki().dir / "no-such-file.pem").string();
  struct Case {
    std::string cert, key, ca;
    std::vector<std::string> expected;  // substrings of the error
  };
  const std::vector<Case> cases = {
      {missing, pki().path("server.key"), "", {missing, "--tls-cert", "No such file"}},
      {pki().path("server.pem"), missing, "", {missing, "--tls-key", "No such file"}},
      {pki().path("not-pem.txt"), pki().path("server.key"), "", {"not-pem.txt", "certificate"}},
      {pki().path("server.pem"), pki().path("not-pem.txt"), "", {"not-pem.txt", "private key"}},
      {pki().path("server.pem"), pki().path("client.key"), "",
       {pki().path("client.key"), "does not match", pki().path("server.pem")}},
      {pki().path("server.pem"), pki().path("server.key"), missing, {missing, "--tls-client-ca"}},
      {pki().path("server.pem"), pki().path("server.key"), pki().path("not-pem.txt"),
       {"not-pem.txt", "--tls-client-ca"}},
      {pki().dir.string(), pki().path("server.key"), "", {pki().dir.string(), "--tls-cert"}},
      {pki().path("server.pem"), "", "", {"--tls-key"}},
      {"", pki().path("server.key"), "", {"--tls-cert"}},
      {"", "", pki().path("ca.pem"), {"--tls-client-ca"}},
  };
  for (const auto& c : cases) {
    const std::string label = "cert='" + c.cert + "' key='" + c.key + "' ca='" + c.ca + "'";
    const std::string grpc_error = error_of([&] {
      hdeform::service::ServerOptions o;
      o.listen_address = "127.0.0.1:0";
      o.workers = 1;
      o.tls_cert_file = c.cert;
      o.tls_key_file = c.key;
      o.tls_client_ca_file = c.ca;
      hdeform::service::Server server(o);
    });
    TestServer backend;
    const std::string http_error = error_of([&] {
      hdeform::gateway::GatewayOptions o;
      o.port = 0;
      o.tls_cert_file = c.cert;
      o.tls_key_file = c.key;
      o.tls_client_ca_file = c.ca;
      hdeform::gateway::HttpGateway gateway(o, backend.server->in_process_channel());
    });
    for (const auto& want : c.expected) {
      EXPECT_NE(grpc_error.find(want), std::string::npos) << label << "\ngRPC: " << grpc_error;
      EXPECT_NE(http_error.find(want), std::string::npos) << label << "\nHTTP: " << http_error;
    }
  }
  // And good files start both.
  EXPECT_EQ(error_of([] { tls_server(true); }), "");
  EXPECT_EQ(error_of([] { TlsDoor door({}, true); }), "");
}

// ---- Authorization reaches the service -------------------------------------------------------

namespace {

// Records the `authorization` metadata of every call it answers.
class RecordingService final : public pb::Deformation::Service {
 public:
  grpc::Status ListMeshes(grpc::ServerContext* ctx, const pb::ListMeshesRequest*,
                          pb::ListMeshesResponse*) override {
    record(*ctx);
    return grpc::Status::OK;
  }
  grpc::Status CreateSession(grpc::ServerContext* ctx,
                             grpc::ServerReader<pb::CreateSessionRequest>* reader,
                             pb::Session* out) override {
    record(*ctx);
    pb::CreateSessionRequest part;
    while (reader->Read(&part)) {
    }
    out->set_name("sessions/recorded");
    return grpc::Status::OK;
  }
  std::vector<std::string> take() {
    std::lock_guard lock(mu_);
    return std::exchange(seen_, {});
  }

 private:
  void record(const grpc::ServerContext& ctx) {
    std::lock_guard lock(mu_);
    for (auto [it, end] = ctx.client_metadata().equal_range("authorization"); it != end; ++it) {
      seen_.emplace_back(it->second.data(), it->second.size());
    }
  }
  std::mutex mu_;
  std::vector<std::string> seen_;
};

}  // namespace

TEST(TlsGateway, AuthorizationHeadersReachTheService) {
  RecordingService service;
  grpc::ServerBuilder builder;
  builder.RegisterService(&service);
  auto backend = builder.BuildAndStart();
  ASSERT_TRUE(backend);
  hdeform::gateway::GatewayOptions o;
  o.port = 0;
  o.tls_cert_file = pki().path("server.pem");
  o.tls_key_file = pki().path("server.key");
  auto gateway =
      std::make_unique<hdeform::gateway::HttpGateway>(o, backend->InProcessChannel({}));

  // gRPC-Web: every value, in order; a value gRPC cannot carry is left out.
  HttpsClient client(gateway->port());
  auto req = grpc_web_list_meshes();
  req.insert(http::field::authorization, "Bearer first-token");
  req.insert(http::field::authorization, "Bearer second-token");
  req.insert(http::field::authorization, "Bearer \xff-not-ascii");
  http::response<http::string_body> res;
  auto ec = client.open_and_request(req, &res);
  ASSERT_FALSE(ec) << ec.message();
  EXPECT_NE(parse_grpc_web(res.body()).trailers.find("grpc-status:0"), std::string::npos);
  EXPECT_EQ(service.take(), (std::vector<std::string>{"Bearer first-token", "Bearer second-token"}));

  // No header, no metadata.
  ASSERT_FALSE(client.request(grpc_web_list_meshes(), &res));
  EXPECT_TRUE(service.take().empty());

  // POST /upload too.
  http::request<http::string_body> upload{http::verb::post, "/upload?library=cactus", 11};
  upload.set("x-hdeform-upload", "1");
  upload.set(http::field::authorization, "Bearer upload-token");
  ec = client.request(upload, &res);
  ASSERT_FALSE(ec) << ec.message();
  EXPECT_EQ(res.result_int(), 200u) << res.body();
  pb::Session session;
  ASSERT_TRUE(session.ParseFromString(res.body()));
  EXPECT_EQ(session.name(), "sessions/recorded");
  EXPECT_EQ(service.take(), std::vector<std::string>{"Bearer upload-token"});

  gateway.reset();
  backend->Shutdown();
}

// Issue 8, the HTTP door: the real Server behind the real gateway (tests/browser's
// gateway_tests cover the same against a fake service, case by case). Files stay inside the
// web root, cross-site POSTs create nothing, idle sockets lock nobody out — and the gRPC
// sessions keep being served throughout.
#include "service_fixture.h"

#include "gateway/http_gateway.h"

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

using namespace hdeform::testing;
namespace fs = std::filesystem;
namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

namespace {

struct Door {
  fs::path dir;
  TestServer t;
  std::unique_ptr<hdeform::gateway::HttpGateway> gateway;

  Door() : dir(fs::temp_directory_path() / ("hdeform-door-" + std::to_string(::getpid()))) {
    fs::create_directories(dir / "root" / "assets");
    std::ofstream(dir / "root" / "index.html") << "<html>viewer</html>";
    std::ofstream(dir / "secret.txt") << "TOP-SECRET";
    fs::create_symlink(dir / "secret.txt", dir / "root" / "assets" / "link.txt");
    hdeform::gateway::GatewayOptions o;
    o.port = 0;
    o.web_root = (dir / "root").string();
    gateway = std::make_unique<hdeform::gateway::HttpGateway>(o, t.server->in_process_channel());
  }
  ~Door() {
    gateway.reset();
    std::error_code ec;
    fs::remove_all(dir, ec);
  }

  // One raw request (the target is sent verbatim); returns status and body.
  std::pair<int, std::string> request(http::verb verb, const std::string& target,
                                      const std::vector<std::pair<std::string, std::string>>&
                                          headers = {},
                                      const std::string& body = "") {
    asio::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect({asio::ip::make_address("127.0.0.1"),
                    static_cast<unsigned short>(gateway->port())});
    http::request<http::string_body> req{verb, target, 11};
    req.set(http::field::host, "127.0.0.1:" + std::to_string(gateway->port()));
    for (const auto& [k, v] : headers) req.set(k, v);
    req.body() = body;
    req.prepare_payload();
    http::write(socket, req);
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    beast::error_code ec;
    http::read(socket, buffer, res, ec);
    return {static_cast<int>(res.result_int()), res.body()};
  }
};

}  // namespace

TEST(SecurityHttp, FilesNeverLeaveTheWebRoot) {
  Door d;
  const pb::Session s = d.t.library_session("cactus");
  const std::string secret = (d.dir / "secret.txt").string();
  const std::vector<std::string> targets = {
       "/" + secret, "//" + secret.substr(1), "/%2F" + secret.substr(1), "/%252F" + secret.substr(1),
        "/../secret.txt", "/%2e%2e/secret.txt", "/%252e%252e/secret.txt", "/assets/..%2F..%2Fsecret.txt",
        "/..\\secret.txt", "/index.html%00.txt", "/assets/link.txt", "//etc/passwd", "/%2Fetc%2Fpasswd"};
  for (const std::string& target : targets) {
    const auto [status, body] = d.request(http::verb::get, target);
    EXPECT_TRUE(status == 400 || status == 404) << target << " → " << status;
    EXPECT_EQ(body.find("TOP-SECRET"), std::string::npos) << target;
    EXPECT_EQ(body.find("root:"), std::string::npos) << target;
  }
  EXPECT_EQ(d.request(http::verb::get, "/").second, "<html>viewer</html>");
  pb::Session again;
  EXPECT_TRUE(d.t.get_session(s.name(), &again).ok());
}

TEST(SecurityHttp, CrossSiteUploadCreatesNothing) {
  Door d;
  const std::string off = slurp(data_path("botsch-sorkine/bar.off"));
  auto [status, body] = d.request(http::verb::post, "/upload?filename=bar.off&session_id=evil",
                                  {{"Origin", "https://evil.example"},
                                   {"Content-Type", "text/plain"}},
                                  off);
  EXPECT_EQ(status, 403) << body;
  // A "simple" request without the custom header, even with no Origin, is refused too.
  std::tie(status, body) = d.request(http::verb::post, "/upload?filename=bar.off&session_id=evil",
                                     {{"Content-Type", "text/plain"}}, off);
  EXPECT_EQ(status, 403) << body;
  pb::Session none;
  EXPECT_EQ(d.t.get_session("sessions/evil", &none).error_code(), grpc::StatusCode::NOT_FOUND);
  // The viewer's own request works.
  std::tie(status, body) = d.request(http::verb::post, "/upload?filename=bar.off&session_id=mine",
                                     {{"X-Session-Id", "mine"},
                                      {"Content-Type", "application/octet-stream"}},
                                     off);
  EXPECT_EQ(status, 200) << body;
  EXPECT_TRUE(d.t.get_session("sessions/mine", &none).ok());
}

TEST(SecurityHttp, IdleSocketsDoNotLockOutClientsOrSessions) {
  Door d;
  const pb::Session s = constrained_cactus(d.t);
  asio::io_context ioc;
  std::vector<std::unique_ptr<tcp::socket>> idle;
  for (int i = 0; i < 300; ++i) {
    auto sock = std::make_unique<tcp::socket>(ioc);
    beast::error_code ec;
    sock->connect({asio::ip::make_address("127.0.0.1"),
                   static_cast<unsigned short>(d.gateway->port())},
                  ec);
    if (!ec) idle.push_back(std::move(sock));
  }
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(d.request(http::verb::get, "/healthz").first, 200);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(2));
  pb::Frame f;
  EXPECT_TRUE(d.t.update(s.name(), 1, {cactus_transform()}, &f).ok());
}

namespace {

// A gRPC-Web request body: one uncompressed message frame.
std::string grpc_web_body(const google::protobuf::Message& m) {
  const std::string bytes = m.SerializeAsString();
  const auto n = static_cast<std::uint32_t>(bytes.size());
  std::string out(1, '\0');
  for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((n >> shift) & 0xff);
  return out + bytes;
}

// RotateTokens reaches a browser's watch stream: the door relays the server's end of it
// (UNAUTHENTICATED in the trailers) at once, and other sessions keep being served.
TEST(SecurityHttp, RotatingEndsAWatchStreamThroughTheDoor) {
  Door d;
  const pb::Session s = d.t.library_session("cactus");
  const pb::Session other = d.t.library_session("bar");
  pb::WatchSessionRequest w;
  w.set_name(s.name());
  const std::string self = "http://127.0.0.1:" + std::to_string(d.gateway->port());
  auto watch = std::async(std::launch::async, [&] {
    return d.request(http::verb::post, "/hdeform.v1.Deformation/WatchSession",
                     {{"Origin", self},
                      {"Content-Type", "application/grpc-web+proto"},
                      // Ends by itself in any case: a failing test must not hang.
                      {"grpc-timeout", "10S"},
                      {"Authorization", "Bearer " + s.view_token()}},
                     grpc_web_body(w));
  });
  // Open once the session counts the watcher.
  pb::Session now;
  for (int i = 0; i < 200; ++i) {
    ASSERT_TRUE(d.t.get_session(s.name(), &now).ok());
    if (now.observers() > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_GT(now.observers(), 0);

  grpc::ClientContext ctx;
  ctx.AddMetadata("authorization", "Bearer " + s.edit_token());
  pb::RotateTokensRequest r;
  r.set_name(s.name());
  pb::Session rotated;
  ASSERT_TRUE(d.t.bare_stub->RotateTokens(&ctx, r, &rotated).ok());
  ASSERT_EQ(watch.wait_for(std::chrono::seconds(5)), std::future_status::ready)
      << "the watch stream did not end after the rotation";
  const auto [status, body] = watch.get();
  EXPECT_EQ(status, 200);
  EXPECT_NE(body.find("grpc-status:16"), std::string::npos)
      << body.substr(body.size() > 300 ? body.size() - 300 : 0);
  EXPECT_NE(body.find("rotated"), std::string::npos);
  pb::Session got;
  EXPECT_TRUE(d.t.get_session(other.name(), &got).ok());
}

}  // namespace

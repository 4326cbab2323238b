// The gRPC-Web gateway against a fake Deformation service (no engine): framing of unary,
// error and streaming calls, /upload → client-streaming CreateSession, the 413 limit, static
// files, cancellation when the browser goes away, and stop() during a stream. Safe to expose:
// no file outside the web root, no cross-site POST, and bounded cost — header,
// idle and stall timeouts, caps that idle clients cannot exhaust, accept() errors survived.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <vector>
#include <thread>

#include "gateway/grpc_web.h"
#include "gateway/http_gateway.h"
#include "hdeform/v1/deform.grpc.pb.h"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;
using namespace hdeform::v1;
using namespace std::chrono_literals;

class FakeService final : public Deformation::Service {
 public:
  std::atomic<bool> watch_cancelled{false};
  std::atomic<int> watch_running{0};
  std::atomic<int> create_calls{0};

  grpc::Status ListMeshes(grpc::ServerContext*, const ListMeshesRequest*,
                          ListMeshesResponse* out) override {
    out->add_meshes()->set_name("cactus");
    out->add_meshes()->set_name("bar");
    return grpc::Status::OK;
  }
  grpc::Status GetSession(grpc::ServerContext*, const GetSessionRequest* req,
                          Session* out) override {
    if (req->name() == "sessions/missing")
      return {grpc::StatusCode::NOT_FOUND, "no session 'sessions/missing' — 100%"};
    out->set_name(req->name());
    return grpc::Status::OK;
  }
  grpc::Status CreateSession(grpc::ServerContext*, grpc::ServerReader<CreateSessionRequest>* in,
                             Session* out) override {
    ++create_calls;
    CreateSessionRequest msg;
    std::string source, id;
    std::optional<double> repair;
    std::size_t bytes = 0;
    int messages = 0;
    while (in->Read(&msg)) {
      ++messages;
      if (msg.has_header()) {
        source = msg.header().has_filename() ? msg.header().filename() : msg.header().library_mesh();
        id = msg.header().session_id();
        if (msg.header().has_repair()) repair = msg.header().repair().merge_tolerance();
      } else {
        bytes += msg.chunk().size();
      }
    }
    if (source.ends_with(".bad")) return {grpc::StatusCode::INVALID_ARGUMENT, "cannot parse " + source};
    out->set_name("sessions/" + (id.empty() ? std::string("x") : id));
    out->set_mesh_name(source);
    out->set_vertex_count(static_cast<int>(bytes));
    out->set_triangle_count(messages);
    // Echoes the header's repair request (its tolerance as the report's first line).
    if (repair) out->mutable_repair()->add_lines(std::to_string(*repair));
    return grpc::Status::OK;
  }
  grpc::Status WatchSession(grpc::ServerContext* ctx, const WatchSessionRequest* req,
                            grpc::ServerWriter<SessionEvent>* out) override {
    ++watch_running;
    // "sessions/slow" is a quiet stream: a frame every 700 ms, longer than the short
    // timeouts the timeout tests use.
    const auto gap = req->name() == "sessions/slow" ? 700ms : 20ms;
    for (int i = 0; i < 10000 && !ctx->IsCancelled(); ++i) {
      SessionEvent ev;
      ev.mutable_frame()->set_session(req->name());
      ev.mutable_frame()->set_sequence(i);
      if (!out->Write(ev)) break;
      for (auto slept = 0ms; slept < gap && !ctx->IsCancelled(); slept += 10ms) {
        std::this_thread::sleep_for(10ms);
      }
    }
    watch_cancelled = ctx->IsCancelled();
    --watch_running;
    return grpc::Status::OK;
  }
};

struct Frame {
  std::uint8_t flag;
  std::string bytes;
};

// Splits a complete gRPC-Web response body into frames.
std::vector<Frame> frames_of(std::string_view body) {
  std::vector<Frame> out;
  std::size_t at = 0;
  while (at + 5 <= body.size()) {
    const std::uint32_t len = (std::uint32_t(std::uint8_t(body[at + 1])) << 24) |
                              (std::uint32_t(std::uint8_t(body[at + 2])) << 16) |
                              (std::uint32_t(std::uint8_t(body[at + 3])) << 8) |
                              std::uint32_t(std::uint8_t(body[at + 4]));
    if (at + 5 + len > body.size()) break;
    out.push_back({std::uint8_t(body[at]), std::string(body.substr(at + 5, len))});
    at += 5 + len;
  }
  return out;
}

std::string grpc_web_body(const google::protobuf::Message& msg) {
  const std::string bytes = msg.SerializeAsString();
  const auto prefix = hdeform::gateway::grpc_web::frame_prefix(0, static_cast<std::uint32_t>(bytes.size()));
  return std::string(prefix.data(), prefix.size()) + bytes;
}

constexpr std::string_view kSecret = "TOP-SECRET-CONTENT";

class GatewayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // base_/www is the web root; base_/secret.txt lies next to it and must never be served.
    base_ = std::filesystem::temp_directory_path() /
            ("hdeform-gw-" + std::to_string(::getpid()) + "-" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    root_ = base_ / "www";
    std::filesystem::create_directories(root_ / "assets");
    std::ofstream(base_ / "secret.txt") << kSecret;
    std::ofstream(root_ / "index.html") << "<!doctype html><title>viewer</title>";
    std::ofstream(root_ / "assets" / "app-123.js") << "console.log(1)";
    grpc::ServerBuilder builder;
    builder.RegisterService(&service_);
    server_ = builder.BuildAndStart();
    restart([](hdeform::gateway::GatewayOptions&) {});
  }

  // A fresh gateway with the fixture's options changed by `tweak`.
  void restart(const std::function<void(hdeform::gateway::GatewayOptions&)>& tweak) {
    gateway_.reset();
    hdeform::gateway::GatewayOptions options;
    options.port = 0;
    options.web_root = root_.string();
    options.max_body_bytes = 1u << 20;
    tweak(options);
    gateway_ = std::make_unique<hdeform::gateway::HttpGateway>(options, server_->InProcessChannel({}));
  }
  void TearDown() override {
    gateway_.reset();
    server_->Shutdown(std::chrono::system_clock::now() + 1s);
    std::filesystem::remove_all(base_);
  }

  tcp::socket connect() {
    tcp::socket s(ioc_);
    s.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(gateway_->port())});
    return s;
  }

  using Headers = std::vector<std::pair<std::string, std::string>>;

  http::response<http::string_body> request(http::verb verb, const std::string& target,
                                            std::string body = {},
                                            const std::string& content_type = "application/grpc-web+proto",
                                            const Headers& headers = {}) {
    auto s = connect();
    http::request<http::string_body> req{verb, target, 11};
    req.set(http::field::host, "127.0.0.1");
    if (!content_type.empty()) req.set(http::field::content_type, content_type);
    for (const auto& [name, value] : headers) req.set(name, value);
    req.body() = std::move(body);
    req.prepare_payload();
    http::write(s, req);
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    http::read(s, buffer, res);
    return res;
  }

  // Sends `bytes` as they are (for targets an HTTP library would refuse to write) and reads one
  // response; a connection closed without an answer gives status 0.
  http::response<http::string_body> raw_request(const std::string& bytes) {
    auto s = connect();
    asio::write(s, asio::buffer(bytes));
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    beast::error_code ec;
    http::read(s, buffer, res, ec);
    if (ec) res.result(0);
    return res;
  }

  // Sends `bytes` and returns everything the server sends back within `timeout` or until it
  // closes the connection (an unanswered request gives "").
  static std::string exchange_within(tcp::socket& s, const std::string& bytes,
                                     std::chrono::milliseconds timeout) {
    beast::error_code ec;
    asio::write(s, asio::buffer(bytes), ec);
    std::string out;
    char buf[4096];
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                            deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) break;
      pollfd p{s.native_handle(), POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      const auto n = ::recv(s.native_handle(), buf, sizeof buf, 0);
      if (n <= 0) break;
      out.append(buf, static_cast<std::size_t>(n));
    }
    return out;
  }

  // GET on a fresh connection, answered within `timeout`: the whole raw response, or "".
  std::string get_within(const std::string& target, std::chrono::milliseconds timeout) {
    auto s = connect();
    return exchange_within(
        s, "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n",
        timeout);
  }

  // Starts a streaming WatchSession call and reads the response header; the frames follow
  // through `parser` (read_frames).
  tcp::socket watch(const std::string& session, beast::flat_buffer& buffer,
                    http::response_parser<http::buffer_body>& parser,
                    const std::string& grpc_timeout = "") {
    auto s = connect();
    WatchSessionRequest req;
    req.set_name(session);
    http::request<http::string_body> r{http::verb::post, "/hdeform.v1.Deformation/WatchSession",
                                       11};
    r.set(http::field::host, "127.0.0.1:" + std::to_string(gateway_->port()));
    r.set(http::field::origin, "http://127.0.0.1:" + std::to_string(gateway_->port()));
    r.set(http::field::content_type, "application/grpc-web+proto");
    if (!grpc_timeout.empty()) r.set("grpc-timeout", grpc_timeout);
    r.body() = grpc_web_body(req);
    r.prepare_payload();
    http::write(s, r);
    http::read_header(s, buffer, parser);
    return s;
  }

  http::response<http::string_body> call(const std::string& method, const google::protobuf::Message& msg) {
    return request(http::verb::post, "/hdeform.v1.Deformation/" + method, grpc_web_body(msg));
  }

  asio::io_context ioc_;
  FakeService service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<hdeform::gateway::HttpGateway> gateway_;
  std::filesystem::path base_, root_;
};

TEST_F(GatewayTest, UnaryCallIsFramedWithTrailers) {
  const auto res = call("ListMeshes", ListMeshesRequest());
  EXPECT_EQ(res.result(), http::status::ok);
  EXPECT_EQ(res[http::field::content_type], "application/grpc-web+proto");
  const auto frames = frames_of(res.body());
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].flag, 0x00);
  ListMeshesResponse reply;
  ASSERT_TRUE(reply.ParseFromString(frames[0].bytes));
  ASSERT_EQ(reply.meshes_size(), 2);
  EXPECT_EQ(reply.meshes(0).name(), "cactus");
  EXPECT_EQ(frames[1].flag, 0x80);
  EXPECT_NE(frames[1].bytes.find("grpc-status:0\r\n"), std::string::npos);
}

TEST_F(GatewayTest, ErrorsTravelInTheTrailersPercentEncoded) {
  GetSessionRequest req;
  req.set_name("sessions/missing");
  const auto frames = frames_of(call("GetSession", req).body());
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].flag, 0x80);
  EXPECT_NE(frames[0].bytes.find("grpc-status:5\r\n"), std::string::npos);
  EXPECT_NE(frames[0].bytes.find("grpc-message:no session 'sessions/missing' %E2%80%94 100%25\r\n"),
            std::string::npos)
      << frames[0].bytes;
}

TEST_F(GatewayTest, UnknownMethodIsUnimplemented) {
  const auto frames = frames_of(call("NoSuchMethod", ListMeshesRequest()).body());
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_NE(frames[0].bytes.find("grpc-status:12\r\n"), std::string::npos);
}

TEST_F(GatewayTest, RejectsOtherContentTypesAndPaths) {
  EXPECT_EQ(request(http::verb::post, "/hdeform.v1.Deformation/ListMeshes", "", "application/json").result(),
            http::status::unsupported_media_type);
  EXPECT_EQ(request(http::verb::get, "/hdeform.v1.Deformation/ListMeshes").result(),
            http::status::method_not_allowed);
}

TEST_F(GatewayTest, UploadBecomesClientStreamingCreateSession) {
  const std::string file(3'500'000, 'v');  // > 1 MiB chunk, < 4 MiB gRPC limit per message
  // The fixture's limit is 1 MiB: raise it for this test with a fresh gateway.
  gateway_.reset();
  hdeform::gateway::GatewayOptions options;
  options.port = 0;
  options.max_body_bytes = 8u << 20;
  gateway_ = std::make_unique<hdeform::gateway::HttpGateway>(options, server_->InProcessChannel({}));

  auto res = request(http::verb::post, "/upload?filename=my%20mesh.obj&session_id=abc", file,
                     "application/octet-stream", {{"X-Session-Id", "abc"}});
  ASSERT_EQ(res.result(), http::status::ok) << res.body();
  EXPECT_EQ(res[http::field::content_type], "application/x-protobuf");
  Session s;
  ASSERT_TRUE(s.ParseFromString(res.body()));
  EXPECT_EQ(s.name(), "sessions/abc");
  EXPECT_EQ(s.mesh_name(), "my mesh.obj");
  EXPECT_EQ(s.vertex_count(), static_cast<int>(file.size()));  // every byte arrived
  EXPECT_GE(s.triangle_count(), 1 + 4);                         // header + ≥ 4 chunks

  res = request(http::verb::post, "/upload?library=cactus", "", "", {{"X-Hdeform-Upload", "1"}});
  ASSERT_EQ(res.result(), http::status::ok);
  ASSERT_TRUE(s.ParseFromString(res.body()));
  EXPECT_EQ(s.mesh_name(), "cactus");

  res = request(http::verb::post, "/upload?filename=broken.bad", "xx", "application/octet-stream",
                {{"X-Hdeform-Upload", "1"}});
  EXPECT_EQ(res.result(), http::status::bad_request);
  EXPECT_EQ(res.body(), "cannot parse broken.bad\n");
  EXPECT_EQ(res["grpc-status"], "3");

  res = request(http::verb::post, "/upload", "xx", "application/octet-stream",
                {{"X-Hdeform-Upload", "1"}});
  EXPECT_EQ(res.result(), http::status::bad_request);

  // &repair=TOL becomes CreateSessionHeader.repair; anything but a number is refused here.
  res = request(http::verb::post, "/upload?filename=m.obj&repair=0.001", "v 0 0 0\n",
                "application/octet-stream", {{"X-Hdeform-Upload", "1"}});
  ASSERT_EQ(res.result(), http::status::ok) << res.body();
  ASSERT_TRUE(s.ParseFromString(res.body()));
  ASSERT_EQ(s.repair().lines_size(), 1);
  EXPECT_EQ(s.repair().lines(0), std::to_string(0.001));
  res = request(http::verb::post, "/upload?filename=m.obj", "v 0 0 0\n",
                "application/octet-stream", {{"X-Hdeform-Upload", "1"}});
  ASSERT_TRUE(s.ParseFromString(res.body()));
  EXPECT_FALSE(s.has_repair());
  res = request(http::verb::post, "/upload?filename=m.obj&repair=yes", "v 0 0 0\n",
                "application/octet-stream", {{"X-Hdeform-Upload", "1"}});
  EXPECT_EQ(res.result(), http::status::bad_request);
  EXPECT_NE(res.body().find("repair must be a number"), std::string::npos) << res.body();
}

TEST_F(GatewayTest, BodyAboveTheLimitGets413) {
  const auto res = request(http::verb::post, "/upload?filename=big.obj", std::string(2u << 20, 'x'),
                           "application/octet-stream");
  EXPECT_EQ(res.result(), http::status::payload_too_large);
  EXPECT_NE(res.body().find("the limit is 1048576 bytes"), std::string::npos) << res.body();
}

TEST_F(GatewayTest, StaticFilesWithContentTypes) {
  auto res = request(http::verb::get, "/", "", "");
  EXPECT_EQ(res.result(), http::status::ok);
  EXPECT_EQ(res[http::field::content_type], "text/html; charset=utf-8");
  EXPECT_EQ(res[http::field::cache_control], "no-cache");
  res = request(http::verb::get, "/assets/app-123.js?v=1", "", "");
  EXPECT_EQ(res.result(), http::status::ok);
  EXPECT_EQ(res[http::field::content_type], "text/javascript; charset=utf-8");
  EXPECT_EQ(res.body(), "console.log(1)");
  EXPECT_NE(res[http::field::cache_control].find("immutable"), beast::string_view::npos);
  EXPECT_EQ(request(http::verb::get, "/nope.css", "", "").result(), http::status::not_found);
  EXPECT_EQ(request(http::verb::get, "/../etc/passwd", "", "").result(), http::status::bad_request);
  EXPECT_EQ(request(http::verb::get, "/%2e%2e/etc/passwd", "", "").result(), http::status::bad_request);
  EXPECT_EQ(request(http::verb::get, "/healthz", "", "").body(), "ok\n");
}

// Every way of naming a file outside the web root (absolute after decoding, "..", encoded
// and doubly encoded separators, backslashes, NUL, symlinks out of the root) and every
// non-regular file gives 400 or 404, and never the bytes of the file next to the root.
TEST_F(GatewayTest, StaticFilesNeverEscapeTheWebRoot) {
  namespace fs = std::filesystem;
  fs::create_symlink(base_ / "secret.txt", root_ / "escape.txt");        // file link out
  fs::create_directory_symlink(base_, root_ / "up");                     // folder link out
  fs::create_symlink("/dev/zero", root_ / "zero");                       // device
  fs::create_directory(root_ / "empty");                                 // no index.html
  ASSERT_EQ(::mkfifo((root_ / "pipe").c_str(), 0600), 0);                // opening would block
  std::string secret = (base_ / "secret.txt").string();                  // "/tmp/…/secret.txt"
  std::string secret_encoded;                                            // every '/' as %2F
  for (const char c : secret) secret_encoded += c == '/' ? std::string("%2F") : std::string(1, c);
  std::string secret_double;                                             // every '/' as %252F
  for (const char c : secret) secret_double += c == '/' ? std::string("%252F") : std::string(1, c);

  const std::vector<std::string> targets = {
      "//etc/passwd", "/%2Fetc%2Fpasswd", "/%2fetc/passwd", "/%252Fetc%252Fpasswd",
      "/" + secret, "/" + secret_encoded, "/" + secret_double, "/." + secret,
      "/../secret.txt", "/./../secret.txt", "/assets/../../secret.txt", "/..%2Fsecret.txt",
      "/%2e%2e/secret.txt", "/%2E%2E%2Fsecret.txt", "/%252e%252e/secret.txt",
      "/%252e%252e%252Fsecret.txt", "/..\\secret.txt", "/..%5Csecret.txt", "/%5C..%5Csecret.txt",
      "/index.html%00", "/%00/../secret.txt", "/escape.txt%00.js", "/escape.txt",
      "/up/secret.txt", "/up%2Fsecret.txt", "/zero", "/pipe", "/empty",
      "/empty/", "/assets", "/assets/"};
  for (const auto& target : targets) {
    const auto res = raw_request("GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    EXPECT_TRUE(res.result() == http::status::bad_request ||
                res.result() == http::status::not_found)
        << target << " → " << res.result_int();
    EXPECT_EQ(res.body().find(kSecret), std::string::npos) << target;
    EXPECT_EQ(res.body().find("root:"), std::string::npos) << target;
  }
  // Links and folders that stay inside the root still work.
  fs::create_symlink(root_ / "index.html", root_ / "home.html");
  fs::create_directory(root_ / "sub");
  std::ofstream(root_ / "sub" / "index.html") << "sub";
  EXPECT_EQ(request(http::verb::get, "/home.html", "", "").result(), http::status::ok);
  EXPECT_EQ(request(http::verb::get, "/sub/", "", "").body(), "sub");
  EXPECT_EQ(request(http::verb::get, "/sub", "", "").body(), "sub");
  EXPECT_EQ(request(http::verb::get, "//assets//app-123.js", "", "").body(), "console.log(1)");
}

// A web root that is itself reached through a symlink is resolved once, at start.
TEST_F(GatewayTest, WebRootBehindASymlinkServesItsFiles) {
  std::filesystem::create_directory_symlink(root_, base_ / "www-link");
  gateway_.reset();
  hdeform::gateway::GatewayOptions options;
  options.port = 0;
  options.web_root = (base_ / "www-link").string();
  gateway_ = std::make_unique<hdeform::gateway::HttpGateway>(options, server_->InProcessChannel({}));
  EXPECT_EQ(request(http::verb::get, "/assets/app-123.js", "", "").body(), "console.log(1)");
  EXPECT_EQ(request(http::verb::get, "/../secret.txt", "", "").result(), http::status::bad_request);
}

// Reads a chunked streaming response until `count` data frames arrived.
std::string read_frames(tcp::socket& s, beast::flat_buffer& buffer,
                        http::response_parser<http::buffer_body>& parser, std::size_t count) {
  std::string body;
  char chunk[4096];
  while (frames_of(body).size() < count && !parser.is_done()) {
    parser.get().body().data = chunk;
    parser.get().body().size = sizeof chunk;
    beast::error_code ec;
    http::read_some(s, buffer, parser, ec);  // returns as soon as some body arrived
    if (ec && ec != http::error::need_buffer) break;
    body.append(chunk, sizeof chunk - parser.get().body().size);
  }
  return body;
}

TEST_F(GatewayTest, ServerStreamIsRelayedAndCancelledWhenTheBrowserLeaves) {
  beast::flat_buffer buffer;
  http::response_parser<http::buffer_body> parser;
  auto s = watch("sessions/w", buffer, parser);
  EXPECT_TRUE(parser.get().chunked());
  const auto frames = frames_of(read_frames(s, buffer, parser, 3));
  ASSERT_GE(frames.size(), 3u);
  SessionEvent ev;
  ASSERT_TRUE(ev.ParseFromString(frames[2].bytes));
  EXPECT_EQ(ev.frame().sequence(), 2);
  EXPECT_EQ(ev.frame().session(), "sessions/w");

  s.close();  // the browser goes away
  for (int i = 0; i < 300 && service_.watch_running > 0; ++i) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(service_.watch_running, 0);
  EXPECT_TRUE(service_.watch_cancelled);
}

TEST_F(GatewayTest, StopEndsStreamsWithUnavailable) {
  beast::flat_buffer buffer;
  http::response_parser<http::buffer_body> parser;
  auto s = watch("sessions/w", buffer, parser);
  read_frames(s, buffer, parser, 1);
  auto idle = connect();  // an idle keep-alive connection must not block stop()

  const auto t0 = std::chrono::steady_clock::now();
  std::thread stopper([&] { gateway_->stop(); });
  const std::string rest = read_frames(s, buffer, parser, 1u << 30);
  stopper.join();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 3s);
  EXPECT_NE(rest.find("grpc-status:14\r\n"), std::string::npos);
  EXPECT_TRUE(parser.is_done());
}

// Whether the server closes (or resets) `s` within `timeout`; data it sends is discarded.
bool closed_within(tcp::socket& s, std::chrono::milliseconds timeout) {
  char buf[4096];
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) return false;
    pollfd p{s.native_handle(), POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
    if (::recv(s.native_handle(), buf, sizeof buf, 0) <= 0) return true;
  }
}

// ---- cross-site requests ------------------------------------------------------------------

TEST_F(GatewayTest, CrossSiteUploadIsRefused) {
  const std::string self = "127.0.0.1:" + std::to_string(gateway_->port());
  // What a page on another site can make a browser send without a preflight: text/plain.
  auto res = request(http::verb::post, "/upload?filename=x.obj", "v 0 0 0", "text/plain",
                     {{"Host", self}, {"Origin", "https://evil.example"}});
  EXPECT_EQ(res.result(), http::status::forbidden);
  EXPECT_NE(res.body().find("cross-site request refused"), std::string::npos) << res.body();
  // A foreign Origin is refused even with the custom header; so are "null" and look-alikes.
  for (const std::string& origin : std::vector<std::string>{
           "https://evil.example", "null", "http://" + self + ".evil.example",
           "http://evil.example/" + self, "http://127.0.0.1:1"}) {
    res = request(http::verb::post, "/upload?library=cactus", "", "text/plain",
                  {{"Host", self}, {"Origin", origin}, {"X-Session-Id", "s"}});
    EXPECT_EQ(res.result(), http::status::forbidden) << origin;
  }
  // A browser that sends no Origin cannot add the custom header cross-site: without it, 403.
  res = request(http::verb::post, "/upload?library=cactus", "", "text/plain");
  EXPECT_EQ(res.result(), http::status::forbidden);
  EXPECT_NE(res.body().find("X-Hdeform-Upload"), std::string::npos) << res.body();
  EXPECT_EQ(service_.create_calls, 0);

  // The viewer: same origin, X-Session-Id on every upload; behind a proxy too.
  res = request(http::verb::post, "/upload?library=cactus&session_id=v", "", "",
                {{"Host", self}, {"Origin", "http://" + self}, {"X-Session-Id", "v"}});
  EXPECT_EQ(res.result(), http::status::ok) << res.body();
  // Behind a proxy the operator names the hosts it passes on (DNS rebinding: request_checks.h).
  res = request(http::verb::post, "/upload?library=cactus", "", "",
                {{"Host", "hdeform.example"}, {"Origin", "https://hdeform.example"},
                 {"X-Session-Id", "v"}});
  EXPECT_EQ(res.result(), http::status::misdirected_request) << res.body();
  restart([](hdeform::gateway::GatewayOptions& o) { o.allowed_hosts = {"hdeform.example", "backend"}; });
  res = request(http::verb::post, "/upload?library=cactus", "", "",
                {{"Host", "Hdeform.Example"}, {"Origin", "https://hdeform.example:443"},
                 {"X-Session-Id", "v"}});
  EXPECT_EQ(res.result(), http::status::ok) << res.body();
  res = request(http::verb::post, "/upload?library=cactus", "", "",
                {{"Host", "backend:8080"}, {"X-Forwarded-Host", "hdeform.example, inner"},
                 {"Origin", "https://hdeform.example"}, {"X-Hdeform-Upload", "1"}});
  EXPECT_EQ(res.result(), http::status::ok) << res.body();
  EXPECT_EQ(service_.create_calls, 3);
}

TEST_F(GatewayTest, CrossSiteGrpcWebCallIsRefused) {
  const std::string self = "127.0.0.1:" + std::to_string(gateway_->port());
  const auto body = grpc_web_body(ListMeshesRequest());
  auto res = request(http::verb::post, "/hdeform.v1.Deformation/ListMeshes", body,
                     "application/grpc-web+proto", {{"Host", self}, {"Origin", "https://evil.example"}});
  EXPECT_EQ(res.result(), http::status::forbidden);
  res = request(http::verb::post, "/hdeform.v1.Deformation/ListMeshes", body,
                "application/grpc-web+proto", {{"Host", self}, {"Origin", "http://" + self}});
  EXPECT_EQ(res.result(), http::status::ok);
  EXPECT_EQ(frames_of(res.body()).size(), 2u);
}

// ---- bounded cost: timeouts and caps --------------------------------------------------------

TEST_F(GatewayTest, IdleSocketsDoNotLockOutClients) {
  std::vector<tcp::socket> idle;
  for (int i = 0; i < 300; ++i) idle.push_back(connect());
  auto res = get_within("/healthz", 2s);
  EXPECT_NE(res.find("200 OK"), std::string::npos) << res;
  EXPECT_TRUE(res.ends_with("\r\n\r\nok\n")) << res;

  // Above max_idle_connections the oldest waiting connections are closed instead.
  idle.clear();
  restart([](auto& o) { o.max_idle_connections = 50; });
  for (int i = 0; i < 300; ++i) idle.push_back(connect());
  res = get_within("/healthz", 2s);
  EXPECT_TRUE(res.ends_with("\r\n\r\nok\n")) << res;
  EXPECT_TRUE(closed_within(idle.front(), 2s));
  EXPECT_FALSE(closed_within(idle.back(), 100ms));
}

TEST_F(GatewayTest, SilentAndSlowClientsAreDroppedAfterTheHeaderTimeout) {
  restart([](auto& o) { o.header_timeout = 500ms; });
  auto silent = connect();
  auto slow = connect();
  const auto t0 = std::chrono::steady_clock::now();
  // A slowloris client: one header byte every 100 ms, never done within 500 ms.
  const std::string header =
      "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Padding: aaaaaaaaaaaaaaaaaaaaaaaa\r\n\r\n";
  bool slow_closed = false;
  for (std::size_t i = 0; i < header.size() && !slow_closed; ++i) {
    beast::error_code ec;
    asio::write(slow, asio::buffer(&header[i], 1), ec);
    slow_closed = ec || closed_within(slow, 100ms);
  }
  const auto slow_lasted = std::chrono::steady_clock::now() - t0;
  EXPECT_TRUE(slow_closed);
  EXPECT_GE(slow_lasted, 400ms);
  EXPECT_LT(slow_lasted, 2s);
  EXPECT_TRUE(closed_within(silent, 1s));
}

TEST_F(GatewayTest, IdleKeepAliveConnectionIsClosedAfterTheIdleTimeout) {
  restart([](auto& o) { o.idle_timeout = 500ms; });
  auto s = connect();
  beast::flat_buffer buffer;
  for (int i = 0; i < 3; ++i) {  // keep-alive still works below the timeout
    http::request<http::empty_body> req{http::verb::get, "/healthz", 11};
    req.set(http::field::host, "127.0.0.1");
    http::write(s, req);
    http::response<http::string_body> res;
    http::read(s, buffer, res);
    EXPECT_EQ(res.body(), "ok\n");
    std::this_thread::sleep_for(300ms);
  }
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(closed_within(s, 2s));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 500ms);  // 300 ms of 500 were already idle
}

TEST_F(GatewayTest, StalledBodyIsDroppedAfterTheStallTimeout) {
  restart([](auto& o) { o.stall_timeout = 500ms; });
  for (const std::string target : {"/upload?filename=a.obj", "/hdeform.v1.Deformation/ListMeshes"}) {
    auto s = connect();
    const std::string head = "POST " + target +
                             " HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Hdeform-Upload: 1\r\nContent-Type: "
                             "application/grpc-web+proto\r\nContent-Length: 1000\r\n\r\n0123456789";
    asio::write(s, asio::buffer(head));
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_TRUE(closed_within(s, 3s)) << target;
    EXPECT_GE(std::chrono::steady_clock::now() - t0, 400ms) << target;
  }
  // The gateway still serves.
  EXPECT_TRUE(get_within("/healthz", 2s).ends_with("ok\n"));
}

TEST_F(GatewayTest, QuietStreamOutlivesTheTimeouts) {
  restart([](auto& o) {
    o.header_timeout = 300ms;
    o.idle_timeout = 300ms;
    o.stall_timeout = 300ms;
  });
  beast::flat_buffer buffer;
  http::response_parser<http::buffer_body> parser;
  auto s = watch("sessions/slow", buffer, parser);  // a frame every 700 ms
  const auto frames = frames_of(read_frames(s, buffer, parser, 3));
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].flag, 0x00);
}

// grpc-timeout becomes the call's deadline (set before the call is prepared: gRPC ignores a
// deadline set later).
TEST_F(GatewayTest, GrpcTimeoutEndsTheCallAtItsDeadline) {
  beast::flat_buffer buffer;
  http::response_parser<http::buffer_body> parser;
  const auto t0 = std::chrono::steady_clock::now();
  auto s = watch("sessions/slow", buffer, parser, "1000m");  // a frame every 700 ms
  const auto frames = frames_of(read_frames(s, buffer, parser, 10));
  const auto took = std::chrono::steady_clock::now() - t0;
  ASSERT_FALSE(frames.empty());
  EXPECT_EQ(frames.back().flag, 0x80);  // the trailers
  EXPECT_NE(frames.back().bytes.find("grpc-status:4"), std::string::npos) << frames.back().bytes;
  EXPECT_LT(took, 5s);
  EXPECT_GE(took, 900ms);
}

TEST_F(GatewayTest, RequestsAboveTheCapGet503) {
  restart([](auto& o) { o.max_connections = 1; });
  {
    beast::flat_buffer buffer;
    http::response_parser<http::buffer_body> parser;
    auto s = watch("sessions/w", buffer, parser);  // holds the only request slot
    read_frames(s, buffer, parser, 1);
    const auto res = request(http::verb::get, "/healthz", "", "");
    EXPECT_EQ(res.result(), http::status::service_unavailable);
    EXPECT_NE(res.body().find("busy"), std::string::npos) << res.body();
    EXPECT_EQ(res[http::field::retry_after], "1");
  }  // the stream's client goes away: its slot frees once the call is cancelled
  std::string res;
  for (int i = 0; i < 40 && !res.ends_with("ok\n"); ++i) {
    std::this_thread::sleep_for(100ms);
    res = get_within("/healthz", 1s);
  }
  EXPECT_TRUE(res.ends_with("ok\n")) << res;
}

TEST_F(GatewayTest, StopIsPromptWithIdleHalfOpenStalledAndStreamingConnections) {
  beast::flat_buffer buffer;
  http::response_parser<http::buffer_body> parser;
  auto stream = watch("sessions/w", buffer, parser);
  read_frames(stream, buffer, parser, 1);
  std::vector<tcp::socket> idle;
  for (int i = 0; i < 20; ++i) idle.push_back(connect());
  auto partial = connect();
  asio::write(partial, asio::buffer(std::string("GET / HTTP/1.1\r\nHo")));
  auto half_closed = connect();
  asio::write(half_closed, asio::buffer(std::string("GET / HT")));
  half_closed.shutdown(tcp::socket::shutdown_send);
  auto stalled = connect();  // a worker waits for this body
  asio::write(stalled, asio::buffer(std::string(
                           "POST /upload?filename=a.obj HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                           "X-Hdeform-Upload: 1\r\nContent-Length: 100\r\n\r\nv 0")));
  std::this_thread::sleep_for(200ms);

  const auto t0 = std::chrono::steady_clock::now();
  gateway_->stop();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 3s);
  EXPECT_TRUE(closed_within(idle.front(), 1s));
  EXPECT_TRUE(closed_within(partial, 1s));
  EXPECT_TRUE(closed_within(stalled, 1s));
  const std::string rest = read_frames(stream, buffer, parser, 1u << 30);
  EXPECT_NE(rest.find("grpc-status:14\r\n"), std::string::npos);
}

// accept() failing (here EMFILE: no descriptor left for the new connection) must pause
// accepting, not end it: once descriptors are free again the waiting client is served.
TEST_F(GatewayTest, AcceptingSurvivesRunningOutOfDescriptors) {
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &old), 0);
  int highest = 0;
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) {
    highest = std::max(highest, std::stoi(e.path().filename().string()));
  }
  struct Restore {  // whatever happens, give the descriptors and the limit back
    rlimit limit;
    std::vector<int> fds;
    ~Restore() {
      for (const int fd : fds) ::close(fd);
      ::setrlimit(RLIMIT_NOFILE, &limit);
    }
  } restore{old, {}};
  tcp::socket s(ioc_);  // the client's socket (and its io_context's epoll) exist already
  s.open(tcp::v4());
  rlimit low = old;
  low.rlim_cur = static_cast<rlim_t>(highest + 16);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  for (int fd; (fd = ::open("/dev/null", O_RDONLY)) >= 0;) restore.fds.push_back(fd);
  ASSERT_FALSE(restore.fds.empty());
  s.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(gateway_->port())});
  std::this_thread::sleep_for(300ms);  // accept() fails with EMFILE meanwhile, and retries
  for (const int fd : restore.fds) ::close(fd);
  restore.fds.clear();
  ::setrlimit(RLIMIT_NOFILE, &old);
  // What must survive is accepting: a new connection is served. (The one that queued while
  // descriptors ran out is usually served too, but under load the kernel or the back-off
  // may drop it; CI once saw that, so it is only logged.)
  const auto queued = exchange_within(
      s, "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n", 3s);
  if (!queued.ends_with("\r\n\r\nok\n")) std::printf("queued connection lost: '%s'\n", queued.c_str());
  tcp::socket fresh(ioc_);
  fresh.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(gateway_->port())});
  const auto res = exchange_within(
      fresh, "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n", 3s);
  EXPECT_TRUE(res.ends_with("\r\n\r\nok\n")) << res;
}

}  // namespace

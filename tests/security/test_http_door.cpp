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
#include <functional>
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

  explicit Door(std::vector<std::string> allowed_hosts = {},
                std::function<void(hdeform::gateway::GatewayOptions&)> tweak = {})
      : dir([] {
          std::string tmpl = (fs::temp_directory_path() / "hdeform-door-XXXXXX").string();
          return fs::path(::mkdtemp(tmpl.data()));
        }()) {
    fs::create_directories(dir / "root" / "assets");
    std::ofstream(dir / "root" / "index.html") << "<html>viewer</html>";
    std::ofstream(dir / "secret.txt") << "TOP-SECRET";
    fs::create_symlink(dir / "secret.txt", dir / "root" / "assets" / "link.txt");
    hdeform::gateway::GatewayOptions o;
    o.port = 0;
    o.web_root = (dir / "root").string();
    o.allowed_hosts = std::move(allowed_hosts);
    if (tweak) tweak(o);
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

  // Raw bytes as the request; the answer must begin within 5 s (else status 0), so a door
  // that never answers fails the test instead of hanging it.
  std::pair<int, std::string> raw(const std::string& bytes) {
    asio::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect({asio::ip::make_address("127.0.0.1"),
                    static_cast<unsigned short>(gateway->port())});
    asio::write(socket, asio::buffer(bytes));
    // Asynchronous, to have a deadline (a blocking asio read would wait forever).
    beast::tcp_stream stream(std::move(socket));
    stream.expires_after(std::chrono::seconds(5));
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    beast::error_code ec;
    http::async_read(stream, buffer, res, [&](beast::error_code e, std::size_t) { ec = e; });
    ioc.run();
    if (ec && res.result_int() == 200 && res.body().empty()) return {0, ec.message()};
    return {static_cast<int>(res.result_int()), res.body()};
  }
  std::string host() const { return "127.0.0.1:" + std::to_string(gateway->port()); }
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

namespace {

std::string frames(const std::vector<std::string>& messages) {
  std::string out;
  for (const auto& m : messages) {
    const auto n = static_cast<std::uint32_t>(m.size());
    out += '\0';
    for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((n >> shift) & 0xff);
    out += m;
  }
  return out;
}

std::string grpc_web_post(const std::string& host, const std::string& method,
                          const std::string& body) {
  return "POST /hdeform.v1.Deformation/" + method + " HTTP/1.1\r\nHost: " + host +
         "\r\nContent-Type: application/grpc-web+proto\r\nContent-Length: " +
         std::to_string(body.size()) + "\r\n\r\n" + body;
}

// Issue 35.1: a unary call the backend would never answer (two messages, none, a body ending
// mid-frame, an unknown method) is refused at once, and many of them leave the door serving.
TEST(SecurityHttp, AUnaryCallWithOtherThanOneMessageIsRefusedAtOnce) {
  Door d;
  const pb::Session s = constrained_cactus(d.t);
  const std::string list = pb::ListMeshesRequest().SerializeAsString();
  struct Case {
    std::string method, body, status, text;
  };
  const std::vector<Case> cases = {
      {"ListMeshes", frames({list, list}), "grpc-status:3", "exactly one request message"},
      {"ListSessions", frames({list, list, list}), "grpc-status:3", "the body holds 3"},
      {"ListMeshes", "", "grpc-status:3", "the body holds 0"},
      {"ListMeshes", frames({list}).substr(0, 3), "grpc-status:3", "truncated"},
      {"GetSession", std::string("\0\0\0\0\x09" "abc", 8), "grpc-status:3", "truncated"},
      {"NoSuchMethod", frames({list}), "grpc-status:12", "has no method 'NoSuchMethod'"},
  };
  for (int round = 0; round < 100; ++round) {
    for (const auto& c : cases) {
      const auto [status, body] = d.raw(grpc_web_post(d.host(), c.method, c.body));
      ASSERT_EQ(status, 200) << c.method << ": " << body;
      ASSERT_NE(body.find(c.status), std::string::npos) << c.method << ": " << body;
      ASSERT_NE(body.find(c.text), std::string::npos) << c.method << ": " << body;
    }
  }
  // One message is still a call.
  const auto [status, body] = d.raw(grpc_web_post(d.host(), "ListMeshes", frames({list})));
  EXPECT_NE(body.find("grpc-status:0"), std::string::npos) << body;
  EXPECT_NE(body.find("cactus"), std::string::npos);
  pb::Frame f;
  EXPECT_TRUE(d.t.update(s.name(), 1, {cactus_transform()}, &f).ok());
}

// Issue 35.4, DNS rebinding: a page on evil.example whose name resolves to this server is
// same-origin by the browser's rules; its Host names it, and the door refuses it (421)
// before anything runs. Localhost names, IP literals and --allowed-hosts pass.
TEST(SecurityHttp, ARequestForAHostNameNotAllowedIsMisdirected) {
  Door d({"viewer.example", ".team.example"});
  const std::string port = std::to_string(d.gateway->port());
  const auto upload = [&](const std::string& host, const std::string& id) {
    return d.raw("POST /upload?library=cactus&session_id=" + id + " HTTP/1.1\r\nHost: " + host +
                 "\r\nOrigin: http://" + host + "\r\nX-Hdeform-Upload: 1\r\n" +
                 "Content-Length: 0\r\n\r\n");
  };
  for (const std::string& host : std::vector<std::string>{"evil.example:" + port, "evil.example", "localhost.evil.example",
                                 "viewer.example.evil", "x.viewer.example", "team.example", "[::1%eth0]:" + port,
                                 "evil.example:" + port + "@127.0.0.1", "bad host", ""}) {
    const auto [status, body] = upload(host, "rebound");
    EXPECT_EQ(status, 421) << "Host '" << host << "': " << body;
    EXPECT_NE(body.find("misdirected request"), std::string::npos) << body;
    pb::Session none;
    EXPECT_EQ(d.t.get_session("sessions/rebound", &none).error_code(), grpc::StatusCode::NOT_FOUND);
    const auto [get_status, page] =
        d.raw("GET / HTTP/1.1\r\nHost: " + host + "\r\nConnection: close\r\n\r\n");
    EXPECT_EQ(get_status, 421) << host;
    EXPECT_EQ(page.find("<html>"), std::string::npos);
  }
  // No Host at all (HTTP/1.1 requires one) is refused too.
  EXPECT_EQ(d.raw("GET / HTTP/1.1\r\nConnection: close\r\n\r\n").first, 421);
  int n = 0;
  for (const std::string& host : std::vector<std::string>{"localhost:" + port, "LocalHost", "app.localhost:" + port,
                                 "127.0.0.1:" + port, "[::1]:" + port, "10.1.2.3",
                                 "viewer.example", "Viewer.Example.:443", "a.team.example"}) {
    const auto [status, body] = upload(host, "ok" + std::to_string(++n));
    EXPECT_EQ(status, 200) << "Host '" << host << "': " << body;
  }
  EXPECT_THROW(hdeform::gateway::HttpGateway(
                   [] {
                     hdeform::gateway::GatewayOptions o;
                     o.port = 0;
                     o.allowed_hosts = {"bad name/"};
                     return o;
                   }(),
                   d.t.server->in_process_channel()),
               std::invalid_argument);
}

// Issue 35.5: a body whose length two parsers could read differently (request smuggling
// through a proxy) is 400 before anything runs; plain chunked bodies still work.
TEST(SecurityHttp, AnAmbiguousTransferEncodingIsABadRequest) {
  Door d;
  const std::string head =
      "POST /upload?library=cactus&session_id=smuggled HTTP/1.1\r\nHost: " + d.host() +
      "\r\nX-Hdeform-Upload: 1\r\n";
  for (const std::string& framing : std::vector<std::string>{
           "Transfer-Encoding: xchunked\r\nContent-Length: 0\r\n",
        "Transfer-Encoding: chunked, identity\r\n", "Transfer-Encoding: identity\r\n",
        "Transfer-Encoding: gzip, chunked\r\n",
        "Transfer-Encoding: chunked\r\nTransfer-Encoding: chunked\r\n",
        "Transfer-Encoding: chunked\r\nContent-Length: 5\r\n"}) {
    const auto [status, body] = d.raw(head + framing + "\r\n0\r\n\r\n");
    EXPECT_EQ(status, 400) << framing << body;
    EXPECT_NE(body.find("bad request"), std::string::npos) << body;
    pb::Session none;
    EXPECT_EQ(d.t.get_session("sessions/smuggled", &none).error_code(),
              grpc::StatusCode::NOT_FOUND)
        << framing;
  }
  const auto [status, body] = d.raw(
      "POST /upload?library=cactus&session_id=chunked HTTP/1.1\r\nHost: " + d.host() +
      "\r\nX-Hdeform-Upload: 1\r\nTransfer-Encoding: Chunked \r\n\r\n0\r\n\r\n");
  EXPECT_EQ(status, 200) << body;
}

// A body on a GET or HEAD is refused before it is read: Beast's string body would reserve
// its whole Content-Length (up to the body limit, outside the upload budget).
TEST(SecurityHttp, AGetOrHeadWithABodyIsABadRequest) {
  Door d;
  for (const std::string method : {"GET", "HEAD"})
    for (const std::string& framing : std::vector<std::string>{
             "Content-Length: 268435456\r\n", "Content-Length: 1\r\n",
             "Transfer-Encoding: chunked\r\n"}) {
      const auto [status, body] =
          d.raw(method + " / HTTP/1.1\r\nHost: " + d.host() + "\r\n" + framing + "\r\n");
      EXPECT_EQ(status, 400) << method << " " << framing;
      if (method == "GET") {
        EXPECT_NE(body.find("carries no body"), std::string::npos) << body;
      }
    }
  const auto [status, body] = d.raw("GET / HTTP/1.1\r\nHost: " + d.host() +
                                    "\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(status, 200) << body;
  pb::ListMeshesResponse meshes;
  grpc::ClientContext ctx;
  EXPECT_TRUE(d.t.stub->ListMeshes(&ctx, {}, &meshes).ok()) << "the server goes on";
}

}  // namespace

namespace {

// Issue 35 (found with the asynchronous door, where a held request costs no thread): the
// request bodies the door holds are bounded all together; above the budget a request is
// answered 503 before its body is read, and the budget comes back when a request ends.
TEST(SecurityHttp, RequestBodiesInFlightAreBounded) {
  Door d({}, [](hdeform::gateway::GatewayOptions& o) { o.max_inflight_body_bytes = 1u << 20; });
  const pb::Session s = constrained_cactus(d.t);
  // A client declares 900 KB and sends a few bytes: the 900 KB are held for it.
  asio::io_context ioc;
  tcp::socket held(ioc);
  held.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(d.gateway->port())});
  asio::write(held, asio::buffer("POST /hdeform.v1.Deformation/ListMeshes HTTP/1.1\r\nHost: " +
                                 d.host() +
                                 "\r\nContent-Type: application/grpc-web+proto\r\n"
                                 "Content-Length: 900000\r\n\r\nabc"));
  const std::string body(200000, '\0');
  std::pair<int, std::string> r;
  for (int i = 0; i < 100; ++i) {  // until the held request's header has been read
    r = d.raw(grpc_web_post(d.host(), "ListMeshes", body));
    if (r.first == 503) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(r.first, 503) << r.second;
  EXPECT_NE(r.second.find("too many request bytes"), std::string::npos) << r.second;
  r = d.raw("POST /upload?library=cactus HTTP/1.1\r\nHost: " + d.host() +
            "\r\nX-Hdeform-Upload: 1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_EQ(r.first, 503) << r.second;
  pb::Frame f;
  EXPECT_TRUE(d.t.update(s.name(), 1, {cactus_transform()}, &f).ok());
  // The held request goes: its share comes back.
  held.close();
  for (int i = 0; i < 100; ++i) {
    r = d.raw(grpc_web_post(d.host(), "ListMeshes", body));
    if (r.first == 200) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(r.first, 200) << r.second;
  // A chunked gRPC-Web body (size unknown up front) is capped at 4 MiB.
  r = d.raw("POST /hdeform.v1.Deformation/ListMeshes HTTP/1.1\r\nHost: " + d.host() +
            "\r\nContent-Type: application/grpc-web+proto\r\nTransfer-Encoding: chunked\r\n\r\n");
  EXPECT_TRUE(r.first == 503 || r.first == 0) << r.first;  // 4 MiB > this door's 1 MiB budget
  Door big;
  std::string chunked = "POST /hdeform.v1.Deformation/ListMeshes HTTP/1.1\r\nHost: " + big.host() +
                        "\r\nContent-Type: application/grpc-web+proto\r\nTransfer-Encoding: chunked\r\n\r\n";
  const std::string piece(1u << 20, 'x');
  for (int i = 0; i < 5; ++i) chunked += "100000\r\n" + piece + "\r\n";
  chunked += "0\r\n\r\n";
  r = big.raw(chunked);
  EXPECT_EQ(r.first, 413) << r.second;
  EXPECT_NE(r.second.find("4194304"), std::string::npos) << r.second;
}

}  // namespace

namespace {

// Every way a request ends gives its slot back: with 8 slots, 200 refused, failed and
// answered requests of every kind leave the door serving (a leaked slot would make it 503).
TEST(SecurityHttp, EveryAnswerFreesItsRequestSlot) {
  Door d({}, [](hdeform::gateway::GatewayOptions& o) { o.max_connections = 8; });
  const std::string list = frames({pb::ListMeshesRequest().SerializeAsString()});
  const std::vector<std::string> requests = {
      "POST /upload?library=cactus HTTP/1.1\r\nHost: " + d.host() +
          "\r\nOrigin: https://evil.example\r\nContent-Length: 0\r\n\r\n",           // 403
      "POST /upload?library=cactus HTTP/1.1\r\nHost: " + d.host() + "\r\nContent-Length: 0\r\n\r\n",  // 403
      "PUT /x HTTP/1.1\r\nHost: " + d.host() + "\r\nContent-Length: 0\r\n\r\n",   // 405
      "GET /hdeform.v1.Deformation/ListMeshes HTTP/1.1\r\nHost: " + d.host() + "\r\n\r\n",  // 405
      "POST /upload HTTP/1.1\r\nHost: " + d.host() + "\r\nX-Hdeform-Upload: 1\r\nContent-Length: 0\r\n\r\n",  // 400
      grpc_web_post(d.host(), "ListMeshes", list),                                      // 200
      grpc_web_post(d.host(), "NoSuchMethod", list),                                    // 200, 12
      "GET /missing HTTP/1.1\r\nHost: " + d.host() + "\r\n\r\n",                      // 404
  };
  for (int round = 0; round < 25; ++round)
    for (const auto& r : requests) ASSERT_NE(d.raw(r).first, 0) << r;
  const auto [status, body] = d.request(http::verb::get, "/healthz");
  EXPECT_EQ(status, 200) << body;
}

}  // namespace

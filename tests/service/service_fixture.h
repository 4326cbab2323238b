// A real Server on 127.0.0.1:0 and a TCP channel to it, plus helpers for the tests.
#pragma once

#include "hdeform/v1/deform.grpc.pb.h"
#include "service/rpc/server.h"

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/client_interceptor.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace hdeform::testing {

namespace pb = ::hdeform::v1;

inline std::string data_path(const std::string& rel) {
  return std::string(HDEFORM_TEST_DATA) + "/" + rel;
}

// A fresh folder under the system's temp folder, removed with everything in it.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "hdeform-test-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path = tmpl;
  }
  TempDir(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << path;
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Adds `authorization: Bearer TOKEN` to every call of a channel.
class BearerInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit BearerInterceptor(std::string token) : token_(std::move(token)) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA))
      methods->GetSendInitialMetadata()->insert({"authorization", "Bearer " + token_});
    methods->Proceed();
  }

 private:
  std::string token_;
};
class BearerFactory final : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit BearerFactory(std::string token) : token_(std::move(token)) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(
      grpc::experimental::ClientRpcInfo*) override {
    return new BearerInterceptor(token_);
  }

 private:
  std::string token_;
};

// The operator token of every TestServer: `stub` presents it on every call, so tests of
// other behaviour need no session tokens; `bare_stub` presents none (access tests).
inline const std::string kTestAdminToken = "test-operator-token-0123456789abcdef";

inline std::shared_ptr<grpc::Channel> test_channel(int port, const std::string& token = "") {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  args.SetMaxSendMessageSize(-1);
  const std::string target = "127.0.0.1:" + std::to_string(port);
  if (token.empty())
    return grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), args);
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> f;
  f.push_back(std::make_unique<BearerFactory>(token));
  return grpc::experimental::CreateCustomChannelWithInterceptors(
      target, grpc::InsecureChannelCredentials(), args, std::move(f));
}

struct TestServer {
  std::unique_ptr<service::Server> server;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<pb::Deformation::Stub> stub;
  std::unique_ptr<pb::Deformation::Stub> bare_stub;

  explicit TestServer(service::ServerOptions options = {}) {
    options.listen_address = "127.0.0.1:0";
    if (options.workers < 1) options.workers = 2;
    if (options.admin_token.empty()) options.admin_token = kTestAdminToken;
    server = std::make_unique<service::Server>(options);
    channel = test_channel(server->port(), options.admin_token);
    stub = pb::Deformation::NewStub(channel);
    bare_stub = pb::Deformation::NewStub(test_channel(server->port()));
  }
  ~TestServer() { server->shutdown(std::chrono::milliseconds(500)); }

  // CreateSession from the library.
  grpc::Status create_library(const std::string& name, pb::Session* out,
                              const std::string& session_id = "") {
    grpc::ClientContext ctx;
    auto writer = stub->CreateSession(&ctx, out);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_library_mesh(name);
    req.mutable_header()->set_session_id(session_id);
    writer->Write(req);
    writer->WritesDone();
    return writer->Finish();
  }
  pb::Session library_session(const std::string& name) {
    pb::Session s;
    auto st = create_library(name, &s);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return s;
  }

  // CreateSession as an upload in `chunk`-byte pieces.
  grpc::Status upload(const std::string& bytes, const std::string& filename, pb::Session* out,
                      std::size_t chunk = 1u << 20, bool declare_size = false) {
    grpc::ClientContext ctx;
    auto writer = stub->CreateSession(&ctx, out);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_filename(filename);
    if (declare_size) req.mutable_header()->set_total_bytes(static_cast<std::int64_t>(bytes.size()));
    bool ok = writer->Write(req);
    for (std::size_t off = 0; ok && off < bytes.size(); off += chunk) {
      pb::CreateSessionRequest c;
      c.set_chunk(bytes.substr(off, chunk));
      ok = writer->Write(c);
    }
    writer->WritesDone();
    return writer->Finish();
  }

  grpc::Status set_constraints(const std::string& name, const pb::Constraints& c,
                               pb::Session* out, std::int64_t expected_version = 0) {
    grpc::ClientContext ctx;
    pb::SetConstraintsRequest req;
    req.set_name(name);
    *req.mutable_constraints() = c;
    req.set_expected_version(expected_version);
    return stub->SetConstraints(&ctx, req, out);
  }

  grpc::Status set_beta(const std::string& name, const pb::Beta& beta, pb::Session* out,
                        std::int64_t expected_version = 0) {
    grpc::ClientContext ctx;
    pb::SetBetaRequest req;
    req.set_name(name);
    *req.mutable_beta() = beta;
    req.set_expected_version(expected_version);
    return stub->SetBeta(&ctx, req, out);
  }
  // A uniform β (area units).
  grpc::Status set_beta(const std::string& name, double beta, pb::Session* out,
                        std::int64_t expected_version = 0) {
    pb::Beta b;
    b.set_value(beta);
    return set_beta(name, b, out, expected_version);
  }

  grpc::Status update(const std::string& name, std::int64_t seq,
                      const std::vector<pb::HandleTransform>& ts, pb::Frame* out,
                      bool energies = false, bool dragging = false) {
    grpc::ClientContext ctx;
    pb::UpdateHandlesRequest req;
    req.set_name(name);
    req.set_sequence(seq);
    req.set_energies(energies);
    req.set_dragging(dragging);
    for (const auto& t : ts) *req.add_transforms() = t;
    return stub->UpdateHandles(&ctx, req, out);
  }

  grpc::Status get_mesh(const std::string& name, bool rest, pb::MeshFormat format,
                        std::string* out, std::vector<std::size_t>* chunk_sizes = nullptr) {
    grpc::ClientContext ctx;
    pb::GetMeshRequest req;
    req.set_name(name);
    req.set_rest(rest);
    req.set_format(format);
    auto reader = stub->GetMesh(&ctx, req);
    pb::MeshChunk chunk;
    out->clear();
    while (reader->Read(&chunk)) {
      out->append(chunk.data());
      if (chunk_sizes) chunk_sizes->push_back(chunk.data().size());
    }
    return reader->Finish();
  }
  // The deformed mesh (GetMesh rest = false) in `format`; expects success.
  std::string deformed(const std::string& name, pb::MeshFormat format) {
    std::string bytes;
    auto st = get_mesh(name, false, format, &bytes);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return bytes;
  }

  grpc::Status get_session(const std::string& name, pb::Session* out) {
    grpc::ClientContext ctx;
    pb::GetSessionRequest req;
    req.set_name(name);
    return stub->GetSession(&ctx, req, out);
  }

  grpc::Status list_sessions(pb::ListSessionsResponse* out) {
    grpc::ClientContext ctx;
    return stub->ListSessions(&ctx, {}, out);
  }

  grpc::Status delete_session(const std::string& name) {
    grpc::ClientContext ctx;
    pb::DeleteSessionRequest req;
    req.set_name(name);
    pb::DeleteSessionResponse resp;
    return stub->DeleteSession(&ctx, req, &resp);
  }

  grpc::Status export_session(const std::string& name, pb::Snapshot* out,
                              bool include_mesh = false) {
    grpc::ClientContext ctx;
    pb::ExportSessionRequest req;
    req.set_name(name);
    req.set_include_mesh(include_mesh);
    return stub->ExportSession(&ctx, req, out);
  }

  grpc::Status import_session(const pb::Snapshot& snap, pb::Session* out,
                              const std::string& session_id = "") {
    grpc::ClientContext ctx;
    pb::ImportSessionRequest req;
    *req.mutable_snapshot() = snap;
    req.set_session_id(session_id);
    return stub->ImportSession(&ctx, req, out);
  }
};

// Two text meshes (OBJ/OFF) equal token by token, numbers within `rel` relative error. For
// results computed by separate solves: CHOLMOD's BLAS kernels may round the last bit
// differently for differently aligned buffers, so only one solve's output is bit-exact.
inline void expect_same_mesh_text(const std::string& a, const std::string& b,
                                  double rel = 1e-12) {
  std::istringstream ia(a), ib(b);
  std::string ta, tb;
  std::size_t token = 0, differ = 0;
  while (ia >> ta) {
    ASSERT_TRUE(static_cast<bool>(ib >> tb)) << "second mesh ends at token " << token;
    ++token;
    char *ea = nullptr, *eb = nullptr;
    const double x = std::strtod(ta.c_str(), &ea), y = std::strtod(tb.c_str(), &eb);
    if (*ea == '\0' && *eb == '\0') {
      if (std::abs(x - y) > rel * std::max(1.0, std::abs(x))) ++differ;
    } else if (ta != tb) {
      ++differ;
    }
  }
  EXPECT_FALSE(static_cast<bool>(ib >> tb)) << "second mesh is longer";
  EXPECT_EQ(differ, 0u) << differ << " of " << token << " tokens differ";
}

// A Botsch–Sorkine benchmark ("cactus", "cylinder", …): fixed = label 0, handle = label 2
// of MODEL.sel.
inline pb::Constraints benchmark_constraints(const std::string& model) {
  const std::string sel = slurp(data_path("botsch-sorkine/" + model + ".sel"));
  pb::Constraints c;
  auto* f = c.mutable_fixed()->add_selectors()->mutable_sel();
  f->set_content(sel);
  f->set_label(0);
  auto* h = c.add_handles()->add_selectors()->mutable_sel();
  h->set_content(sel);
  h->set_label(2);
  return c;
}

// MODEL.def as a 4×4 matrix transform.
inline pb::HandleTransform benchmark_transform(const std::string& model) {
  std::istringstream in(slurp(data_path("botsch-sorkine/" + model + ".def")));
  std::string header;
  std::getline(in, header);
  pb::HandleTransform t;
  for (int i = 0; i < 16; ++i) {
    double v = 0;
    in >> v;
    t.add_matrix(v);
  }
  return t;
}

inline pb::Constraints cactus_constraints() { return benchmark_constraints("cactus"); }
inline pb::HandleTransform cactus_transform() { return benchmark_transform("cactus"); }

// A library cactus with its benchmark constraints; expects success.
inline pb::Session constrained_cactus(TestServer& t) {
  const pb::Session s = t.library_session("cactus");
  pb::Session c;
  auto st = t.set_constraints(s.name(), cactus_constraints(), &c);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return c;
}

// One Deform stream message: NAME (empty: the stream's session), SEQUENCE, one transform.
inline pb::DeformRequest deform_request(const std::string& name, std::int64_t sequence,
                                        const pb::HandleTransform& transform) {
  pb::DeformRequest req;
  req.set_name(name);
  req.set_sequence(sequence);
  *req.add_transforms() = transform;
  return req;
}

inline pb::HandleTransform translation(double x, double y, double z) {
  pb::HandleTransform t;
  t.mutable_translation()->set_x(x);
  t.mutable_translation()->set_y(y);
  t.mutable_translation()->set_z(z);
  return t;
}

// grid_off's left strip (x ≤ 0.3) fixed, its right strip (x ≥ 2.8) the one handle.
inline pb::Constraints grid_strips() {
  auto half_space = [](double nx, double offset) {
    pb::Selector sel;
    sel.mutable_half_space()->mutable_normal()->set_x(nx);
    sel.mutable_half_space()->set_offset(offset);
    return sel;
  };
  pb::Constraints c;
  *c.mutable_fixed()->add_selectors() = half_space(-1, -0.3);
  *c.add_handles()->add_selectors() = half_space(1, 2.8);
  return c;
}

// A finely subdivided wavy grid (n×n vertices) as OFF text with 17 significant digits.
inline std::string grid_off(int n) {
  std::string s = "OFF\n" + std::to_string(n * n) + " " + std::to_string(2 * (n - 1) * (n - 1)) +
                  " 0\n";
  char buf[128];
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = i / double(n - 1), y = j / double(n - 1);
      std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g\n", x * 3.14159265358979, y * 2.718281828459,
                    0.05 * std::sin(7.1 * x) * std::cos(5.3 * y) + 0.0123456789);
      s += buf;
    }
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      std::snprintf(buf, sizeof buf, "3 %d %d %d\n3 %d %d %d\n", a, b, d, a, d, c);
      s += buf;
    }
  return s;
}

}  // namespace hdeform::testing

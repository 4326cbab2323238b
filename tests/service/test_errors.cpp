// Every error class, limits, TTL expiry, and isolation between sessions.
#include "service_fixture.h"

#include <thread>

using namespace hdeform::testing;
using grpc::StatusCode;

namespace {
pb::Constraints by_ids(std::vector<int> fixed, std::vector<int> handle) {
  pb::Constraints c;
  for (int i : fixed) c.mutable_fixed()->add_selectors()->mutable_ids()->add_ids(i);
  auto* h = c.add_handles()->add_selectors()->mutable_ids();
  for (int i : handle) h->add_ids(i);
  return c;
}
}  // namespace

TEST(ServiceErrors, InvalidArgument) {
  TestServer t;
  pb::Session s;
  // A bad mesh: the engine's message comes back.
  auto st = t.upload("OFF\n3 1 0\n0 0 0\n1 0 0\n", "broken.off", &s);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_FALSE(st.error_message().empty());
  st = t.upload("solid nothing", "mesh.xyz", &s);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();

  const pb::Session k = t.library_session("knight");
  pb::Session out;
  // A bad vertex id.
  st = t.set_constraints(k.name(), by_ids({0, 1, 2}, {999999}), &out);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("999999"), std::string::npos) << st.error_message();
  // β = 1.
  st = t.set_beta(k.name(), 1.0, &out);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  st = t.set_beta(k.name(), -0.1, &out);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();

  const pb::Session c = constrained_cactus(t);
  pb::Frame f;
  // A singular transform matrix.
  pb::HandleTransform singular;
  for (int i = 0; i < 15; ++i) singular.add_matrix(0);
  singular.add_matrix(1);
  st = t.update(c.name(), 1, {singular}, &f);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  // A non-unit quaternion, a wrong transform count.
  pb::HandleTransform q;
  q.mutable_rotation()->set_w(2);
  st = t.update(c.name(), 1, {q}, &f);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  st = t.update(c.name(), 1, {translation(0, 0, 0), translation(0, 0, 0)}, &f);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  // The failed updates changed nothing.
  pb::Session now;
  ASSERT_TRUE(t.get_session(c.name(), &now).ok());
  EXPECT_EQ(now.version(), c.version());
}

TEST(ServiceErrors, NotFound) {
  TestServer t;
  pb::Session s;
  EXPECT_EQ(t.create_library("no-such-mesh", &s).error_code(), StatusCode::NOT_FOUND);
  EXPECT_EQ(t.get_session("sessions/nope", &s).error_code(), StatusCode::NOT_FOUND);
  pb::Frame f;
  EXPECT_EQ(t.update("sessions/nope", 1, {}, &f).error_code(), StatusCode::NOT_FOUND);
  EXPECT_EQ(t.set_beta("sessions/nope", 0.1, &s).error_code(), StatusCode::NOT_FOUND);
  std::string bytes;
  EXPECT_EQ(t.get_mesh("sessions/nope", true, pb::MESH_FORMAT_GLB, &bytes).error_code(),
            StatusCode::NOT_FOUND);
  {
    grpc::ClientContext ctx;
    pb::WatchSessionRequest req;
    req.set_name("sessions/nope");
    auto reader = t.stub->WatchSession(&ctx, req);
    pb::SessionEvent ev;
    EXPECT_FALSE(reader->Read(&ev));
    EXPECT_EQ(reader->Finish().error_code(), StatusCode::NOT_FOUND);
  }
  {
    grpc::ClientContext ctx;
    auto stream = t.stub->Deform(&ctx);
    pb::DeformRequest req;
    req.set_name("sessions/nope");
    stream->Write(req);
    stream->WritesDone();
    pb::Frame fr;
    EXPECT_FALSE(stream->Read(&fr));
    EXPECT_EQ(stream->Finish().error_code(), StatusCode::NOT_FOUND);
  }
  EXPECT_EQ(t.delete_session("sessions/nope").error_code(), StatusCode::NOT_FOUND);
}

TEST(ServiceErrors, FailedPreconditionBeforeConstraints) {
  TestServer t;
  const pb::Session s = t.library_session("knight");
  pb::Frame f;
  EXPECT_EQ(t.update(s.name(), 1, {translation(0, 0, 0)}, &f).error_code(),
            StatusCode::FAILED_PRECONDITION);
  {
    grpc::ClientContext ctx;
    pb::SweepRequest req;
    req.set_name(s.name());
    req.add_betas(0.1);
    pb::SweepResponse resp;
    EXPECT_EQ(t.stub->Sweep(&ctx, req, &resp).error_code(), StatusCode::FAILED_PRECONDITION);
  }
  {
    grpc::ClientContext ctx;
    auto stream = t.stub->Deform(&ctx);
    pb::DeformRequest req;
    req.set_name(s.name());
    *req.add_transforms() = translation(0, 0, 0);
    stream->Write(req);
    stream->WritesDone();
    pb::Frame fr;
    while (stream->Read(&fr)) {
    }
    EXPECT_EQ(stream->Finish().error_code(), StatusCode::FAILED_PRECONDITION);
  }
  // β may be set before constraints.
  pb::Session out;
  EXPECT_TRUE(t.set_beta(s.name(), 0.2, &out).ok());
}

TEST(ServiceErrors, AbortedOnVersionConflict) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  pb::Session c;
  ASSERT_TRUE(t.set_constraints(s.name(), cactus_constraints(), &c, s.version()).ok());
  pb::Session out;
  // s.version() is stale now.
  EXPECT_EQ(t.set_beta(s.name(), 0.3, &out, s.version()).error_code(), StatusCode::ABORTED);
  EXPECT_EQ(t.set_constraints(s.name(), cactus_constraints(), &out, s.version()).error_code(),
            StatusCode::ABORTED);
  grpc::ClientContext ctx;
  pb::UpdateHandlesRequest req;
  req.set_name(s.name());
  *req.add_transforms() = translation(0, 0, 0);
  req.set_expected_version(s.version());
  pb::Frame f;
  EXPECT_EQ(t.stub->UpdateHandles(&ctx, req, &f).error_code(), StatusCode::ABORTED);
  EXPECT_TRUE(t.set_beta(s.name(), 0.3, &out, c.version()).ok());
}

TEST(ServiceErrors, ResourceExhaustedSessions) {
  hdeform::service::ServerOptions o;
  o.max_sessions = 2;
  TestServer t(o);
  t.library_session("knight");
  t.library_session("knight");
  pb::Session s;
  EXPECT_EQ(t.create_library("knight", &s).error_code(), StatusCode::RESOURCE_EXHAUSTED);
}

TEST(ServiceErrors, ResourceExhaustedVertices) {
  hdeform::service::ServerOptions o;
  o.max_vertices = 1000;
  TestServer t(o);
  pb::Session s;
  EXPECT_TRUE(t.create_library("knight", &s).ok());  // 502 vertices
  auto st = t.create_library("cactus", &s);          // 5261 vertices
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  st = t.upload(slurp(data_path("botsch-sorkine/cactus.off")), "cactus.off", &s);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  // Applied while parsing: the header's count is refused before any vertex is read.
  EXPECT_NE(st.error_message().find("--max-vertices"), std::string::npos) << st.error_message();
}

TEST(ServiceErrors, ResourceExhaustedUploadBytes) {
  hdeform::service::ServerOptions o;
  o.max_upload_bytes = 1u << 20;
  TestServer t(o);
  const std::string big = grid_off(120);  // ≈ 1.4 MB
  ASSERT_GT(big.size(), o.max_upload_bytes);
  pb::Session s;
  // Rejected while streaming (no declared size) ...
  auto st = t.upload(big, "grid.off", &s, 256u << 10);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  // ... and at the header when the size is declared.
  st = t.upload(big, "grid.off", &s, 256u << 10, /*declare_size=*/true);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  // A small upload still works.
  st = t.upload(slurp(data_path("models/knight.off")), "knight.off", &s);
  EXPECT_TRUE(st.ok()) << st.error_message();
}

TEST(ServiceErrors, IdleSessionsExpire) {
  hdeform::service::ServerOptions o;
  o.session_ttl = std::chrono::seconds(1);
  TestServer t(o);
  const pb::Session s = t.library_session("knight");
  pb::Session got;
  ASSERT_TRUE(t.get_session(s.name(), &got).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(2600));
  EXPECT_EQ(t.get_session(s.name(), &got).error_code(), StatusCode::NOT_FOUND);
}

TEST(ServiceErrors, OneSessionsFailureDoesNotHarmAnother) {
  TestServer t;
  const pb::Session good = constrained_cactus(t);
  pb::Frame before;
  ASSERT_TRUE(t.update(good.name(), 1, {cactus_transform()}, &before).ok());

  const pb::Session bad = constrained_cactus(t);
  pb::Frame f;
  pb::HandleTransform nan = translation(std::nan(""), 0, 0);
  EXPECT_EQ(t.update(bad.name(), 1, {nan}, &f).error_code(), StatusCode::INVALID_ARGUMENT);
  pb::Session out;
  EXPECT_EQ(t.set_constraints(bad.name(), by_ids({}, {}), &out).error_code(),
            StatusCode::INVALID_ARGUMENT);
  {
    grpc::ClientContext ctx;
    auto stream = t.stub->Deform(&ctx);
    pb::DeformRequest req;
    req.set_name(bad.name());
    *req.add_transforms() = nan;
    stream->Write(req);
    pb::Frame fr;
    while (stream->Read(&fr)) {
    }
    EXPECT_EQ(stream->Finish().error_code(), StatusCode::INVALID_ARGUMENT);
  }
  pb::Frame after;
  ASSERT_TRUE(t.update(good.name(), 2, {cactus_transform()}, &after).ok());
  EXPECT_EQ(after.positions(), before.positions());
  // The bad session itself still works after its failures.
  EXPECT_TRUE(t.update(bad.name(), 2, {cactus_transform()}, &f).ok());
  EXPECT_EQ(f.positions(), before.positions());
}

// Issue 8 ("Safe to expose"), the gRPC door: each attack class over loopback against a real
// Server, asserting the status code and message, and that a bystander session keeps being
// served throughout (Bystander::check after every attack).
#include "service_fixture.h"

#include <atomic>
#include <chrono>
#include <thread>

using namespace hdeform::testing;
using namespace std::chrono_literals;
using grpc::StatusCode;

namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A constrained cactus that must keep answering with the same frame.
struct Bystander {
  TestServer& t;
  pb::Session session;
  pb::Frame reference;
  explicit Bystander(TestServer& server) : t(server), session(constrained_cactus(server)) {
    EXPECT_TRUE(t.update(session.name(), 1, {cactus_transform()}, &reference).ok());
  }
  void check() {
    pb::Frame f;
    const auto st = t.update(session.name(), 2, {cactus_transform()}, &f);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(f.positions(), reference.positions());
  }
};

pb::Constraints by_ids(const std::vector<int>& fixed, const std::vector<int>& handle) {
  pb::Constraints c;
  auto* f = c.mutable_fixed()->add_selectors()->mutable_ids();
  for (int i : fixed) f->add_ids(i);
  auto* h = c.add_handles()->add_selectors()->mutable_ids();
  for (int i : handle) h->add_ids(i);
  return c;
}

// The wavy grid's left edge fixed, its right edge the handle.
pb::Constraints grid_constraints() {
  pb::Constraints c;
  auto* f = c.mutable_fixed()->add_selectors()->mutable_half_space();
  f->mutable_normal()->set_x(-1);
  f->set_offset(-0.3);
  auto* h = c.add_handles()->add_selectors()->mutable_half_space();
  h->mutable_normal()->set_x(1);
  h->set_offset(2.8);
  return c;
}

// An n×n grid upload with grid_constraints(): big enough that a factorization takes a while.
pb::Session grid_session(TestServer& t, int n) {
  pb::Session s, out;
  EXPECT_TRUE(t.upload(grid_off(n), "grid.off", &s).ok());
  EXPECT_TRUE(t.set_constraints(s.name(), grid_constraints(), &out).ok());
  return s;
}

std::vector<int> range(int from, int to) {
  std::vector<int> v;
  for (int i = from; i < to; ++i) v.push_back(i);
  return v;
}

}  // namespace

// Defect 2: a constraint set with no free vertex crashed the whole server.
TEST(Security, NoFreeVertexAnswersTheTargets) {
  TestServer t;
  Bystander by(t);
  const pb::Session s = t.library_session("cactus");
  const int n = s.vertex_count();
  pb::Session out;
  auto st = t.set_constraints(s.name(), by_ids(range(0, n / 2), range(n / 2, n)), &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  pb::Frame f;
  st = t.update(s.name(), 1, {translation(1, 2, 3)}, &f);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_TRUE(t.set_beta(s.name(), 0.4, &out).ok());
  st = t.update(s.name(), 2, {translation(1, 2, 3)}, &f);
  ASSERT_TRUE(st.ok()) << st.error_message();
  by.check();
}

// Defect 4: transforms near 1e300 gave NaN/Inf frames that went to watchers.
TEST(Security, NonFiniteResultsAreRejectedAndNeverStreamed) {
  TestServer t;
  Bystander by(t);
  const pb::Session c = constrained_cactus(t);
  grpc::ClientContext watch_ctx;
  pb::WatchSessionRequest wreq;
  wreq.set_name(c.name());
  auto watch = t.stub->WatchSession(&watch_ctx, wreq);
  pb::SessionEvent first;
  ASSERT_TRUE(watch->Read(&first));  // the current state

  for (double big : {1e300, 1e200, 1e40}) {
    pb::Frame f;
    auto st = t.update(c.name(), 1, {translation(big, 0, 0)}, &f);
    EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << big;
    EXPECT_TRUE(contains(st.error_message(), "handle 0's transform")) << st.error_message();
    pb::HandleTransform scaled;
    scaled.set_uniform_scale(big);
    st = t.update(c.name(), 1, {scaled}, &f);
    EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  }
  pb::Frame ok;
  ASSERT_TRUE(t.update(c.name(), 7, {translation(0.1, 0, 0)}, &ok).ok());
  // The watcher's next frame is the good one: no rejected result was ever broadcast.
  pb::SessionEvent ev;
  while (watch->Read(&ev) && !ev.has_frame()) {
  }
  ASSERT_TRUE(ev.has_frame());
  EXPECT_EQ(ev.frame().sequence(), 7);
  watch_ctx.TryCancel();
  watch->Finish();
  by.check();
}

// Defect 5: a .sel with invalid UTF-8 gave UNIMPLEMENTED with an empty message; a selector
// that selects nothing blamed "a single handle needs a fixed region".
TEST(Security, SelBytesAndEmptyRegionsAreNamed) {
  TestServer t;
  Bystander by(t);
  const pb::Session s = t.library_session("cactus");
  pb::Constraints c = cactus_constraints();
  c.mutable_fixed()->mutable_selectors(0)->mutable_sel()->set_content("\xff\xfe\x80 not utf-8\n");
  pb::Session out;
  auto st = t.set_constraints(s.name(), c, &out);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_TRUE(contains(st.error_message(), "fixed")) << st.error_message();

  c = cactus_constraints();
  auto* box = c.mutable_fixed()->mutable_selectors(0)->mutable_box();
  box->mutable_min()->set_x(100);
  box->mutable_min()->set_y(100);
  box->mutable_min()->set_z(100);
  box->mutable_max()->set_x(101);
  box->mutable_max()->set_y(101);
  box->mutable_max()->set_z(101);
  st = t.set_constraints(s.name(), c, &out);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_TRUE(contains(st.error_message(), "the fixed region selects no vertices"))
      << st.error_message();
  by.check();
}

// Bounded cost: every count in a request has a cap with a flag and a clear message.
TEST(Security, RequestCapsGiveResourceExhausted) {
  hdeform::service::ServerOptions o;
  o.request.max_handles = 3;
  o.request.max_selector_ids = 100;
  o.request.max_selectors = 4;
  o.request.max_local_beta = 2;
  o.request.max_sweep_betas = 5;
  TestServer t(o);
  Bystander by(t);
  const pb::Session s = t.library_session("cactus");
  pb::Session out;

  pb::Constraints c = by_ids({0, 1, 2}, {10});
  for (int j = 0; j < 3; ++j) c.add_handles()->add_selectors()->mutable_ids()->add_ids(20 + j);
  auto st = t.set_constraints(s.name(), c, &out);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(contains(st.error_message(), "--max-handles")) << st.error_message();

  st = t.set_constraints(s.name(), by_ids(range(0, 101), {500}), &out);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(contains(st.error_message(), "--max-selector-ids")) << st.error_message();

  c = by_ids({0}, {500});
  for (int i = 0; i < 4; ++i) c.mutable_fixed()->add_selectors()->mutable_ids()->add_ids(i + 1);
  st = t.set_constraints(s.name(), c, &out);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(contains(st.error_message(), "--max-selectors")) << st.error_message();

  ASSERT_TRUE(t.set_constraints(s.name(), cactus_constraints(), &out).ok());
  pb::Beta b;
  for (int i = 0; i < 3; ++i) {
    auto* e = b.add_local();
    e->set_beta(0.2);
    e->mutable_region()->add_selectors()->mutable_ids()->add_ids(i);
  }
  st = t.set_beta(s.name(), b, &out);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(contains(st.error_message(), "--max-local-beta")) << st.error_message();

  grpc::ClientContext ctx;
  pb::SweepRequest sweep;
  sweep.set_name(s.name());
  for (int i = 0; i < 6; ++i) sweep.add_betas(0.1 * i);
  pb::SweepResponse resp;
  st = t.stub->Sweep(&ctx, sweep, &resp);
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(contains(st.error_message(), "--max-sweep-betas")) << st.error_message();
  by.check();
}

// WatchSession streams per session are capped (each one's memory is bounded already).
TEST(Security, WatchersPerSessionAreCapped) {
  hdeform::service::ServerOptions o;
  o.request.max_watchers = 2;
  TestServer t(o);
  const pb::Session s = t.library_session("bar");
  pb::WatchSessionRequest req;
  req.set_name(s.name());
  grpc::ClientContext a_ctx, b_ctx, c_ctx;
  auto a = t.stub->WatchSession(&a_ctx, req);
  auto b = t.stub->WatchSession(&b_ctx, req);
  pb::SessionEvent ev;
  ASSERT_TRUE(a->Read(&ev));
  ASSERT_TRUE(b->Read(&ev));
  auto c = t.stub->WatchSession(&c_ctx, req);
  EXPECT_FALSE(c->Read(&ev));
  const auto st = c->Finish();
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(contains(st.error_message(), "--max-watchers")) << st.error_message();
  a_ctx.TryCancel();
  b_ctx.TryCancel();
  a->Finish();
  b->Finish();
}

// Sweep: stops at its deadline, never blocks the session's edits for its whole length, and
// its transient factorizations leave the results of the session's own β unchanged.
TEST(Security, SweepIsCancellableAndDoesNotBlockEdits) {
  hdeform::service::ServerOptions o;
  // The abandoned first sweep holds its slot until its current row ends (seconds under ASan).
  o.request.max_concurrent_sweeps = 2;
  TestServer t(o);
  const pb::Session s = grid_session(t, 120);

  // 60 β of fresh factorizations: seconds of work. The deadline ends it early.
  pb::SweepRequest sweep;
  sweep.set_name(s.name());
  for (int i = 0; i < 60; ++i) sweep.add_betas(0.01 + 0.015 * i);
  {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 400ms);
    pb::SweepResponse resp;
    const auto t0 = std::chrono::steady_clock::now();
    const auto st = t.stub->Sweep(&ctx, sweep, &resp);
    EXPECT_EQ(st.error_code(), StatusCode::DEADLINE_EXCEEDED);
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 2s);
  }

  // A sweep in the background; edits of the same session answer meanwhile.
  std::atomic<bool> sweep_done{false};
  grpc::ClientContext sweep_ctx;
  grpc::Status sweep_status;
  std::thread sweeper([&] {
    pb::SweepResponse resp;
    sweep_status = t.stub->Sweep(&sweep_ctx, sweep, &resp);
    sweep_done = true;
  });
  std::this_thread::sleep_for(100ms);
  pb::Frame frame;
  ASSERT_TRUE(t.update(s.name(), 1, {translation(0, 0, 0.2)}, &frame).ok());
  EXPECT_FALSE(sweep_done.load()) << "the update waited for the whole sweep";
  sweep_ctx.TryCancel();
  sweeper.join();
  EXPECT_EQ(sweep_status.error_code(), StatusCode::CANCELLED) << sweep_status.error_message();
  // The server's cached state is intact: a new solve equals the first.
  pb::Frame again;
  ASSERT_TRUE(t.update(s.name(), 2, {translation(0, 0, 0.2)}, &again).ok());
  EXPECT_EQ(again.positions(), frame.positions());
}

// Defect 7: a call queued on a session's strand ran after the session was deleted.
TEST(Security, CallsQueuedBehindADeleteFailWithNotFound) {
  TestServer t;
  const pb::Session s = grid_session(t, 150);
  const pb::Constraints c = grid_constraints();
  // A β change (a new factorization) holds the strand while a SetConstraints queues behind it.
  std::thread slow([&] {
    pb::Session o;
    t.set_beta(s.name(), 0.37, &o);
  });
  std::this_thread::sleep_for(30ms);
  grpc::Status queued;
  std::thread second([&] {
    pb::Session o;
    queued = t.set_constraints(s.name(), c, &o);
  });
  std::this_thread::sleep_for(30ms);
  ASSERT_TRUE(t.delete_session(s.name()).ok());
  slow.join();
  second.join();
  EXPECT_EQ(queued.error_code(), StatusCode::NOT_FOUND) << queued.error_message();
  pb::ListSessionsResponse list;
  ASSERT_TRUE(t.list_sessions(&list).ok());
  EXPECT_EQ(list.sessions_size(), 0);
}

// Uploads: the declared size is an upper bound, bytes in flight are budgeted server-wide,
// stalled uploads end, cancelled uploads create nothing.
TEST(Security, UploadsAreBounded) {
  hdeform::service::ServerOptions o;
  o.max_upload_bytes = 1u << 20;
  o.max_upload_inflight_bytes = 1u << 20;
  o.upload_stall_timeout = 300ms;
  TestServer t(o);
  Bystander by(t);
  const std::string cube = slurp(data_path("botsch-sorkine/bar.off"));

  {  // more bytes than declared
    grpc::ClientContext ctx;
    pb::Session out;
    auto w = t.stub->CreateSession(&ctx, &out);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_filename("x.off");
    req.mutable_header()->set_total_bytes(10);
    w->Write(req);
    pb::CreateSessionRequest chunk;
    chunk.set_chunk(std::string(100, 'x'));
    w->Write(chunk);
    w->WritesDone();
    const auto st = w->Finish();
    EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
    EXPECT_TRUE(contains(st.error_message(), "declared total_bytes")) << st.error_message();
  }
  {  // two declared uploads above the in-flight budget: the second is refused at once
    grpc::ClientContext a_ctx, b_ctx;
    pb::Session a_out, b_out;
    auto a = t.stub->CreateSession(&a_ctx, &a_out);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_filename("a.off");
    req.mutable_header()->set_total_bytes(700 << 10);
    a->Write(req);
    std::this_thread::sleep_for(50ms);
    auto b = t.stub->CreateSession(&b_ctx, &b_out);
    req.mutable_header()->set_filename("b.off");
    b->Write(req);
    b->WritesDone();
    const auto st = b->Finish();
    EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_TRUE(contains(st.error_message(), "--max-upload-inflight-mb")) << st.error_message();
    // `a` goes quiet: the stall timeout ends it and frees its share.
    const auto t0 = std::chrono::steady_clock::now();
    const auto sa = a->Finish();
    EXPECT_NE(sa.error_code(), StatusCode::OK);
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 3s);
  }
  {  // a stalled upload without WritesDone ends within the timeout
    grpc::ClientContext ctx;
    pb::Session out;
    auto w = t.stub->CreateSession(&ctx, &out);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_filename("stall.off");
    w->Write(req);
    pb::CreateSessionRequest chunk;
    chunk.set_chunk(cube.substr(0, 100));
    w->Write(chunk);
    const auto t0 = std::chrono::steady_clock::now();
    const auto st = w->Finish();
    EXPECT_NE(st.error_code(), StatusCode::OK);
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 3s);
  }
  // After all of that the budget is free again: a real upload succeeds.
  pb::Session ok;
  const auto st = t.upload(cube, "bar.off", &ok, 4096, true);
  EXPECT_TRUE(st.ok()) << st.error_message();
  {  // a cancelled upload creates no session
    grpc::ClientContext ctx;
    pb::Session out;
    auto w = t.stub->CreateSession(&ctx, &out);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_filename("cancel.off");
    req.mutable_header()->set_session_id("cancelled-upload");
    w->Write(req);
    pb::CreateSessionRequest chunk;
    chunk.set_chunk(cube);
    w->Write(chunk);
    ctx.TryCancel();
    w->Finish();
    std::this_thread::sleep_for(200ms);
    pb::Session none;
    EXPECT_EQ(t.get_session("sessions/cancelled-upload", &none).error_code(),
              StatusCode::NOT_FOUND);
  }
  by.check();
}

// Defect 3: a binary PLY element with no properties and a huge count looped ~forever.
TEST(Security, ZeroByteRowPlyIsRejectedAtOnce) {
  TestServer t;
  Bystander by(t);
  const std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement junk 4000000000\n"
      "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  pb::Session out;
  const auto t0 = std::chrono::steady_clock::now();
  const auto st = t.upload(ply, "evil.ply", &out);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_TRUE(contains(st.error_message(), "evil.ply")) << st.error_message();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 2s);
  by.check();
}

// Issue 35.3: ImportSession's mesh bytes are an upload too: charged to the same in-flight
// budget as CreateSession's streams, so imports cannot take the memory uploads are refused.
TEST(Security, ImportedMeshBytesShareTheUploadBudget) {
  hdeform::service::ServerOptions o;
  o.max_upload_bytes = 2u << 20;
  o.max_upload_inflight_bytes = 2u << 20;
  TestServer t(o);
  Bystander by(t);
  pb::Snapshot snap;
  snap.set_filename("bar.off");
  snap.set_mesh_bytes(slurp(data_path("botsch-sorkine/bar.off")));  // 448 KB, charged twice
  // Probed with an id that fails validation, after the charge: nothing is created meanwhile.
  const auto probe = [&] {
    pb::Session none;
    return t.import_session(snap, &none, "not a valid id!");
  };
  // An upload declared at 1.5 MiB holds most of the budget while it is open. Its header is
  // charged when the server reads it; a probe at that moment could take the budget first and
  // the upload would be refused, so each attempt waits longer before its one probe.
  std::unique_ptr<grpc::ClientContext> upload_ctx;
  std::unique_ptr<grpc::ClientWriter<pb::CreateSessionRequest>> upload;
  pb::Session upload_out;
  grpc::Status st;
  for (int attempt = 1; attempt <= 10; ++attempt) {
    upload_ctx = std::make_unique<grpc::ClientContext>();
    upload = t.stub->CreateSession(upload_ctx.get(), &upload_out);
    pb::CreateSessionRequest header;
    header.mutable_header()->set_filename("big.off");
    header.mutable_header()->set_total_bytes(3 << 19);
    ASSERT_TRUE(upload->Write(header));
    std::this_thread::sleep_for(attempt * 100ms);
    st = probe();
    if (st.error_code() == StatusCode::RESOURCE_EXHAUSTED) break;
    upload_ctx->TryCancel();
    upload->Finish();
  }
  EXPECT_EQ(st.error_code(), StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  EXPECT_TRUE(contains(st.error_message(), "--max-upload-inflight-mb")) << st.error_message();
  const auto wait_for = [&](StatusCode code) {
    for (int i = 0; i < 1000; ++i) {  // ≤ 20 s
      st = probe();
      if (st.error_code() == code) break;
      std::this_thread::sleep_for(20ms);
    }
    return st;
  };
  by.check();
  // The upload ends: its share comes back, and the same import fits.
  upload_ctx->TryCancel();
  upload->Finish();
  st = wait_for(StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  pb::Session out;
  st = t.import_session(snap, &out, "");
  EXPECT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(out.vertex_count(), 6084);
  by.check();
}

// Defect 7: a failed ImportSession leaves no session behind and keeps its id free.
TEST(Security, FailedImportPublishesNothing) {
  TestServer t;
  pb::Snapshot snap;
  snap.set_library_mesh("cactus");
  *snap.mutable_constraints() = cactus_constraints();
  snap.add_transforms()->mutable_translation()->set_x(1e300);
  snap.add_transforms();  // two transforms for one handle
  pb::Session out;
  auto st = t.import_session(snap, &out, "imported");
  EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT) << st.error_message();
  pb::Session none;
  EXPECT_EQ(t.get_session("sessions/imported", &none).error_code(), StatusCode::NOT_FOUND);
  snap.clear_transforms();
  st = t.import_session(snap, &out, "imported");
  EXPECT_TRUE(st.ok()) << st.error_message();
}

// Defect 9: ListMeshes revealed absolute server paths.
TEST(Security, ListMeshesShowsLibraryRelativePaths) {
  TestServer t;
  grpc::ClientContext ctx;
  pb::ListMeshesResponse resp;
  ASSERT_TRUE(t.stub->ListMeshes(&ctx, {}, &resp).ok());
  ASSERT_GT(resp.meshes_size(), 0);
  for (const auto& m : resp.meshes()) {
    EXPECT_FALSE(m.path().empty());
    EXPECT_NE(m.path().front(), '/') << m.path();
    EXPECT_FALSE(contains(m.path(), HDEFORM_TEST_DATA)) << m.path();
  }
}

// Defect 8: cache identities are SHA-256 (64 hex digits), not a forgeable 64-bit hash.
TEST(Security, MeshHashIsSha256) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  EXPECT_EQ(s.mesh_hash().size(), 64u);
}

// Shutdown stops within a few seconds while workers are busy with a long sweep.
TEST(Security, ShutdownStopsBusyWorkersQuickly) {
  auto t = std::make_unique<TestServer>();
  const pb::Session s = grid_session(*t, 120);
  pb::SweepRequest sweep;
  sweep.set_name(s.name());
  for (int i = 0; i < 60; ++i) sweep.add_betas(0.01 + 0.015 * i);
  grpc::Status sweep_status;
  std::thread sweeper([&] {
    grpc::ClientContext ctx;
    pb::SweepResponse resp;
    sweep_status = t->stub->Sweep(&ctx, sweep, &resp);
  });
  std::this_thread::sleep_for(300ms);
  const auto t0 = std::chrono::steady_clock::now();
  t->server->shutdown(std::chrono::milliseconds(1000));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 4s);
  sweeper.join();
  EXPECT_FALSE(sweep_status.ok());
}

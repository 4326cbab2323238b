// Issue 9, durable sessions: a Server with --state-dir keeps every session's state in SQLite
// and restores it (same id, tokens, version, pose) in the next Server on the same folder, on
// first use. Real Servers over loopback, one after the other on one temp folder.
#include "service_fixture.h"

#include <sqlite3.h>

#include <atomic>
#include <filesystem>
#include <thread>

using namespace hdeform::testing;
using grpc::StatusCode;
namespace fs = std::filesystem;

namespace {

hdeform::service::ServerOptions durable(const fs::path& dir) {
  hdeform::service::ServerOptions o;
  o.state_dir = (dir / "state").string();
  return o;
}

std::unique_ptr<grpc::ClientContext> as(const std::string& token) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->AddMetadata("authorization", "Bearer " + token);
  return ctx;
}

pb::Session get(TestServer& t, const std::string& name, const std::string& token,
                grpc::Status* status = nullptr) {
  pb::GetSessionRequest r;
  r.set_name(name);
  pb::Session out;
  const auto st = t.bare_stub->GetSession(as(token).get(), r, &out);
  if (status) *status = st;
  else EXPECT_TRUE(st.ok()) << st.error_message();
  return out;
}

std::size_t stored_records(const fs::path& dir) {
  sqlite3* db = nullptr;
  const auto file = (dir / "state" / "state.sqlite3").string();
  EXPECT_EQ(sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "SELECT count(*) FROM sessions", -1, &st, nullptr);
  std::size_t n = 0;
  if (sqlite3_step(st) == SQLITE_ROW) n = static_cast<std::size_t>(sqlite3_column_int64(st, 0));
  sqlite3_finalize(st);
  sqlite3_close(db);
  return n;
}

// Positions of two frames agree (separate solves may round the last bits differently).
void expect_same_positions(const pb::Frame& a, const pb::Frame& b) {
  ASSERT_EQ(a.positions().size(), b.positions().size());
  const auto* x = reinterpret_cast<const float*>(a.positions().data());
  const auto* y = reinterpret_cast<const float*>(b.positions().data());
  const std::size_t n = a.positions().size() / sizeof(float);
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, double(std::abs(x[i] - y[i])));
  EXPECT_LT(worst, 1e-5);
}

}  // namespace

TEST(Durable, ARestartKeepsIdTokensVersionPoseAndBeta) {
  TempDir dir;
  pb::Session created, before;
  pb::Frame last;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.create_library("cactus", &created, "meeting").ok());
    ASSERT_TRUE(a.set_constraints(created.name(), cactus_constraints(), &before).ok());
    pb::Beta beta;
    beta.set_value(0.2);
    auto* local = beta.add_local();
    local->mutable_region()->add_selectors()->mutable_ids()->add_ids(5);
    local->set_beta(0.5);
    local->set_falloff_radius(0.1);
    ASSERT_TRUE(a.set_beta(created.name(), beta, &before).ok());
    for (int i = 1; i <= 5; ++i)
      ASSERT_TRUE(a.update(created.name(), i, {translation(0.01 * i, 0, 0.02 * i)}, &last).ok());
    before = get(a, created.name(), created.view_token());
  }  // a clean stop flushes the coalesced handle moves
  TestServer b(durable(dir.path));
  const pb::Session after = get(b, "sessions/meeting", created.view_token());
  EXPECT_EQ(after.name(), "sessions/meeting");
  EXPECT_EQ(after.version(), before.version());
  EXPECT_EQ(after.mesh_hash(), before.mesh_hash());
  EXPECT_EQ(after.constraints().SerializeAsString(), before.constraints().SerializeAsString());
  EXPECT_EQ(after.beta().SerializeAsString(), before.beta().SerializeAsString());
  ASSERT_EQ(after.transforms_size(), 1);
  EXPECT_DOUBLE_EQ(after.transforms(0).translation().x(), 0.05);
  EXPECT_DOUBLE_EQ(after.transforms(0).translation().z(), 0.10);
  EXPECT_EQ(after.create_time_unix_ms(), before.create_time_unix_ms());
  // The edit token still edits; the deformation is the one before the restart.
  pb::UpdateHandlesRequest r;
  r.set_name(after.name());
  r.set_sequence(6);
  *r.add_transforms() = translation(0.05, 0, 0.10);
  pb::Frame again;
  const auto st = b.bare_stub->UpdateHandles(as(created.edit_token()).get(), r, &again);
  ASSERT_TRUE(st.ok()) << st.error_message();
  expect_same_positions(again, last);
  grpc::Status denied;
  get(b, after.name(), "not-a-token", &denied);
  EXPECT_EQ(denied.error_code(), StatusCode::PERMISSION_DENIED);
}

// A clean stop in the middle of a drag: the server stops accepting, ends the streams, drains
// the calls in flight, then flushes, so the last move it answered is what a restart finds.
TEST(Durable, AStopMidDragKeepsTheLastAnsweredMove) {
  TempDir dir;
  pb::Session created, s;
  double last_answered = -1;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.create_library("cactus", &created, "dragged").ok());
    ASSERT_TRUE(a.set_constraints(created.name(), cactus_constraints(), &s).ok());
    std::atomic<bool> go{true};
    std::thread drag([&] {
      for (int i = 1; go; ++i) {
        pb::Frame f;
        const double z = 0.001 * i;
        if (!a.update(created.name(), i, {translation(0, 0, z)}, &f, false, /*dragging=*/true)
                 .ok())
          break;  // the server stopped accepting
        last_answered = z;
      }
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    a.server->shutdown(std::chrono::milliseconds(2000));
    go = false;
    drag.join();
  }
  ASSERT_GT(last_answered, 0);
  TestServer b(durable(dir.path));
  const pb::Session after = get(b, "sessions/dragged", created.view_token());
  ASSERT_EQ(after.transforms_size(), 1);
  EXPECT_DOUBLE_EQ(after.transforms(0).translation().z(), last_answered)
      << "a move answered before the stop was lost";
}

TEST(Durable, UploadedMeshesAndRotatedTokensSurvive) {
  TempDir dir;
  pb::Session up;
  std::string rest;
  std::string edit, view;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.upload(grid_off(20), "wavy.off", &up).ok());
    ASSERT_TRUE(a.get_mesh(up.name(), true, pb::MESH_FORMAT_OFF, &rest).ok());
    pb::RotateTokensRequest r;
    r.set_name(up.name());
    pb::Session rotated;
    ASSERT_TRUE(a.bare_stub->RotateTokens(as(up.edit_token()).get(), r, &rotated).ok());
    edit = rotated.edit_token();
    view = rotated.view_token();
  }
  // One file per mesh, by content.
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir.path / "state" / "meshes")) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
  TestServer b(durable(dir.path));
  grpc::Status old;
  get(b, up.name(), up.view_token(), &old);
  EXPECT_EQ(old.error_code(), StatusCode::PERMISSION_DENIED) << "rotated tokens must stay revoked";
  const pb::Session s = get(b, up.name(), view);
  EXPECT_EQ(s.mesh_name(), "wavy.off");
  std::string again;
  ASSERT_TRUE(b.get_mesh(up.name(), true, pb::MESH_FORMAT_OFF, &again).ok());
  EXPECT_EQ(again, rest);
  (void)edit;
}

// A restore re-applies the stored constraints; that must not write a record of its own (one
// without the upload's mesh key, at the restore's version), or the next restart cannot
// restore the session. Two restarts, and an import, on an uploaded mesh with constraints.
TEST(Durable, AnUploadedSessionSurvivesTwoRestartsAtItsVersion) {
  TempDir dir;
  pb::Session up, imported;
  pb::Frame moved;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.upload(grid_off(20), "wavy.off", &up).ok());
    pb::Session constrained;
    ASSERT_TRUE(a.set_constraints(up.name(), grid_strips(), &constrained).ok());
    pb::HandleTransform t;
    t.mutable_translation()->set_y(0.5);
    ASSERT_TRUE(a.update(up.name(), 1, {t}, &moved).ok());
    pb::Snapshot snap;
    ASSERT_TRUE(a.export_session(up.name(), &snap, true).ok());
    const grpc::Status st = a.import_session(snap, &imported);
    ASSERT_TRUE(st.ok()) << st.error_message();
  }
  for (int restart = 1; restart <= 2; ++restart) {
    SCOPED_TRACE("restart " + std::to_string(restart));
    TestServer b(durable(dir.path));
    grpc::Status st;
    const pb::Session s = get(b, up.name(), up.view_token(), &st);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(s.version(), moved.version());
    ASSERT_EQ(s.transforms_size(), 1);
    EXPECT_DOUBLE_EQ(s.transforms(0).translation().y(), 0.5);
    const pb::Session i = get(b, imported.name(), imported.view_token(), &st);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(i.version(), imported.version());
  }
}

TEST(Durable, StoredSessionsAreListedAndTheirIdsStayTakenBeforeTheyAreRestored) {
  TempDir dir;
  pb::Session s;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.create_library("bar", &s, "kept").ok());
  }
  TestServer b(durable(dir.path));
  // Listed (from its record) for its token and for the operator, without a restore.
  pb::ListSessionsResponse mine;
  ASSERT_TRUE(b.bare_stub->ListSessions(as(s.view_token()).get(), {}, &mine).ok());
  ASSERT_EQ(mine.sessions_size(), 1);
  EXPECT_EQ(mine.sessions(0).name(), "sessions/kept");
  EXPECT_EQ(mine.sessions(0).mesh_name(), "bar");
  EXPECT_TRUE(mine.sessions(0).edit_token().empty());
  pb::ListSessionsResponse none;
  ASSERT_TRUE(b.bare_stub->ListSessions(as("other").get(), {}, &none).ok());
  EXPECT_EQ(none.sessions_size(), 0);
  // Its id cannot be taken by a new session.
  pb::Session squat;
  EXPECT_EQ(b.create_library("cactus", &squat, "kept").error_code(), StatusCode::ALREADY_EXISTS);
}

// ListSessions finds stored sessions through the token index: after a rotation only the new
// tokens list it, and records stored before the index existed are indexed at start.
TEST(Durable, StoredSessionsAreListedThroughTheTokenIndex) {
  TempDir dir;
  pb::Session s, other;
  pb::Session rotated;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.create_library("bar", &s, "indexed").ok());
    ASSERT_TRUE(a.create_library("bar", &other, "someone-else").ok());
    pb::RotateTokensRequest r;
    r.set_name(s.name());
    ASSERT_TRUE(a.bare_stub->RotateTokens(as(s.edit_token()).get(), r, &rotated).ok());
  }
  auto listed = [](TestServer& t, const std::string& token) {
    pb::ListSessionsResponse out;
    EXPECT_TRUE(t.bare_stub->ListSessions(as(token).get(), {}, &out).ok());
    std::vector<std::string> names;
    for (const auto& x : out.sessions()) names.push_back(x.name());
    return names;
  };
  {
    TestServer b(durable(dir.path));
    EXPECT_TRUE(listed(b, s.view_token()).empty());  // the tokens before the rotation
    EXPECT_TRUE(listed(b, s.edit_token()).empty());
    EXPECT_EQ(listed(b, rotated.view_token()), std::vector<std::string>{"sessions/indexed"});
    EXPECT_EQ(listed(b, other.edit_token()), std::vector<std::string>{"sessions/someone-else"});
  }
  // A state file from before the index: its entries are gone; the next start writes them.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir.path / "state" / "state.sqlite3").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "DELETE FROM tokens", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  TestServer c(durable(dir.path));
  EXPECT_EQ(listed(c, rotated.edit_token()), std::vector<std::string>{"sessions/indexed"});
  EXPECT_EQ(listed(c, other.view_token()), std::vector<std::string>{"sessions/someone-else"});
}

TEST(Durable, DeletedAndExpiredSessionsLeaveTheDisk) {
  TempDir dir;
  pb::Session gone, idle;
  {
    auto o = durable(dir.path);
    o.session_ttl = std::chrono::seconds(2);
    TestServer a(o);
    ASSERT_TRUE(a.create_library("bar", &gone).ok());
    ASSERT_TRUE(a.upload(grid_off(10), "idle.off", &idle).ok());
    ASSERT_TRUE(a.delete_session(gone.name()).ok());
  }
  EXPECT_EQ(stored_records(dir.path), 1u);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  {
    auto o = durable(dir.path);
    o.session_ttl = std::chrono::seconds(2);
    TestServer b(o);  // purges the expired record and its mesh at start
    grpc::Status st;
    // Their tokens open nothing now; the operator sees that they are gone.
    get(b, gone.name(), gone.view_token(), &st);
    EXPECT_EQ(st.error_code(), StatusCode::PERMISSION_DENIED);
    get(b, idle.name(), idle.view_token(), &st);
    EXPECT_EQ(st.error_code(), StatusCode::PERMISSION_DENIED);
    pb::Session none;
    EXPECT_EQ(b.get_session(gone.name(), &none).error_code(), StatusCode::NOT_FOUND);
    EXPECT_EQ(b.get_session(idle.name(), &none).error_code(), StatusCode::NOT_FOUND);
  }
  EXPECT_EQ(stored_records(dir.path), 0u);
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir.path / "state" / "meshes")) files += e.is_regular_file();
  EXPECT_EQ(files, 0u);
}

TEST(Durable, AForeignStateFileIsRefusedAndLeftAsItIs) {
  TempDir dir;
  fs::create_directories(dir.path / "state");
  const auto file = dir.path / "state" / "state.sqlite3";
  {
    std::ofstream out(file, std::ios::binary);
    out << "these are someone's notes, not a database\n";
  }
  const std::string before = slurp(file.string());
  try {
    TestServer t(durable(dir.path));
    FAIL() << "a server started on a foreign state file";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(file.string()), before);
}

TEST(Durable, ACorruptRecordIsReportedAndKept) {
  TempDir dir;
  pb::Session s;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.create_library("bar", &s, "broken").ok());
  }
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir.path / "state" / "state.sqlite3").c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "UPDATE sessions SET record = x'ffff0102' WHERE id = 'broken'",
                           nullptr, nullptr, nullptr),
              SQLITE_OK);
    sqlite3_close(db);
  }
  {
    TestServer b(durable(dir.path));
    grpc::Status st;
    get(b, s.name(), s.view_token(), &st);
    EXPECT_EQ(st.error_code(), StatusCode::UNAVAILABLE) << st.error_message();
    EXPECT_NE(st.error_message().find("broken"), std::string::npos) << st.error_message();
    pb::Session other;
    EXPECT_EQ(b.create_library("cactus", &other, "broken").error_code(),
              StatusCode::ALREADY_EXISTS);  // never overwritten
    EXPECT_TRUE(b.create_library("cactus", &other).ok());  // the server serves the others
  }
  EXPECT_EQ(stored_records(dir.path), 2u);
}

// After a restart, many first calls at once: each stored session is restored once (every
// caller gets that one session), two sessions restore side by side, and the session cap is
// checked before a restore does any work.
TEST(Durable, ConcurrentFirstCallsRestoreEachSessionOnce) {
  TempDir dir;
  pb::Session s1, s2, s3;
  {
    TestServer a(durable(dir.path));
    ASSERT_TRUE(a.create_library("cactus", &s1, "first").ok());
    ASSERT_TRUE(a.create_library("bar", &s2, "second").ok());
    ASSERT_TRUE(a.create_library("plane", &s3, "third").ok());
  }
  auto o = durable(dir.path);
  o.max_sessions = 2;
  TestServer b(o);
  std::vector<pb::Session> got(8);
  std::vector<grpc::Status> status(8);
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < got.size(); ++k)
    threads.emplace_back([&, k] {
      const pb::Session& s = k % 2 ? s2 : s1;
      got[k] = get(b, s.name(), s.view_token(), &status[k]);
    });
  for (auto& t : threads) t.join();
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_TRUE(status[k].ok()) << status[k].error_message();
    EXPECT_EQ(got[k].create_time_unix_ms(), got[k % 2].create_time_unix_ms());
    EXPECT_EQ(got[k].name(), (k % 2 ? s2 : s1).name());
  }
  grpc::Status full;
  get(b, s3.name(), s3.view_token(), &full);
  EXPECT_EQ(full.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(full.error_message().find("cannot be restored now"), std::string::npos)
      << full.error_message();
}

// Restoring a stored session parses its mesh and factorizes: never on gRPC's callback
// threads. After a restart, the first call of each kind on a not-yet-restored session (a
// lookup inline, a change through the strand, a pool call) is answered, and every restore
// ran on the worker pool.
TEST(Durable, RestoresRunOnTheWorkerPoolNotOnGrpcThreads) {
  TempDir dir;
  std::vector<pb::Session> s(16);
  {
    TestServer a(durable(dir.path));
    for (auto& session : s) {
      ASSERT_TRUE(a.create_library("cactus", &session).ok());
      pb::Session constrained;
      ASSERT_TRUE(
          a.set_constraints(session.name(), benchmark_constraints("cactus"), &constrained).ok());
    }
  }
  TestServer b(durable(dir.path));
  auto view = [&](std::size_t k) { return as(s[k].view_token()); };
  auto edit = [&](std::size_t k) { return as(s[k].edit_token()); };
  {
    pb::GetSessionRequest r;
    r.set_name(s[0].name());
    pb::Session out;
    EXPECT_TRUE(b.bare_stub->GetSession(view(0).get(), r, &out).ok());
  }
  {
    pb::ListHistoryRequest r;
    r.set_name(s[1].name());
    pb::ListHistoryResponse out;
    EXPECT_TRUE(b.bare_stub->ListHistory(view(1).get(), r, &out).ok());
  }
  {
    pb::GetTimelineRequest r;
    r.set_name(s[2].name());
    pb::Timeline out;
    EXPECT_TRUE(b.bare_stub->GetTimeline(view(2).get(), r, &out).ok());
  }
  {
    pb::PoseAtRequest r;
    r.set_name(s[3].name());
    pb::Keyframe out;
    const auto st = b.bare_stub->PoseAt(view(3).get(), r, &out);
    EXPECT_EQ(st.error_code(), StatusCode::FAILED_PRECONDITION) << st.error_message();  // no keys
  }
  {
    pb::ListSnapshotsRequest r;
    r.set_name(s[4].name());
    pb::ListSnapshotsResponse out;
    EXPECT_TRUE(b.bare_stub->ListSnapshots(view(4).get(), r, &out).ok());
  }
  {
    pb::SetBetaRequest r;
    r.set_name(s[5].name());
    r.mutable_beta()->set_value(0.1);
    pb::Session out;
    const auto st = b.bare_stub->SetBeta(edit(5).get(), r, &out);
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
  {
    pb::GetHandleWeightsRequest r;
    r.set_name(s[6].name());
    pb::HandleWeights out;
    EXPECT_TRUE(b.bare_stub->GetHandleWeights(view(6).get(), r, &out).ok());
  }
  {
    pb::UpdateHandlesRequest r;
    r.set_name(s[7].name());
    *r.add_transforms() = benchmark_transform("cactus");
    pb::Frame out;
    const auto st = b.bare_stub->UpdateHandles(edit(7).get(), r, &out);
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
  {
    pb::DeleteSessionRequest r;
    r.set_name(s[8].name());
    pb::DeleteSessionResponse out;
    EXPECT_TRUE(b.bare_stub->DeleteSession(edit(8).get(), r, &out).ok());
  }
  {
    pb::GetMeshRequest r;
    r.set_name(s[9].name());
    auto ctx = view(9);  // the context outlives the stream
    auto reader = b.bare_stub->GetMesh(ctx.get(), r);
    pb::MeshChunk chunk;
    std::size_t bytes = 0;
    while (reader->Read(&chunk)) bytes += chunk.data().size();
    EXPECT_TRUE(reader->Finish().ok());
    EXPECT_GT(bytes, 0u);
  }
  {
    pb::SweepRequest r;
    r.set_name(s[10].name());
    r.add_betas(0.1);
    pb::SweepResponse out;
    const auto st = b.bare_stub->Sweep(edit(10).get(), r, &out);
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
  {
    pb::ExportRigRequest r;
    r.set_name(s[11].name());
    auto ctx = edit(11);
    auto reader = b.bare_stub->ExportRig(ctx.get(), r);
    pb::MeshChunk chunk;
    bool report = false;
    while (reader->Read(&chunk)) report = report || chunk.has_rig_report();
    const auto st = reader->Finish();
    EXPECT_TRUE(st.ok()) << st.error_message();
    EXPECT_TRUE(report);
  }
  {
    // A view token is refused after the restore, on the pool, as before it.
    pb::ExportAnimationRequest r;
    r.set_name(s[12].name());
    auto ctx = view(12);
    auto reader = b.bare_stub->ExportAnimation(ctx.get(), r);
    pb::MeshChunk chunk;
    while (reader->Read(&chunk)) {
    }
    EXPECT_EQ(reader->Finish().error_code(), StatusCode::PERMISSION_DENIED);
  }
  {
    // Deform: the first message names the session; its frame comes after the restore.
    auto ctx = edit(13);
    auto stream = b.bare_stub->Deform(ctx.get());
    pb::DeformRequest r;
    r.set_name(s[13].name());
    r.set_sequence(1);
    *r.add_transforms() = benchmark_transform("cactus");
    ASSERT_TRUE(stream->Write(r));
    pb::Frame f;
    EXPECT_TRUE(stream->Read(&f));
    EXPECT_EQ(f.sequence(), 1);
    stream->WritesDone();
    const auto st = stream->Finish();
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
  {
    // WatchSession: the join state comes after the restore; joined presence shows.
    auto ctx = view(14);
    pb::WatchSessionRequest r;
    r.set_name(s[14].name());
    r.mutable_client()->set_client_id("w1");
    auto reader = b.bare_stub->WatchSession(ctx.get(), r);
    pb::SessionEvent ev;
    ASSERT_TRUE(reader->Read(&ev));
    EXPECT_TRUE(ev.has_state() || ev.has_presence());
    ctx->TryCancel();
    while (reader->Read(&ev)) {
    }
    EXPECT_EQ(reader->Finish().error_code(), StatusCode::CANCELLED);
  }
  {
    // A refused watcher (edit-only encoding) is refused after the restore, with its reason.
    auto ctx = view(15);
    pb::WatchSessionRequest r;
    r.set_name(s[15].name());
    r.mutable_format()->set_encoding(pb::FRAME_ENCODING_FLOAT64);
    auto reader = b.bare_stub->WatchSession(ctx.get(), r);
    pb::SessionEvent ev;
    EXPECT_FALSE(reader->Read(&ev));
    const auto st = reader->Finish();
    EXPECT_EQ(st.error_code(), StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("FLOAT64"), std::string::npos) << st.error_message();
  }
  EXPECT_EQ(b.server->restores_off_pool(), 0u);
}

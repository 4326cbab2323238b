// History and named snapshots (docs/api.md "History and snapshots"): a drag is one step,
// undo and redo are new visible steps that never silently lose another editor's later
// change, snapshots are kept with the session (durably). Real server over loopback.
#include "editors_fixture.h"
#include "service/session/history.h"
#include "service/session/convert.h"
#include "service/session/history_record.h"

#include <sqlite3.h>

#include <chrono>
#include <filesystem>
#include <thread>

using namespace hdeform::testing;
namespace fs = std::filesystem;

namespace {

struct Editor {
  TwoHandles& e;
  std::string id;
  grpc::Status undo(pb::Session* out = nullptr, std::int64_t step = 0) {
    pb::UndoRequest r;
    r.set_name(e.s.name());
    r.set_client_id(id);
    r.set_step(step);
    pb::Session s;
    return e.t.bare_stub->Undo(as(e.s.edit_token()).get(), r, out ? out : &s);
  }
  grpc::Status redo(pb::Session* out = nullptr) {
    pb::UndoRequest r;
    r.set_name(e.s.name());
    r.set_client_id(id);
    pb::Session s;
    return e.t.bare_stub->Redo(as(e.s.edit_token()).get(), r, out ? out : &s);
  }
  // A drag of `handle` to z = `to` in three frames: one step.
  void drag(int handle, double to) {
    for (int i = 1; i <= 3; ++i)
      ASSERT_TRUE(e.update(id, {handle}, {translation(0, 0, to * i / 3)}, nullptr, false, i < 3)
                      .ok());
  }
};

pb::ListHistoryResponse history(TwoHandles& e, int page_size = 0, const std::string& token = "") {
  pb::ListHistoryRequest r;
  r.set_name(e.s.name());
  r.set_page_size(page_size);
  r.set_page_token(token);
  pb::ListHistoryResponse out;
  const auto st = e.t.bare_stub->ListHistory(as(e.s.view_token()).get(), r, &out);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return out;
}

grpc::Status save(TwoHandles& e, const std::string& name) {
  pb::SaveSnapshotRequest r;
  r.set_name(e.s.name());
  r.set_snapshot(name);
  r.set_client_id("alice");
  pb::NamedSnapshot out;
  return e.t.bare_stub->SaveSnapshot(as(e.s.edit_token()).get(), r, &out);
}

// `keys` keys at 0, 1, … s, each moving both handles up by 0.1 per second (alice's).
grpc::Status set_timeline(TwoHandles& e, int keys) {
  pb::SetTimelineRequest r;
  r.set_name(e.s.name());
  r.set_client_id("alice");
  for (int k = 0; k < keys; ++k) {
    auto* key = r.mutable_timeline()->add_keys();
    key->set_time_s(k);
    for (int h = 0; h < 2; ++h) *key->add_transforms() = translation(0, 0, 0.1 * k);
  }
  pb::Timeline out;
  return e.t.bare_stub->SetTimeline(as(e.s.edit_token()).get(), r, &out);
}

int timeline_keys(TwoHandles& e) {
  pb::GetTimelineRequest r;
  r.set_name(e.s.name());
  pb::Timeline out;
  EXPECT_TRUE(e.t.bare_stub->GetTimeline(as(e.s.view_token()).get(), r, &out).ok());
  return out.keys_size();
}

grpc::Status delete_snapshot(TwoHandles& e, const std::string& name) {
  pb::DeleteSnapshotRequest d;
  d.set_name(e.s.name());
  d.set_snapshot(name);
  d.set_client_id("alice");
  pb::DeleteSnapshotResponse out;
  return e.t.bare_stub->DeleteSnapshot(as(e.s.edit_token()).get(), d, &out);
}

// "NAME@VERSION" of each named snapshot.
std::vector<std::string> snapshot_names(TwoHandles& e) {
  pb::ListSnapshotsRequest r;
  r.set_name(e.s.name());
  pb::ListSnapshotsResponse out;
  EXPECT_TRUE(e.t.bare_stub->ListSnapshots(as(e.s.view_token()).get(), r, &out).ok());
  std::vector<std::string> names;
  for (const auto& x : out.snapshots()) names.push_back(x.name() + "@" + std::to_string(x.version()));
  return names;
}

grpc::Status restore(TwoHandles& e, const std::string& name) {
  pb::RestoreSnapshotRequest r;
  r.set_name(e.s.name());
  r.set_snapshot(name);
  r.set_client_id("alice");
  pb::Session out;
  return e.t.bare_stub->RestoreSnapshot(as(e.s.edit_token()).get(), r, &out);
}

}  // namespace

TEST(History, ADragIsOneStepWithItsAuthorAndUndoRedoAreStepsToo) {
  TwoHandles e;
  ASSERT_TRUE(e.grab(who("alice", "Alice"), {0}).ok());  // names her
  Editor alice{e, "alice"};
  alice.drag(0, 0.6);
  auto h = history(e);
  ASSERT_EQ(h.steps_size(), 2);  // the constraints, then the whole drag
  EXPECT_EQ(h.steps(0).kind(), pb::STEP_KIND_MOVE);
  EXPECT_EQ(h.steps(0).author(), "Alice");
  EXPECT_EQ(h.steps(0).summary(), "moved handle 0");
  EXPECT_GT(h.steps(0).time_unix_ms(), 0);
  EXPECT_EQ(h.steps(1).kind(), pb::STEP_KIND_CONSTRAINTS);

  pb::Session after;
  auto st = alice.undo(&after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(tz(after, 0), 0.0);  // back to before the drag's first frame
  h = history(e);
  EXPECT_EQ(h.steps(0).kind(), pb::STEP_KIND_UNDO);
  EXPECT_EQ(h.steps(0).target(), h.steps(1).id());
  EXPECT_TRUE(h.steps(1).undone());

  ASSERT_TRUE(alice.redo(&after).ok());
  EXPECT_DOUBLE_EQ(tz(after, 0), 0.6);
  EXPECT_EQ(history(e).steps(0).kind(), pb::STEP_KIND_REDO);
  EXPECT_EQ(alice.redo().error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  // Undo then a new change: the redo list is gone.
  ASSERT_TRUE(alice.undo().ok());
  alice.drag(0, 0.2);
  EXPECT_EQ(alice.redo().error_code(), grpc::StatusCode::FAILED_PRECONDITION);
}

TEST(History, UndoKeepsAnotherEditorsIndependentChange) {
  TwoHandles e;
  Editor alice{e, "alice"}, bob{e, "bob"};
  alice.drag(0, 0.5);
  bob.drag(1, -0.5);
  pb::Session after;
  ASSERT_TRUE(alice.undo(&after).ok());
  EXPECT_DOUBLE_EQ(tz(after, 0), 0.0);
  EXPECT_DOUBLE_EQ(tz(after, 1), -0.5);  // Bob's later move of another handle stays
}

TEST(History, UndoThatWouldLoseALaterChangeIsRefusedNamingIt) {
  TwoHandles e;
  ASSERT_TRUE(e.grab(who("bob", "Bob"), {1}).ok());
  ASSERT_TRUE(e.release("bob").ok());
  Editor alice{e, "alice"}, bob{e, "bob"};
  alice.drag(1, 0.5);
  bob.drag(1, 0.9);  // Bob moved the same handle after her
  const auto before = e.state();
  const auto st = alice.undo();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("handle 1 changed since"), std::string::npos)
      << st.error_message();
  EXPECT_NE(st.error_message().find("Bob: moved handle 1"), std::string::npos)
      << st.error_message();
  EXPECT_EQ(e.state().version(), before.version());  // nothing changed
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.9);
  // Bob undoes his, then Alice's undo goes through.
  ASSERT_TRUE(bob.undo().ok());
  ASSERT_TRUE(alice.undo().ok());
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.0);
}

TEST(History, BetaAndConstraintChangesUndo) {
  TwoHandles e;
  Editor alice{e, "alice"};
  pb::SetBetaRequest b;
  b.set_name(e.s.name());
  b.mutable_beta()->set_value(0.25);
  b.set_client_id("alice");
  pb::Session out;
  ASSERT_TRUE(e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), b, &out).ok());
  const auto config = out.config_version();
  EXPECT_EQ(history(e).steps(0).kind(), pb::STEP_KIND_BETA);
  ASSERT_TRUE(alice.undo(&out).ok());
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.0);
  EXPECT_GT(out.config_version(), config);  // a β change like any other
  // Undo of the constraints (step 1, anonymous) by id: back to no constraints.
  const auto h = history(e);
  const std::int64_t first = h.steps(h.steps_size() - 1).id();
  ASSERT_TRUE(alice.undo(&out, first).ok());
  EXPECT_FALSE(out.constrained());
  ASSERT_TRUE(alice.redo(&out).ok());
  EXPECT_TRUE(out.constrained());
  EXPECT_EQ(out.constraints().handles_size(), 2);
}

// A β slider drag is one step (History::kGestureMs): undone in one Undo back to the β
// before the drag; a β set to what it is already is no step and no new version.
TEST(History, ASliderDragIsOneStep) {
  TwoHandles e;
  Editor alice{e, "alice"};
  auto set_beta = [&](const std::string& client, double v, pb::Session* out) {
    pb::SetBetaRequest b;
    b.set_name(e.s.name());
    b.mutable_beta()->set_value(v);
    b.set_client_id(client);
    return e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), b, out);
  };
  pb::Session out;
  ASSERT_TRUE(set_beta("alice", 0.1, &out).ok());  // a step of its own, then the drag
  std::this_thread::sleep_for(
      std::chrono::milliseconds(hdeform::service::History::kGestureMs + 100));
  const std::int64_t steps_before = history(e).total();
  for (int k = 2; k <= 27; ++k) ASSERT_TRUE(set_beta("alice", 0.01 * k * 3.5, &out).ok());
  const std::int64_t version = out.version();
  ASSERT_TRUE(set_beta("alice", 0.01 * 27 * 3.5, &out).ok());  // the last value again
  EXPECT_EQ(out.version(), version);
  const auto h = history(e);
  EXPECT_EQ(h.total(), steps_before + 1) << "26 values, one step";
  EXPECT_EQ(h.steps(0).kind(), pb::STEP_KIND_BETA);
  EXPECT_NE(h.steps(0).summary().find("beta 0.1 -> 0.945"), std::string::npos)
      << h.steps(0).summary();
  ASSERT_TRUE(alice.undo(&out).ok());
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.1) << "one Undo: the beta before the drag";

  // Another client's value in between starts a step of its own.
  ASSERT_TRUE(set_beta("alice", 0.2, &out).ok());
  ASSERT_TRUE(set_beta("bob", 0.3, &out).ok());
  ASSERT_TRUE(set_beta("alice", 0.4, &out).ok());
  const auto h2 = history(e);
  EXPECT_EQ(h2.steps(0).client_id(), "alice");
  EXPECT_EQ(h2.steps(1).client_id(), "bob");
  EXPECT_EQ(h2.steps(2).client_id(), "alice");
}

TEST(History, WatchersSeeStepsAndTheUndoneFrame) {
  TwoHandles e;
  Editor alice{e, "alice"};
  alice.drag(0, 0.5);
  grpc::ClientContext ctx;
  ctx.AddMetadata("authorization", "Bearer " + e.s.view_token());
  pb::WatchSessionRequest wr;
  wr.set_name(e.s.name());
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  auto reader = e.t.bare_stub->WatchSession(&ctx, wr);
  pb::SessionEvent ev;
  // The state event says the watcher is registered: an undo before it would not reach it.
  ASSERT_TRUE(reader->Read(&ev) && ev.has_state());
  ASSERT_TRUE(alice.undo().ok());
  bool step = false, frame = false;
  while ((!step || !frame) && reader->Read(&ev)) {
    if (ev.has_step() && ev.step().kind() == pb::STEP_KIND_UNDO) step = true;
    if (ev.has_frame() && step) {
      frame = true;
      ASSERT_EQ(ev.frame().transforms_size(), 2);
      EXPECT_DOUBLE_EQ(ev.frame().transforms(0).translation().z(), 0.0);
      EXPECT_FALSE(ev.frame().positions().empty());
    }
  }
  EXPECT_TRUE(step && frame);
  ctx.TryCancel();
}

TEST(History, PagesNewestFirstAndBadRequestsAreRefused) {
  TwoHandles e;
  Editor alice{e, "alice"};
  for (int i = 1; i <= 4; ++i) ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, i)}).ok());
  auto p1 = history(e, 2);
  ASSERT_EQ(p1.steps_size(), 2);
  EXPECT_EQ(p1.total(), 5);
  EXPECT_GT(p1.steps(0).id(), p1.steps(1).id());
  auto p2 = history(e, 2, p1.next_page_token());
  ASSERT_EQ(p2.steps_size(), 2);
  EXPECT_LT(p2.steps(0).id(), p1.steps(1).id());
  auto p3 = history(e, 2, p2.next_page_token());
  EXPECT_EQ(p3.steps_size(), 1);
  EXPECT_TRUE(p3.next_page_token().empty());
  for (const auto& [size, token] : std::vector<std::pair<int, std::string>>{
           {501, ""}, {-1, ""}, {2, "abc"}, {2, "-3"}}) {
    pb::ListHistoryRequest r;
    r.set_name(e.s.name());
    r.set_page_size(size);
    r.set_page_token(token);
    pb::ListHistoryResponse out;
    EXPECT_EQ(e.t.bare_stub->ListHistory(as(e.s.view_token()).get(), r, &out).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT)
        << size << " " << token;
  }
  Editor nobody{e, "nobody"};
  const auto st = nobody.undo();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(st.error_message().find("nothing to undo"), std::string::npos);
  EXPECT_EQ(nobody.undo(nullptr, 999).error_code(), grpc::StatusCode::NOT_FOUND);
  // The view token reads the history but cannot undo.
  pb::UndoRequest r;
  r.set_name(e.s.name());
  pb::Session out;
  EXPECT_EQ(e.t.bare_stub->Undo(as(e.s.view_token()).get(), r, &out).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
}

TEST(Snapshots, SaveListRestoreDeleteAndRestoreIsUndoable) {
  hdeform::service::ServerOptions o;
  o.request.max_snapshots = 2;
  TwoHandles e(o);
  ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, 0.4)}).ok());
  ASSERT_TRUE(save(e, "pose A").ok());
  ASSERT_TRUE(e.update("alice", {0, 1}, {translation(0, 0, 1), translation(0, 0, 1)}).ok());
  auto st = restore(e, "pose A");
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_DOUBLE_EQ(tz(e.state(), 0), 0.4);
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.0);
  EXPECT_EQ(history(e).steps(0).kind(), pb::STEP_KIND_RESTORE);
  EXPECT_EQ(history(e).steps(0).snapshot(), "pose A");
  Editor alice{e, "alice"};
  ASSERT_TRUE(alice.undo().ok());
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 1.0);

  pb::ListSnapshotsRequest lr;
  lr.set_name(e.s.name());
  pb::ListSnapshotsResponse list;
  ASSERT_TRUE(e.t.bare_stub->ListSnapshots(as(e.s.view_token()).get(), lr, &list).ok());
  ASSERT_EQ(list.snapshots_size(), 1);
  EXPECT_EQ(list.snapshots(0).name(), "pose A");
  EXPECT_TRUE(list.snapshots(0).snapshot().mesh_bytes().empty());

  ASSERT_TRUE(save(e, "pose B").ok());
  ASSERT_TRUE(save(e, "pose B").ok());  // replacing is not a new one
  st = save(e, "pose C");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(st.error_message().find("--max-snapshots"), std::string::npos) << st.error_message();
  EXPECT_EQ(save(e, "").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(save(e, std::string(65, 'x')).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(save(e, "a\nb").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(restore(e, "nope").error_code(), grpc::StatusCode::NOT_FOUND);

  pb::DeleteSnapshotRequest d;
  d.set_name(e.s.name());
  d.set_snapshot("pose A");
  pb::DeleteSnapshotResponse dr;
  ASSERT_TRUE(e.t.bare_stub->DeleteSnapshot(as(e.s.edit_token()).get(), d, &dr).ok());
  EXPECT_EQ(e.t.bare_stub->DeleteSnapshot(as(e.s.edit_token()).get(), d, &dr).error_code(),
            grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(restore(e, "pose A").error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(Snapshots, AreDurableWithTheSession) {
  char tmpl[] = "/tmp/hdeform-snapshots-XXXXXX";
  const fs::path dir = ::mkdtemp(tmpl);
  hdeform::service::ServerOptions o;
  o.state_dir = (dir / "state").string();
  std::string name, edit, view;
  {
    TwoHandles e(o);
    name = e.s.name();
    edit = e.s.edit_token();
    view = e.s.view_token();
    ASSERT_TRUE(e.update("alice", {1}, {translation(0, 0, 0.7)}).ok());
    ASSERT_TRUE(save(e, "kept").ok());
  }
  {
    TestServer t(o);  // a restarted server on the same state
    pb::ListSnapshotsRequest lr;
    lr.set_name(name);
    pb::ListSnapshotsResponse list;
    const auto st = t.bare_stub->ListSnapshots(as(view).get(), lr, &list);
    ASSERT_TRUE(st.ok()) << st.error_message();
    ASSERT_EQ(list.snapshots_size(), 1);
    EXPECT_EQ(list.snapshots(0).name(), "kept");
    EXPECT_DOUBLE_EQ(list.snapshots(0).snapshot().transforms(1).translation().z(), 0.7);
  }
  fs::remove_all(dir);
}

// History survives a restart: the steps, their undone flags and the redo lists come back
// with the session, and Undo / Redo work on them as before (timeline and snapshot steps too,
// which compare their values by identity with the restored session's).
TEST(History, SurvivesARestartAndUndoRedoWorkOnIt) {
  TempDir dir;
  hdeform::service::ServerOptions o;
  o.state_dir = (dir.path / "state").string();
  pb::Session session;
  std::string before_restart;
  auto set_beta = [](TwoHandles& e, double value) {
    pb::SetBetaRequest r;
    r.set_name(e.s.name());
    r.set_client_id("alice");
    r.mutable_beta()->set_value(value);
    pb::Session out;
    return e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), r, &out);
  };
  {
    TwoHandles e(o);
    session = e.s;
    Editor alice{e, "alice"};
    alice.drag(1, 0.7);
    ASSERT_TRUE(set_beta(e, 0.3).ok());
    ASSERT_TRUE(set_timeline(e, 2).ok());
    ASSERT_TRUE(save(e, "A").ok());
    ASSERT_TRUE(delete_snapshot(e, "A").ok());
    ASSERT_TRUE(alice.undo().ok());  // the delete: "A" is back, and Redo may delete it again
    before_restart = history(e, 500).SerializeAsString();
    EXPECT_EQ(history(e).total(), 7);
  }
  TwoHandles e(o, session);  // a new server on the same state
  Editor alice{e, "alice"};
  EXPECT_EQ(history(e, 500).SerializeAsString(), before_restart);
  ASSERT_EQ(snapshot_names(e).size(), 1u);
  auto st = alice.redo();  // the delete again
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(snapshot_names(e).empty());
  EXPECT_EQ(history(e).steps(0).id(), 8);  // ids go on where they were
  ASSERT_TRUE(alice.undo().ok());  // the delete
  EXPECT_EQ(snapshot_names(e).size(), 1u);
  st = alice.undo();  // the save
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(snapshot_names(e).empty());
  ASSERT_EQ(timeline_keys(e), 2);
  st = alice.undo();  // the timeline
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(timeline_keys(e), 0);
  pb::Session now;
  st = alice.undo(&now);  // β
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(now.beta().value(), 0);
  st = alice.undo(&now);  // the drag
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(now.transforms(1).translation().z(), 0);
  st = alice.undo();  // the constraints: by another client id (the fixture's), not alice's
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
}

// A session whose stored history is missing or unreadable opens with an empty one, and Undo
// says why it finds nothing.
TEST(History, AnUnreadableStoredHistoryIsSaidSo) {
  TempDir dir;
  hdeform::service::ServerOptions o;
  o.state_dir = (dir.path / "state").string();
  pb::Session session;
  {
    TwoHandles e(o);
    session = e.s;
    Editor alice{e, "alice"};
    alice.drag(1, 0.5);
  }
  auto set_history = [&](const char* sql) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir.path / "state" / "state.sqlite3").c_str(), &db), SQLITE_OK);
    char* err = nullptr;
    EXPECT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "");
    sqlite3_free(err);
    sqlite3_close(db);
  };
  set_history("UPDATE sessions SET history = x'ffff01'");
  {
    TwoHandles e(o, session);
    Editor alice{e, "alice"};
    EXPECT_EQ(history(e).total(), 0);
    const auto st = alice.undo();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(st.error_message().find("the stored history could not be read after a restart"),
              std::string::npos)
        << st.error_message();
    alice.drag(0, 0.2);  // a new history starts
  }
  set_history("UPDATE sessions SET history = NULL");
  TwoHandles e(o, session);
  Editor alice{e, "alice"};
  const auto st = alice.undo();
  EXPECT_NE(st.error_message().find("restored from stored state that kept no history"),
            std::string::npos)
      << st.error_message();
}

// A stored history is input too (a state folder or Redis others can write): what Undo
// would apply from it is checked before it is adopted, and a bad one changes nothing.
TEST(History, AStoredHistoryIsCheckedBeforeItIsAdopted) {
  using hdeform::service::History;
  namespace st = hdeform::state;
  hdeform::service::HistoryContext context;
  context.parse_beta = [](const pb::Beta& b) {
    hdeform::service::SessionBeta out;
    out.uniform = hdeform::service::from_proto(b);
    return out;
  };
  auto step = [](st::StoredHistory& h, std::int64_t id) {
    st::StoredStep* s = h.add_steps();
    s->mutable_info()->set_id(id);
    s->mutable_info()->set_kind(pb::STEP_KIND_BETA);
    s->set_beta(true);
    return s;
  };
  auto refused = [&](const st::StoredHistory& h, const std::string& why) {
    History history({});
    try {
      hdeform::service::history_from_record(h, context, history);
      ADD_FAILURE() << "adopted; expected: " << why;
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    EXPECT_EQ(history.size(), 0);
  };
  st::StoredHistory good;
  good.set_format(hdeform::service::kHistoryFormat);
  step(good, 1)->mutable_after()->mutable_beta()->set_value(0.25);
  step(good, 2)->mutable_after()->mutable_beta()->set_value(0.5);
  History adopted({});
  hdeform::service::history_from_record(good, context, adopted);
  EXPECT_EQ(adopted.size(), 2);
  EXPECT_EQ(adopted.next_id(), 3);
  EXPECT_EQ(adopted.steps().back().after.beta.uniform.value, 0.5);

  st::StoredHistory h = good;
  h.set_format(7);
  refused(h, "format 7");
  h = good;
  h.mutable_steps(1)->mutable_info()->set_id(1);
  refused(h, "not increasing");
  h = good;
  h.mutable_steps(1)->mutable_after()->mutable_beta()->set_value(1.5);
  refused(h, "beta");
  h = good;
  h.mutable_steps(1)->set_beta(false);
  h.mutable_steps(1)->set_timeline(true);
  h.mutable_steps(1)->mutable_after()->set_timeline(3);
  refused(h, "timeline reference 3 is out of range");
  h.add_values()->mutable_snapshot();
  h.add_values();
  h.add_values();
  refused(h, "timeline reference 3 names another kind of value");
  h = good;
  h.mutable_steps(1)->set_beta(false);
  h.mutable_steps(1)->add_handles(4);
  refused(h, "names handle 4");
  h = good;
  h.mutable_steps(1)->set_constraints(true);
  h.mutable_steps(1)->mutable_after()->set_cs_key("cs/x");  // and no constraints
  refused(h, "constraints without their transforms");
}

TEST(History, AnUpdateThatChangesNothingIsNoStep) {
  TwoHandles e;
  ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, 0)}).ok());  // a frame refresh
  // The viewer's refresh after Apply: identity with an explicit pivot (its centroid) moves
  // nothing either.
  pb::HandleTransform pivoted = translation(0, 0, 0);
  pivoted.mutable_pivot()->set_x(0.3);
  pivoted.mutable_pivot()->set_y(-2);
  ASSERT_TRUE(e.update("alice", {0, 1}, {pivoted, pivoted}).ok());
  Editor alice{e, "alice"};
  alice.drag(1, 0.0);  // a drag that ends where it began
  EXPECT_EQ(history(e).total(), 1);  // only the constraints
  EXPECT_EQ(alice.undo().error_code(), grpc::StatusCode::FAILED_PRECONDITION);
}

// Everything a user can change is a step: timeline edits, snapshot saves and deletes undo
// and redo like moves; one that changes nothing is no step.
TEST(History, TimelineEditsAndSnapshotSavesAndDeletesAreUndoable) {
  TwoHandles e;
  Editor alice{e, "alice"};
  const auto version = e.state().version();
  ASSERT_TRUE(set_timeline(e, 2).ok());
  ASSERT_TRUE(set_timeline(e, 3).ok());
  const auto steps = history(e).total();
  ASSERT_TRUE(set_timeline(e, 3).ok());  // the same keys: no step
  EXPECT_EQ(history(e).total(), steps);
  EXPECT_EQ(history(e).steps(0).kind(), pb::STEP_KIND_TIMELINE);
  EXPECT_TRUE(history(e).steps(0).timeline_changed());
  EXPECT_EQ(e.state().version(), version);  // the pose did not change
  ASSERT_TRUE(alice.undo().ok());
  EXPECT_EQ(timeline_keys(e), 2);
  ASSERT_TRUE(alice.undo().ok());
  EXPECT_EQ(timeline_keys(e), 0);
  ASSERT_TRUE(alice.redo().ok());
  EXPECT_EQ(timeline_keys(e), 2);

  ASSERT_TRUE(save(e, "pose A").ok());
  const auto saved = snapshot_names(e);
  ASSERT_EQ(saved.size(), 1u);
  ASSERT_TRUE(delete_snapshot(e, "pose A").ok());
  EXPECT_TRUE(snapshot_names(e).empty());
  EXPECT_EQ(history(e).steps(0).kind(), pb::STEP_KIND_SNAPSHOT_DELETE);
  EXPECT_EQ(history(e).steps(0).snapshot(), "pose A");
  ASSERT_TRUE(alice.undo().ok());
  EXPECT_EQ(snapshot_names(e), saved);  // the very snapshot, back
  ASSERT_TRUE(restore(e, "pose A").ok());
  // Undo of the save by id: gone again; a save under the name since refuses it.
  const auto h = history(e, 500);
  std::int64_t save_step = 0;
  for (const auto& s : h.steps())
    if (s.kind() == pb::STEP_KIND_SNAPSHOT_SAVE) save_step = s.id();
  ASSERT_NE(save_step, 0);
  ASSERT_TRUE(save(e, "pose A").ok());  // replaced since
  auto st = alice.undo(nullptr, save_step);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("snapshot 'pose A'"), std::string::npos) << st.error_message();
  ASSERT_TRUE(alice.undo().ok());  // the replacing save: the first one is back
  EXPECT_EQ(snapshot_names(e), saved);
  ASSERT_TRUE(alice.undo(nullptr, save_step).ok());
  EXPECT_TRUE(snapshot_names(e).empty());
}

// Retries are safe: a change repeated with the same request_id answers as the first did and
// applies nothing more; a call that applied nothing (refused) is not remembered, so its
// retry may apply; ids are per method and at most 64 bytes.
TEST(Retries, ARepeatedRequestIdAnswersTheFirstAnswerWithoutApplyingAgain) {
  TwoHandles e;
  ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, 0.4)}).ok());
  ASSERT_TRUE(e.update("alice", {1}, {translation(0, 0, 0.2)}).ok());
  auto undo = [&](const std::string& id, pb::Session* out) {
    pb::UndoRequest r;
    r.set_name(e.s.name());
    r.set_client_id("alice");
    r.set_request_id(id);
    return e.t.bare_stub->Undo(as(e.s.edit_token()).get(), r, out);
  };
  pb::Session first, again;
  ASSERT_TRUE(undo("u-1", &first).ok());
  const auto steps = history(e).total();
  auto st = undo("u-1", &again);  // the answer was lost: the client retries
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(again.SerializeAsString(), first.SerializeAsString());
  EXPECT_EQ(history(e).total(), steps);  // no second undo
  EXPECT_DOUBLE_EQ(tz(e.state(), 0), 0.4);  // handle 0's move stands
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.0);
  ASSERT_TRUE(undo("u-2", &again).ok());  // a new id: the next undo
  EXPECT_DOUBLE_EQ(tz(e.state(), 0), 0.0);

  // Refused first (nothing applied): not remembered, the retry applies once it can.
  pb::RestoreSnapshotRequest r;
  r.set_name(e.s.name());
  r.set_snapshot("later");
  r.set_client_id("alice");
  r.set_request_id("r-1");
  pb::Session out;
  EXPECT_EQ(e.t.bare_stub->RestoreSnapshot(as(e.s.edit_token()).get(), r, &out).error_code(),
            grpc::StatusCode::NOT_FOUND);
  ASSERT_TRUE(save(e, "later").ok());
  st = e.t.bare_stub->RestoreSnapshot(as(e.s.edit_token()).get(), r, &out);
  EXPECT_TRUE(st.ok()) << st.error_message();

  // Per method: the same id on another call is another request.
  pb::SetBetaRequest b;
  b.set_name(e.s.name());
  b.mutable_beta()->set_value(0.25);
  b.set_client_id("alice");
  b.set_request_id("u-1");
  ASSERT_TRUE(e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), b, &out).ok());
  EXPECT_DOUBLE_EQ(out.beta().value(), 0.25);

  b.set_request_id(std::string(65, 'x'));
  st = e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), b, &out);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("request_id"), std::string::npos) << st.error_message();
}

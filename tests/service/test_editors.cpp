// Several editors in one session (docs/api.md "Several editors"): updates that name their
// handles, grabs with leases, presence on the watch stream, and stale constraint / β changes
// refused. A real server over loopback; the clients present real session tokens.
#include "editors_fixture.h"
#include "service/session/handle_update.h"

#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>

using namespace hdeform::testing;

namespace {

// Collects one client's WatchSession stream (presence and frames) on its own thread.
struct PresenceWatcher {
  grpc::ClientContext ctx;
  std::unique_ptr<grpc::ClientReader<pb::SessionEvent>> reader;
  std::thread thread;
  std::mutex mutex;
  std::condition_variable cv;
  pb::Presence presence;
  int presences = 0;
  std::vector<pb::Frame> frames;
  bool ended = false;

  PresenceWatcher(TestServer& t, const std::string& name, const std::string& token,
                  const pb::Participant* client) {
    ctx.AddMetadata("authorization", "Bearer " + token);
    pb::WatchSessionRequest req;
    req.set_name(name);
    if (client) *req.mutable_client() = *client;
    reader = t.bare_stub->WatchSession(&ctx, req);
    thread = std::thread([this] {
      pb::SessionEvent ev;
      while (reader->Read(&ev)) {
        std::lock_guard lock(mutex);
        if (ev.has_presence()) {
          presence = ev.presence();
          ++presences;
        }
        if (ev.has_frame()) frames.push_back(ev.frame());
        cv.notify_all();
      }
      reader->Finish();
      std::lock_guard lock(mutex);
      ended = true;
      cv.notify_all();
    });
  }
  ~PresenceWatcher() { stop(); }
  void stop() {
    ctx.TryCancel();
    if (thread.joinable()) thread.join();
  }
  template <class Pred>
  bool wait(Pred pred) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, std::chrono::seconds(20), [&] { return pred(); });
  }
  // A copy of participant `id` in the latest presence (empty if absent), read under the
  // lock: the reader thread replaces `presence` at any time.
  pb::Participant copy_of(const std::string& id) {
    std::lock_guard lock(mutex);
    const auto* p = find(id);
    return p ? *p : pb::Participant{};
  }
  int participants() {
    std::lock_guard lock(mutex);
    return presence.participants_size();
  }
  // The participant with `id` in the latest presence, or null (hold `mutex`: in wait()).
  const pb::Participant* find(const std::string& id) const {
    for (const auto& p : presence.participants())
      if (p.client_id() == id) return &p;
    return nullptr;
  }
};

}  // namespace

TEST(Editors, UpdatesNamingHandlesKeepTheOthers) {
  TwoHandles e;
  pb::Frame fa, fb;
  ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, 0.5)}, &fa).ok());
  auto st = e.update("bob", {1}, {translation(0, 0, -0.25)}, &fb);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const pb::Session now = e.state();
  EXPECT_DOUBLE_EQ(tz(now, 0), 0.5);   // Alice's move survives Bob's update
  EXPECT_DOUBLE_EQ(tz(now, 1), -0.25);
  // Frames say whose update they answer and every handle's transform.
  EXPECT_EQ(fb.client_id(), "bob");
  ASSERT_EQ(fb.transforms_size(), 2);
  EXPECT_DOUBLE_EQ(fb.transforms(0).translation().z(), 0.5);
  EXPECT_DOUBLE_EQ(fb.transforms(1).translation().z(), -0.25);
  // Without `handles` an update still sets every handle.
  ASSERT_TRUE(e.update("", {}, {translation(0, 0, 0), translation(0, 0, 0.125)}).ok());
  EXPECT_DOUBLE_EQ(tz(e.state(), 0), 0.0);
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.125);
}

TEST(Editors, AGrabbedHandleIsRefusedToOthersWithTheHoldersName) {
  TwoHandles e;
  ASSERT_TRUE(e.grab(who("alice-1", "Alice"), {0}).ok());
  auto st = e.grab(who("bob-2", "Bob"), {0});
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("held by Alice"), std::string::npos) << st.error_message();
  // A refused grab takes nothing: handle 1 stays free for Bob.
  st = e.grab(who("bob-2", "Bob"), {1, 0});
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  st = e.update("bob-2", {0}, {translation(0, 0, 1)});
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("handle 0 is held by Alice"), std::string::npos)
      << st.error_message();
  // An anonymous update of every handle would move Alice's too: refused.
  st = e.update("", {}, {translation(0, 0, 1), translation(0, 0, 1)});
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_TRUE(e.update("bob-2", {1}, {translation(0, 0, 0.3)}).ok());
  EXPECT_TRUE(e.update("alice-1", {0}, {translation(0, 0, 0.7)}).ok());
  EXPECT_DOUBLE_EQ(tz(e.state(), 0), 0.7);
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.3);
  // Released: Bob may take it.
  ASSERT_TRUE(e.release("alice-1").ok());
  EXPECT_TRUE(e.grab(who("bob-2", "Bob"), {0}).ok());
  // The holder grabbing again renews (not refused).
  EXPECT_TRUE(e.grab(who("bob-2", "Bob"), {0}).ok());
}

TEST(Editors, ALeaseRunsOutWhenNotRenewed) {
  TwoHandles e;
  pb::GrabHandlesResponse r;
  ASSERT_TRUE(e.grab(who("alice", "Alice"), {0}, 200, &r).ok());
  EXPECT_GT(r.lease_expire_unix_ms(), 0);
  ASSERT_EQ(r.presence().participants_size(), 1);
  EXPECT_EQ(r.presence().participants(0).held_handles_size(), 1);
  EXPECT_EQ(e.grab(who("bob", "Bob"), {0}).error_code(), grpc::StatusCode::ABORTED);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // Past its lease the grab is void at once, before the sweeper has run.
  EXPECT_TRUE(e.update("bob", {0}, {translation(0, 0, 1)}).ok());
  EXPECT_TRUE(e.grab(who("bob", "Bob"), {0}).ok());
}

TEST(Editors, UpdatesByTheHolderRenewItsLease) {
  TwoHandles e;
  ASSERT_TRUE(e.grab(who("alice", "Alice"), {0}, 400).ok());
  for (int i = 0; i < 6; ++i) {  // 6 × 150 ms: well past one lease, renewed by each update
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, 0.1 * i)}).ok());
  }
  EXPECT_EQ(e.grab(who("bob", "Bob"), {0}).error_code(), grpc::StatusCode::ABORTED);
}

TEST(Editors, WatchersSeePresenceLiveAndAVanishedClientHoldsNothing) {
  TwoHandles e;
  const pb::Participant alice = who("alice", "Alice"), viewer = who("v-9", "Vera");
  PresenceWatcher w(e.t, e.s.name(), e.s.view_token(), &viewer);
  ASSERT_TRUE(w.wait([&] { return w.find("v-9") != nullptr; }));
  const pb::Participant vera = w.copy_of("v-9");
  EXPECT_FALSE(vera.editor());  // the view token
  EXPECT_TRUE(vera.watching());
  EXPECT_EQ(vera.color().size(), 7u);  // one picked for it
  {
    auto a = std::make_unique<PresenceWatcher>(e.t, e.s.name(), e.s.edit_token(), &alice);
    ASSERT_TRUE(w.wait([&] { return w.find("alice") != nullptr; }));
    EXPECT_TRUE(w.copy_of("alice").editor());
    EXPECT_EQ(w.copy_of("alice").display_name(), "Alice");
    ASSERT_TRUE(e.grab(alice, {1}).ok());
    ASSERT_TRUE(w.wait([&] {
      const auto* p = w.find("alice");
      return p && p->held_handles_size() == 1 && p->held_handles(0) == 1;
    }));
    // Alice's frames reach the watcher with her id.
    ASSERT_TRUE(e.update("alice", {1}, {translation(0, 0, 0.2)}).ok());
    ASSERT_TRUE(w.wait([&] { return !w.frames.empty() && w.frames.back().client_id() == "alice"; }));
    a->stop();  // Alice's tab closes without releasing
  }
  ASSERT_TRUE(w.wait([&] { return w.find("alice") == nullptr; }));
  EXPECT_TRUE(e.grab(who("bob", "Bob"), {1}).ok());
  // A watcher without a client identity is counted but not listed.
  PresenceWatcher anon(e.t, e.s.name(), e.s.view_token(), nullptr);
  ASSERT_TRUE(anon.wait([&] { return anon.presences > 0; }));
  EXPECT_EQ(anon.participants(), 2);  // Vera watching, Bob grabbing
}

// Issue 35.8: a client id belongs to the role that claimed it first. A view token cannot take
// an editor's identity (nor keep its grabs alive after the editor's stream ends); an edit
// claim takes an id a viewer holds, and the viewer's stream then changes nothing.
TEST(Editors, AViewTokenCannotTakeAnEditorsIdentity) {
  TwoHandles e;
  PresenceWatcher w(e.t, e.s.name(), e.s.view_token(), nullptr);  // sees presence only
  const pb::Participant alice = who("alice", "Alice"), mallory = who("alice", "Mallory");
  auto a = std::make_unique<PresenceWatcher>(e.t, e.s.name(), e.s.edit_token(), &alice);
  ASSERT_TRUE(w.wait([&] { return w.find("alice") != nullptr; }));
  ASSERT_TRUE(e.grab(alice, {0}).ok());
  {
    PresenceWatcher m(e.t, e.s.name(), e.s.view_token(), &mallory);
    ASSERT_TRUE(m.wait([&] { return m.ended; }));  // refused at once
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer " + e.s.view_token());
    pb::WatchSessionRequest req;
    req.set_name(e.s.name());
    *req.mutable_client() = mallory;
    auto reader = e.t.bare_stub->WatchSession(&ctx, req);
    pb::SessionEvent ev;
    EXPECT_FALSE(reader->Read(&ev));
    const auto st = reader->Finish();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::ALREADY_EXISTS) << st.error_message();
    EXPECT_NE(st.error_message().find("belongs to an editor"), std::string::npos)
        << st.error_message();
  }
  EXPECT_EQ(w.copy_of("alice").display_name(), "Alice");
  EXPECT_TRUE(w.copy_of("alice").editor());
  // Alice's tab closes: her grab ends with it, whatever a viewer claimed.
  a->stop();
  ASSERT_TRUE(w.wait([&] { return w.find("alice") == nullptr; }));
  EXPECT_TRUE(e.grab(who("bob", "Bob"), {0}).ok());

  // The other way round: a viewer claims "carol" first; the editor Carol takes it over, and
  // the viewer's stream ending takes nothing from her.
  const pb::Participant carol = who("carol", "Carol"), squatter = who("carol", "Squatter");
  auto v = std::make_unique<PresenceWatcher>(e.t, e.s.name(), e.s.view_token(), &squatter);
  ASSERT_TRUE(w.wait([&] { return w.find("carol") != nullptr; }));
  EXPECT_FALSE(w.copy_of("carol").editor());
  PresenceWatcher c(e.t, e.s.name(), e.s.edit_token(), &carol);
  ASSERT_TRUE(w.wait([&] {
    const auto* p = w.find("carol");
    return p && p->editor() && p->display_name() == "Carol";
  }));
  ASSERT_TRUE(e.grab(carol, {1}).ok());
  v->stop();
  ASSERT_TRUE(v->wait([&] { return v->ended; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const pb::Participant still = w.copy_of("carol");
  EXPECT_EQ(still.display_name(), "Carol");
  EXPECT_TRUE(still.watching());
  ASSERT_EQ(still.held_handles_size(), 1);
  EXPECT_EQ(e.grab(who("bob", "Bob"), {1}).error_code(), grpc::StatusCode::ABORTED);
}

TEST(Editors, LeaseExpiryReachesWatchers) {
  TwoHandles e;
  const pb::Participant viewer = who("v", "Vera");
  PresenceWatcher w(e.t, e.s.name(), e.s.view_token(), &viewer);
  ASSERT_TRUE(e.grab(who("alice", "Alice"), {0}, 150).ok());
  ASSERT_TRUE(w.wait([&] { return w.find("alice") != nullptr; }));
  // The sweeper (≤ 1 s period) ends the lease and tells the watchers.
  ASSERT_TRUE(w.wait([&] { return w.find("alice") == nullptr; }));
}

TEST(Editors, StaleConstraintAndBetaChangesAreRefused) {
  TwoHandles e;
  const std::int64_t c0 = e.s.config_version();
  ASSERT_GT(c0, 0);
  // Handle moves do not make a β change stale.
  ASSERT_TRUE(e.update("alice", {0}, {translation(0, 0, 0.5)}).ok());
  pb::SetBetaRequest r;
  r.set_name(e.s.name());
  r.mutable_beta()->set_value(0.1);
  r.set_expected_config_version(c0);
  pb::Session after;
  auto st = e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), r, &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(after.config_version(), c0 + 1);
  // Another editor's change made against c0 is now stale: refused, the state untouched.
  r.mutable_beta()->set_value(0.3);
  st = e.t.bare_stub->SetBeta(as(e.s.edit_token()).get(), r, &after);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("changed since config_version"), std::string::npos)
      << st.error_message();
  EXPECT_DOUBLE_EQ(e.state().beta().value(), 0.1);
  pb::SetConstraintsRequest c;
  c.set_name(e.s.name());
  *c.mutable_constraints() = cactus_constraints();  // any: refused before it is read
  c.set_expected_config_version(c0);
  st = e.t.bare_stub->SetConstraints(as(e.s.edit_token()).get(), c, &after);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_EQ(e.state().constraints().handles_size(), 2);
}

TEST(Editors, NewConstraintsEndEveryGrab) {
  TwoHandles e;
  ASSERT_TRUE(e.grab(who("alice", "Alice"), {0, 1}).ok());
  pb::Session out;
  pb::Constraints c;
  *c.mutable_fixed()->add_selectors() = box(-1, -0.01, 4, 0.01);
  *c.add_handles()->add_selectors() = box(2.9, 2.6, 3.2, 3);
  ASSERT_TRUE(e.t.set_constraints(e.s.name(), c, &out).ok());
  EXPECT_TRUE(e.grab(who("bob", "Bob"), {0}).ok());  // handle 0 is another region now
}

TEST(Editors, CoalescedPartialUpdatesAreNeverLost) {
  TwoHandles e;
  // Many pipelined updates from two editors at once: whichever are superseded, each
  // editor's last move is in the final state.
  std::vector<std::thread> threads;
  std::atomic<int> superseded{0}, failed{0};
  for (int client = 0; client < 2; ++client)
    threads.emplace_back([&, client] {
      for (int i = 1; i <= 8; ++i) {
        pb::Frame f;
        const auto st = e.update(client ? "bob" : "alice", {client},
                                 {translation(0, 0, (client ? -0.01 : 0.01) * i)}, &f, true);
        if (!st.ok()) ++failed;
        if (f.superseded()) ++superseded;
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(failed.load(), 0);
  std::printf("[ measured ] %d of 16 updates superseded\n", superseded.load());
  const pb::Session now = e.state();
  EXPECT_DOUBLE_EQ(tz(now, 0), 0.08);
  EXPECT_DOUBLE_EQ(tz(now, 1), -0.08);
}

TEST(Editors, DeformStreamsMergePartialUpdatesTheyCoalesce) {
  using hdeform::service::merge_deform_requests;
  pb::DeformRequest pending, newer;
  pending.add_handles(0);
  *pending.add_transforms() = translation(0, 0, 1);
  pending.mutable_beta()->set_value(0.2);
  newer.add_handles(1);
  *newer.add_transforms() = translation(0, 0, 2);
  newer.set_sequence(7);
  merge_deform_requests(pending, std::move(newer));
  EXPECT_EQ(pending.sequence(), 7);
  ASSERT_EQ(pending.handles_size(), 2);
  EXPECT_EQ(pending.handles(0), 0);
  EXPECT_DOUBLE_EQ(pending.transforms(0).translation().z(), 1);
  EXPECT_DOUBLE_EQ(pending.transforms(1).translation().z(), 2);
  EXPECT_DOUBLE_EQ(pending.beta().value(), 0.2);  // the β only the older one set stays
  // A full update then a partial one: the partial is laid over the full list.
  pb::DeformRequest full, part;
  *full.add_transforms() = translation(0, 0, 1);
  *full.add_transforms() = translation(0, 0, 1);
  part.add_handles(1);
  *part.add_transforms() = translation(0, 0, 3);
  merge_deform_requests(full, std::move(part));
  EXPECT_EQ(full.handles_size(), 0);
  ASSERT_EQ(full.transforms_size(), 2);
  EXPECT_DOUBLE_EQ(full.transforms(0).translation().z(), 1);
  EXPECT_DOUBLE_EQ(full.transforms(1).translation().z(), 3);
  // A β-only message keeps the move before it.
  pb::DeformRequest beta_only;
  beta_only.mutable_beta()->set_value(0.4);
  merge_deform_requests(full, std::move(beta_only));
  EXPECT_EQ(full.transforms_size(), 2);
  EXPECT_DOUBLE_EQ(full.beta().value(), 0.4);
}

TEST(Editors, DeformStreamsNameTheirHandles) {
  TwoHandles e;
  ASSERT_TRUE(e.grab(who("alice", "Alice"), {0}).ok());
  grpc::ClientContext ctx;
  ctx.AddMetadata("authorization", "Bearer " + e.s.edit_token());
  auto stream = e.t.bare_stub->Deform(&ctx);
  pb::DeformRequest r;
  r.set_name(e.s.name());
  r.set_sequence(1);
  r.set_client_id("bob");
  r.add_handles(1);
  *r.add_transforms() = translation(0, 0, 0.4);
  ASSERT_TRUE(stream->Write(r));
  pb::Frame f;
  ASSERT_TRUE(stream->Read(&f));
  EXPECT_EQ(f.client_id(), "bob");
  r.set_sequence(2);
  r.set_handles(0, 0);  // Alice's
  ASSERT_TRUE(stream->Write(r));
  stream->WritesDone();
  while (stream->Read(&f)) {
  }
  const auto st = stream->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("held by Alice"), std::string::npos) << st.error_message();
  EXPECT_DOUBLE_EQ(tz(e.state(), 1), 0.4);
  EXPECT_DOUBLE_EQ(tz(e.state(), 0), 0.0);
}

TEST(Editors, BadInputsGetPreciseErrors) {
  TwoHandles e;
  struct Case {
    pb::Participant p;
    std::vector<int> handles;
    int lease;
    grpc::StatusCode code;
    const char* says;
  };
  pb::Participant long_name = who("x", std::string(65, 'a'));
  pb::Participant control = who("x", "tab\there");
  pb::Participant colour = who("x", "X");
  colour.set_color("red");
  const std::vector<Case> cases = {
      {who("", "A"), {0}, 0, grpc::StatusCode::INVALID_ARGUMENT, "client_id must be"},
      {who("a b", "A"), {0}, 0, grpc::StatusCode::INVALID_ARGUMENT, "client_id must be"},
      {who(std::string(65, 'a'), "A"), {0}, 0, grpc::StatusCode::INVALID_ARGUMENT,
       "client_id must be"},
      {long_name, {0}, 0, grpc::StatusCode::INVALID_ARGUMENT, "65 characters"},
      {control, {0}, 0, grpc::StatusCode::INVALID_ARGUMENT, "control characters"},
      {colour, {0}, 0, grpc::StatusCode::INVALID_ARGUMENT, "#rrggbb"},
      {who("a", "A"), {}, 0, grpc::StatusCode::INVALID_ARGUMENT, "handles is empty"},
      {who("a", "A"), {2}, 0, grpc::StatusCode::INVALID_ARGUMENT, "is not a handle"},
      {who("a", "A"), {-1}, 0, grpc::StatusCode::INVALID_ARGUMENT, "is not a handle"},
      {who("a", "A"), {1, 1}, 0, grpc::StatusCode::INVALID_ARGUMENT, "twice"},
      {who("a", "A"), {0}, 60001, grpc::StatusCode::INVALID_ARGUMENT, "--max-lease-ms"},
      {who("a", "A"), {0}, -5, grpc::StatusCode::INVALID_ARGUMENT, "lease_ms"},
  };
  for (const auto& c : cases) {
    const auto st = e.grab(c.p, c.handles, c.lease);
    EXPECT_EQ(st.error_code(), c.code) << c.says << ": " << st.error_message();
    EXPECT_NE(st.error_message().find(c.says), std::string::npos) << st.error_message();
  }
  // Read-only: the view token cannot grab.
  auto st = e.grab(who("a", "A"), {0}, 0, nullptr, e.s.view_token());
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  // Updates naming handles badly.
  st = e.update("a", {0, 1}, {translation(0, 0, 1)});
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("one transform per named handle"), std::string::npos);
  st = e.update("a", {5}, {translation(0, 0, 1)});
  EXPECT_NE(st.error_message().find("is not a handle"), std::string::npos) << st.error_message();
  st = e.update("a", {1, 1}, {translation(0, 0, 1), translation(0, 0, 1)});
  EXPECT_NE(st.error_message().find("twice"), std::string::npos) << st.error_message();
  st = e.update("a b", {0}, {translation(0, 0, 1)});  // ids are only checked where kept
  EXPECT_TRUE(st.ok()) << st.error_message();
  // A watcher with a bad identity is refused before it is counted.
  pb::WatchSessionRequest wr;
  wr.set_name(e.s.name());
  *wr.mutable_client() = colour;
  auto ctx = as(e.s.view_token());
  auto reader = e.t.bare_stub->WatchSession(ctx.get(), wr);
  pb::SessionEvent ev;
  EXPECT_FALSE(reader->Read(&ev));
  st = reader->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("#rrggbb"), std::string::npos) << st.error_message();
  // Grabs before any constraints.
  pb::Session bare;
  ASSERT_TRUE(e.t.upload(grid_off(4), "g.off", &bare).ok());
  pb::GrabHandlesRequest g;
  g.set_name(bare.name());
  *g.mutable_client() = who("a", "A");
  g.add_handles(0);
  pb::GrabHandlesResponse resp;
  st = e.t.bare_stub->GrabHandles(as(bare.edit_token()).get(), g, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
}

TEST(Editors, HandleWeightsAreTheHarmonicFieldForASoftSelectionPreview) {
  TwoHandles e;
  pb::GetHandleWeightsRequest r;
  r.set_name(e.s.name());
  r.set_handle(1);
  pb::HandleWeights w;
  auto st = e.t.bare_stub->GetHandleWeights(as(e.s.view_token()).get(), r, &w);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(w.weights().size(), 4u * 144);  // 12×12 grid, float32 per vertex
  std::vector<float> phi(144);
  std::memcpy(phi.data(), w.weights().data(), w.weights().size());
  const auto& c = e.s.constraints();
  for (int id : c.handles(1).ids()) EXPECT_EQ(phi[static_cast<std::size_t>(id)], 1.0f);
  for (int id : c.handles(0).ids()) EXPECT_EQ(phi[static_cast<std::size_t>(id)], 0.0f);
  for (int id : c.fixed().ids()) EXPECT_EQ(phi[static_cast<std::size_t>(id)], 0.0f);
  // The maximum principle: free vertices lie strictly between.
  int inside = 0;
  for (float v : phi) {
    EXPECT_GE(v, 0.0f);
    EXPECT_LE(v, 1.0f);
    inside += v > 0.0f && v < 1.0f;
  }
  EXPECT_GT(inside, 100);
  r.set_handle(2);
  st = e.t.bare_stub->GetHandleWeights(as(e.s.view_token()).get(), r, &w);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("handle 2 is not a handle"), std::string::npos);
  pb::Session bare;
  ASSERT_TRUE(e.t.upload(grid_off(4), "g.off", &bare).ok());
  r.set_name(bare.name());
  r.set_handle(0);
  st = e.t.bare_stub->GetHandleWeights(as(bare.view_token()).get(), r, &w);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  st = e.t.bare_stub->GetHandleWeights(as("not-a-token").get(), r, &w);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED);
}

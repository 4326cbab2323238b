// Live streams: Deform (latest wins) and WatchSession (every observer sees every frame).
#include "service_fixture.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

using namespace hdeform::testing;

TEST(ServiceStreams, DeformBurstIsLatestWins) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  constexpr int kUpdates = 1000;

  grpc::ClientContext ctx;
  auto stream = t.stub->Deform(&ctx);
  for (int i = 1; i <= kUpdates; ++i) {
    const std::string name = i == 1 ? s.name() : "";  // the first message names the session
    ASSERT_TRUE(stream->Write(deform_request(name, i, translation(0, 0.0005 * i, 0))));
  }
  stream->WritesDone();
  std::vector<std::int64_t> seqs;
  pb::Frame f, last;
  while (stream->Read(&f)) {
    seqs.push_back(f.sequence());
    last = f;
  }
  auto st = stream->Finish();
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_FALSE(seqs.empty());
  std::printf("[   info   ] %d updates answered by %zu frames\n", kUpdates, seqs.size());
  EXPECT_EQ(seqs.back(), kUpdates);  // the last frame answers the last update
  EXPECT_LT(seqs.size(), static_cast<std::size_t>(kUpdates));  // fewer solves than updates
  for (std::size_t i = 1; i < seqs.size(); ++i) EXPECT_LT(seqs[i - 1], seqs[i]);
  EXPECT_EQ(last.positions().size(), 5261u * 12);

  // The session now holds the last update's transform.
  pb::Session now;
  ASSERT_TRUE(t.get_session(s.name(), &now).ok());
  ASSERT_EQ(now.transforms_size(), 1);
  EXPECT_DOUBLE_EQ(now.transforms(0).translation().y(), 0.0005 * kUpdates);
  EXPECT_EQ(now.version(), last.version());
}

TEST(ServiceStreams, DeformChangesBetaAndAnswersEachUpdate) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  grpc::ClientContext ctx;
  auto stream = t.stub->Deform(&ctx);
  pb::Frame f0, f1;
  {
    ASSERT_TRUE(stream->Write(deform_request(s.name(), 1, cactus_transform())));
    ASSERT_TRUE(stream->Read(&f0));
    EXPECT_EQ(f0.sequence(), 1);
  }
  {
    pb::DeformRequest req;  // β only: transforms stay
    req.set_sequence(2);
    req.mutable_beta()->set_value(0.4);
    ASSERT_TRUE(stream->Write(req));
    ASSERT_TRUE(stream->Read(&f1));
    EXPECT_EQ(f1.sequence(), 2);
    EXPECT_DOUBLE_EQ(f1.beta().value(), 0.4);
    EXPECT_NE(f1.positions(), f0.positions());
  }
  stream->WritesDone();
  pb::Frame extra;
  EXPECT_FALSE(stream->Read(&extra));
  EXPECT_TRUE(stream->Finish().ok());
}

namespace {
// Collects a WatchSession stream on its own thread.
struct Watcher {
  grpc::ClientContext ctx;
  std::unique_ptr<grpc::ClientReader<pb::SessionEvent>> reader;
  std::thread thread;
  std::mutex mutex;
  std::condition_variable cv;
  std::map<std::int64_t, std::string> frames;  // sequence → positions
  int states = 0;
  std::string deleted;
  bool ended = false;
  grpc::Status status;

  Watcher(TestServer& t, const std::string& name) {
    pb::WatchSessionRequest req;
    req.set_name(name);
    reader = t.stub->WatchSession(&ctx, req);
    thread = std::thread([this] {
      pb::SessionEvent ev;
      while (reader->Read(&ev)) {
        std::lock_guard lock(mutex);
        if (ev.has_frame()) frames[ev.frame().sequence()] = ev.frame().positions();
        if (ev.has_state()) ++states;
        if (ev.has_deleted()) deleted = ev.deleted();
        cv.notify_all();
      }
      auto st = reader->Finish();
      std::lock_guard lock(mutex);
      status = st;
      ended = true;
      cv.notify_all();
    });
  }
  ~Watcher() {
    ctx.TryCancel();
    if (thread.joinable()) thread.join();
  }
  template <class Pred>
  bool wait(Pred pred) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, std::chrono::seconds(20), [&] { return pred(); });
  }
};
}  // namespace

TEST(ServiceStreams, TwoWatchersSeeTheSameFrames) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  Watcher a(t, s.name()), b(t, s.name());
  ASSERT_TRUE(a.wait([&] { return a.states > 0; }));
  ASSERT_TRUE(b.wait([&] { return b.states > 0; }));
  {
    pb::Session now;
    ASSERT_TRUE(t.get_session(s.name(), &now).ok());
    EXPECT_EQ(now.observers(), 2);
  }
  for (int i = 1; i <= 5; ++i) {
    pb::Frame f;
    auto st = t.update(s.name(), i, {translation(0.01 * i, 0, 0)}, &f);
    ASSERT_TRUE(st.ok()) << st.error_message();
    ASSERT_TRUE(a.wait([&] { return a.frames.count(i) > 0; })) << i;
    ASSERT_TRUE(b.wait([&] { return b.frames.count(i) > 0; })) << i;
    std::lock_guard la(a.mutex), lb(b.mutex);
    EXPECT_EQ(a.frames[i], f.positions());
    EXPECT_EQ(b.frames[i], f.positions());
  }
  // A client's Deform stream on the same session reaches the watchers too.
  {
    grpc::ClientContext ctx;
    auto stream = t.stub->Deform(&ctx);
    ASSERT_TRUE(stream->Write(deform_request(s.name(), 100, cactus_transform())));
    stream->WritesDone();
    pb::Frame f;
    ASSERT_TRUE(stream->Read(&f));
    ASSERT_TRUE(stream->Finish().ok());
    ASSERT_TRUE(a.wait([&] { return a.frames.count(100) > 0; }));
    ASSERT_TRUE(b.wait([&] { return b.frames.count(100) > 0; }));
    std::lock_guard la(a.mutex), lb(b.mutex);
    EXPECT_EQ(a.frames[100], f.positions());
    EXPECT_EQ(b.frames[100], f.positions());
  }
  // Deleting the session ends both streams with a `deleted` event.
  ASSERT_TRUE(t.delete_session(s.name()).ok());
  ASSERT_TRUE(a.wait([&] { return a.ended; }));
  ASSERT_TRUE(b.wait([&] { return b.ended; }));
  EXPECT_EQ(a.deleted, s.name());
  EXPECT_EQ(b.deleted, s.name());
  EXPECT_TRUE(a.status.ok()) << a.status.error_message();
}

// A watcher is told the state once on joining (then who is here); the watchers already there
// get the new observer count.
TEST(ServiceStreams, AJoiningWatcherGetsTheStateOnce) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  pb::WatchSessionRequest wreq;
  wreq.set_name(s.name());
  grpc::ClientContext first_ctx;
  auto first = t.stub->WatchSession(&first_ctx, wreq);
  pb::SessionEvent ev;
  ASSERT_TRUE(first->Read(&ev));
  ASSERT_TRUE(ev.has_state());
  EXPECT_EQ(ev.state().observers(), 1);
  ASSERT_TRUE(first->Read(&ev));
  EXPECT_TRUE(ev.has_presence());

  grpc::ClientContext second_ctx;
  auto second = t.stub->WatchSession(&second_ctx, wreq);
  pb::Frame f;
  ASSERT_TRUE(second->Read(&ev));
  ASSERT_TRUE(ev.has_state());
  EXPECT_EQ(ev.state().observers(), 2);
  ASSERT_TRUE(t.update(s.name(), 1, {translation(0, 0, 0.01)}, &f).ok());
  int states = 0;
  while (second->Read(&ev) && !ev.has_frame()) states += ev.has_state();
  EXPECT_TRUE(ev.has_frame());
  EXPECT_EQ(states, 0) << "the newcomer was sent its join state again";

  bool saw_two = false;
  while (first->Read(&ev) && !ev.has_frame())
    if (ev.has_state()) saw_two = saw_two || ev.state().observers() == 2;
  EXPECT_TRUE(saw_two) << "the first watcher did not see the second one arrive";
  first_ctx.TryCancel();
  second_ctx.TryCancel();
  first->Finish();
  second->Finish();
}

TEST(ServiceStreams, SlowWatcherSkipsToTheNewestFrame) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  // A watcher that does not read while 30 frames are produced.
  grpc::ClientContext wctx;
  pb::WatchSessionRequest wreq;
  wreq.set_name(s.name());
  auto reader = t.stub->WatchSession(&wctx, wreq);
  pb::SessionEvent ev;
  ASSERT_TRUE(reader->Read(&ev));
  ASSERT_TRUE(ev.has_state());
  for (int i = 1; i <= 30; ++i) {
    pb::Frame f;
    ASSERT_TRUE(t.update(s.name(), i, {translation(0, 0, 0.002 * i)}, &f).ok());
  }
  int frames = 0;
  std::int64_t last = 0;
  while (last != 30 && reader->Read(&ev)) {
    if (ev.has_frame()) {
      ++frames;
      EXPECT_GT(ev.frame().sequence(), last);
      last = ev.frame().sequence();
    }
  }
  EXPECT_EQ(last, 30);
  EXPECT_LE(frames, 30);
  wctx.TryCancel();
  reader->Finish();
}

TEST(ServiceStreams, ClientsThatGoAwayDoNotHurtTheServer) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  for (int round = 0; round < 5; ++round) {
    grpc::ClientContext ctx, wctx;
    auto stream = t.stub->Deform(&ctx);
    pb::WatchSessionRequest wreq;
    wreq.set_name(s.name());
    auto watch = t.stub->WatchSession(&wctx, wreq);
    for (int i = 1; i <= 20; ++i) {
      const std::string name = i == 1 ? s.name() : "";
      if (!stream->Write(deform_request(name, i, translation(0.001 * i, 0, 0)))) break;
    }
    if (round % 2) {
      pb::Frame f;
      stream->Read(&f);
    }
    ctx.TryCancel();  // mid-solve, with frames unread
    wctx.TryCancel();
    stream->Finish();
    watch->Finish();
  }
  pb::Frame f;
  auto st = t.update(s.name(), 1, {cactus_transform()}, &f);
  ASSERT_TRUE(st.ok()) << st.error_message();
  pb::Session now;
  ASSERT_TRUE(t.get_session(s.name(), &now).ok());
  // Cancelled watchers are gone (their OnDone may trail the client's Finish briefly).
  for (int i = 0; i < 100 && now.observers() != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ASSERT_TRUE(t.get_session(s.name(), &now).ok());
  }
  EXPECT_EQ(now.observers(), 0);
}

TEST(ServiceStreams, DeformStreamEndsWhenItsSessionIsDeleted) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  grpc::ClientContext ctx;
  auto stream = t.stub->Deform(&ctx);
  ASSERT_TRUE(stream->Write(deform_request(s.name(), 1, translation(0, 0.01, 0))));
  pb::Frame f;
  ASSERT_TRUE(stream->Read(&f));
  EXPECT_EQ(f.sequence(), 1);

  ASSERT_TRUE(t.delete_session(s.name()).ok());

  // may already fail if the server ended the stream
  stream->Write(deform_request("", 2, translation(0, 0.02, 0)));
  stream->WritesDone();
  while (stream->Read(&f)) EXPECT_NE(f.sequence(), 2) << "a deleted session answered";
  const grpc::Status st = stream->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << st.error_message();
}

// Drag frames (docs/api.md "Drag frames"): while `dragging`, frames are marked inexact and
// carry measures at most every 100 ms; they stay within 1e-6 of the bbox diagonal of the
// exact answer; the release frame is exact with measures, and GetMesh never serves a drag
// frame's positions.
TEST(ServiceStreams, DragFramesAreMarkedBoundedAndEndExact) {
  TestServer t;
  const pb::Session s = constrained_cactus(t);
  const double diag = std::sqrt(std::pow(s.bbox_max().x() - s.bbox_min().x(), 2) +
                                std::pow(s.bbox_max().y() - s.bbox_min().y(), 2) +
                                std::pow(s.bbox_max().z() - s.bbox_min().z(), 2));
  auto floats = [](const std::string& bytes) {
    std::vector<float> v(bytes.size() / sizeof(float));
    std::memcpy(v.data(), bytes.data(), bytes.size());
    return v;
  };
  pb::Frame drag, exact;
  // The server decides at solve time, which lies between a request's send and its answer, so
  // the throttle is checked against client times that bound it (sanitizer builds are slow):
  // two measured frames i < j have answer_j − send_i ≥ 100 ms; an unmeasured frame k after
  // the measured frame m has send_k − answer_m < 100 ms.
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::milliseconds(100);
  int with_measures = 0;
  const int kMoves = 6;
  Clock::time_point last_send, last_answer;  // of the last measured frame
  Clock::duration slowest{};
  for (int i = 1; i <= kMoves; ++i) {
    const auto move = translation(0, 0.01 * i, 0);
    const auto sent = Clock::now();
    ASSERT_TRUE(t.update(s.name(), i, {move}, &drag, false, /*dragging=*/true).ok());
    const auto answered = Clock::now();
    slowest = std::max(slowest, answered - sent);
    EXPECT_FALSE(drag.exact()) << "move " << i;
    if (drag.has_measures()) {
      if (with_measures > 0) {
        EXPECT_GE(answered - last_send, period) << "move " << i;
      }
      last_send = sent;
      last_answer = answered;
      ++with_measures;
    } else {
      ASSERT_GT(with_measures, 0) << "the first drag frame must be measured";
      EXPECT_LT(sent - last_answer, period) << "move " << i << " skipped its measures";
    }
  }
  EXPECT_GE(with_measures, 1);  // the first drag frame is measured (none for 100 ms before)
  // Moves well under the period must share measured frames (not so in slow sanitizer builds).
  if (slowest < period / 4) {
    EXPECT_LT(with_measures, kMoves) << "every drag frame was measured";
  }

  // The same pose, exact: the drag frame was within the tolerance of it.
  const auto last_move = translation(0, 0.01 * kMoves, 0);
  ASSERT_TRUE(t.update(s.name(), kMoves + 1, {last_move}, &exact).ok());
  EXPECT_TRUE(exact.exact());
  EXPECT_TRUE(exact.has_measures());
  const auto a = floats(drag.positions()), b = floats(exact.positions());
  ASSERT_EQ(a.size(), b.size());
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, std::abs(static_cast<double>(a[i]) - b[i]));
  // float32 frames round at ≈ 6e-8 relative to the coordinates; the solves differ ≤ 1e-6·d.
  EXPECT_LE(worst, 1e-6 * diag + 1e-6 * diag) << "diag " << diag;

  // GetMesh after a drag frame solves exactly (never serves the drag frame's positions).
  const auto after_drag = translation(0, 0.07, 0);
  ASSERT_TRUE(t.update(s.name(), kMoves + 2, {after_drag}, &drag, false, true).ok());
  ASSERT_FALSE(drag.exact());
  const std::string mesh_after_drag = t.deformed(s.name(), pb::MESH_FORMAT_OBJ);
  ASSERT_TRUE(t.update(s.name(), kMoves + 3, {after_drag}, &exact).ok());
  EXPECT_EQ(mesh_after_drag, t.deformed(s.name(), pb::MESH_FORMAT_OBJ));
}

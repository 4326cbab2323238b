// Observers (server/service/session/observers.h) on its own: who gets a broadcast, what a
// revocation and a close take out, and that a closed session takes no new watcher. The
// service-level behaviour (RotateTokens, DeleteSession over gRPC and the door) is in
// test_streams.cpp and tests/security.
#include "service/session/observers.h"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

namespace hdeform::service {
namespace {

struct Sink : EventSink {
  std::vector<std::shared_ptr<const pb::SessionEvent>> events;
  int revoked = 0, closed = 0;
  void push(std::shared_ptr<const pb::SessionEvent> e) override { events.push_back(std::move(e)); }
  void close() override { ++closed; }
  void revoke(const grpc::Status&) override { ++revoked; }
};

struct Stream : AuthorizedStream {
  int revoked = 0;
  void revoke(const grpc::Status&) override { ++revoked; }
};

TEST(Observers, BroadcastReachesEveryWatcherButTheOneExcepted) {
  Observers o;
  auto a = std::make_shared<Sink>(), b = std::make_shared<Sink>();
  ASSERT_TRUE(o.add_watcher(a));
  ASSERT_TRUE(o.add_watcher(b));
  EXPECT_EQ(o.watchers(), 2);
  o.broadcast(std::make_shared<pb::SessionEvent>(), b.get());
  EXPECT_EQ(a->events.size(), 1u);
  EXPECT_EQ(b->events.size(), 0u);
  EXPECT_TRUE(o.remove_watcher(a.get()));
  EXPECT_FALSE(o.remove_watcher(a.get()));
  o.broadcast(std::make_shared<pb::SessionEvent>());
  EXPECT_EQ(a->events.size(), 1u);
  EXPECT_EQ(b->events.size(), 1u);
}

TEST(Observers, TakeIfTakesOnlyTheLostStreamsOfBothKinds) {
  Observers o;
  auto keep = std::make_shared<Sink>(), lose = std::make_shared<Sink>();
  lose->needed = Access::kEdit;
  auto deform_keep = std::make_shared<Stream>(), deform_lose = std::make_shared<Stream>();
  deform_lose->needed = Access::kEdit;
  o.add_watcher(keep);
  o.add_watcher(lose);
  o.add_stream(deform_keep);
  o.add_stream(deform_lose);
  const auto taken =
      o.take_if([](const AuthorizedStream& s) { return s.needed == Access::kEdit; });
  ASSERT_EQ(taken.size(), 2u);
  EXPECT_EQ(o.watchers(), 1);
  // The kept ones are still there: a close takes them.
  const Observers::Open open = o.close();
  ASSERT_EQ(open.watchers.size(), 1u);
  EXPECT_EQ(open.watchers[0], keep);
  ASSERT_EQ(open.deform.size(), 1u);
  EXPECT_EQ(open.deform[0], deform_keep);
}

TEST(Observers, AClosedSessionTakesNoWatcherAndAGoneStreamIsDropped) {
  Observers o;
  {
    auto gone = std::make_shared<Stream>();
    o.add_stream(gone);
  }  // a Deform stream that ended unregisters by going away
  EXPECT_TRUE(o.take_if([](const AuthorizedStream&) { return true; }).empty());
  o.close();
  EXPECT_FALSE(o.add_watcher(std::make_shared<Sink>()));
  EXPECT_EQ(o.watchers(), 0);
}

TEST(Observers, EndAllRevokesEveryStreamAndTheSessionStaysUsable) {
  Observers o;
  auto w = std::make_shared<Sink>();
  auto d = std::make_shared<Stream>();
  o.add_watcher(w);
  o.add_stream(d);
  o.end_all(grpc::Status(grpc::StatusCode::UNAVAILABLE, "stopping"));
  EXPECT_EQ(w->revoked, 1);
  EXPECT_EQ(d->revoked, 1);
  EXPECT_EQ(o.watchers(), 0);
  EXPECT_TRUE(o.add_watcher(std::make_shared<Sink>()));
}

TEST(Observers, DeltaWatchersAreCappedAndOpenStreamsKeepItBusy) {
  Observers o;
  EXPECT_TRUE(o.acquire_delta_watcher(2));
  EXPECT_TRUE(o.acquire_delta_watcher(2));
  EXPECT_FALSE(o.acquire_delta_watcher(2));
  EXPECT_EQ(o.delta_watchers(), 2);
  o.release_delta_watcher();
  EXPECT_TRUE(o.acquire_delta_watcher(2));
  EXPECT_FALSE(o.busy());
  o.stream_opened();
  EXPECT_TRUE(o.busy());
  o.stream_closed();
  EXPECT_FALSE(o.busy());
}

}  // namespace
}  // namespace hdeform::service

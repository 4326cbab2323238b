// A client's pipelined (coalescing) UpdateHandles are concurrent calls: they may reach the
// server in either order. UpdateHandlesRequest.sequence orders one client's updates, so a late,
// older update never undoes a newer move (docs/api.md "Pipelined updates"). First the
// per-client table on its own, then over loopback.
#include "service/session/client_sequences.h"
#include "service_fixture.h"

#include <chrono>
#include <thread>

namespace hdeform::testing {
namespace {

using service::ClientSequences;

TEST(ClientSequences, RecordsNamedClientsOnlyAndTheLatestApplied) {
  ClientSequences seq;
  seq.applied("", {5, false});
  EXPECT_FALSE(seq.last("").has_value()) << "an anonymous client is never ordered";
  EXPECT_EQ(seq.size(), 0u);
  EXPECT_FALSE(seq.last("alice").has_value());
  seq.applied("alice", {7, true});
  ASSERT_TRUE(seq.last("alice").has_value());
  EXPECT_EQ(seq.last("alice")->sequence, 7);
  EXPECT_TRUE(seq.last("alice")->dragging);
  // A lower sequence replaces it (a restarted client counts anew).
  seq.applied("alice", {1, false});
  EXPECT_EQ(seq.last("alice")->sequence, 1);
  EXPECT_FALSE(seq.last("alice")->dragging);
  EXPECT_FALSE(seq.last("bob").has_value());
}

TEST(ClientSequences, ForgetsTheLeastRecentlyAppliedClientBeyondItsBound) {
  ClientSequences seq;
  const auto n = ClientSequences::kMaxClients;
  for (std::size_t i = 0; i < n; ++i) seq.applied("c" + std::to_string(i), {1, false});
  seq.applied("c0", {2, false});  // c0 is now the most recent, c1 the least
  seq.applied("new", {1, false});
  EXPECT_EQ(seq.size(), n);
  EXPECT_TRUE(seq.last("c0").has_value());
  EXPECT_FALSE(seq.last("c1").has_value());
  EXPECT_TRUE(seq.last("c2").has_value());
  EXPECT_TRUE(seq.last("new").has_value());
}

pb::UpdateHandlesRequest pipelined(const std::string& name, const std::string& client,
                                   std::int64_t sequence, double z, bool coalesce = true,
                                   bool dragging = false) {
  pb::UpdateHandlesRequest req;
  req.set_name(name);
  req.set_client_id(client);
  req.set_sequence(sequence);
  *req.add_transforms() = translation(0, 0, z);
  req.set_coalesce(coalesce);
  req.set_dragging(dragging);
  return req;
}

double handle_z(TestServer& t, const std::string& name) {
  pb::Session s;
  EXPECT_TRUE(t.get_session(name, &s).ok());
  EXPECT_EQ(s.transforms_size(), 1);
  return s.transforms_size() ? s.transforms(0).translation().z() : NAN;
}

pb::Frame update(TestServer& t, const pb::UpdateHandlesRequest& req) {
  grpc::ClientContext ctx;
  pb::Frame f;
  const auto st = t.stub->UpdateHandles(&ctx, req, &f);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return f;
}

TEST(PipelinedOrder, AnOvertakenUpdateOfTheSameClientMovesNothing) {
  TestServer t;
  const auto s = constrained_cactus(t);
  const auto& name = s.name();
  const pb::Frame f5 = update(t, pipelined(name, "alice", 5, 0.3));
  EXPECT_FALSE(f5.superseded());
  // Sequence 4 was sent before 5 but arrives after it: answered superseded, moves nothing.
  const pb::Frame f4 = update(t, pipelined(name, "alice", 4, 0.1));
  EXPECT_TRUE(f4.superseded());
  EXPECT_EQ(f4.sequence(), 4);
  EXPECT_EQ(f4.version(), f5.version()) << "nothing was committed";
  EXPECT_TRUE(f4.positions().empty());
  EXPECT_EQ(handle_z(t, name), 0.3);
  // The same sequence again is not newer either.
  EXPECT_TRUE(update(t, pipelined(name, "alice", 5, 0.2)).superseded());
  EXPECT_EQ(handle_z(t, name), 0.3);
  // Sequences are per client: bob's first update and anonymous ones apply.
  EXPECT_FALSE(update(t, pipelined(name, "bob", 1, 0.4)).superseded());
  EXPECT_EQ(handle_z(t, name), 0.4);
  EXPECT_FALSE(update(t, pipelined(name, "", 1, 0.45)).superseded());
  EXPECT_FALSE(update(t, pipelined(name, "", 1, 0.5)).superseded());
  EXPECT_EQ(handle_z(t, name), 0.5);
  // A reloaded page counts from 1 again: its first update (not coalescing) restarts the count.
  EXPECT_FALSE(update(t, pipelined(name, "alice", 1, 0.6, /*coalesce=*/false)).superseded());
  EXPECT_FALSE(update(t, pipelined(name, "alice", 2, 0.7)).superseded());
  EXPECT_EQ(handle_z(t, name), 0.7);
  EXPECT_TRUE(update(t, pipelined(name, "alice", 1, 0.1)).superseded());
  EXPECT_EQ(handle_z(t, name), 0.7);
  // Without a sequence (0), arrival order alone decides.
  EXPECT_FALSE(update(t, pipelined(name, "alice", 0, 0.8)).superseded());
  EXPECT_FALSE(update(t, pipelined(name, "alice", 0, 0.9)).superseded());
  EXPECT_EQ(handle_z(t, name), 0.9);
}

// The drag's last update (11, exact) and the one before it (10, a drag frame) both wait behind
// a β change, and 11 arrives first. 10, the newest arrival, supersedes 11 (which commits its
// move) and is itself stale: it must not undo 11's move, and it carries the frame 11 asked
// for (exact, at 11's pose), so the drag's last frame still comes.
TEST(PipelinedOrder, ADragsLastUpdateOvertakenWhileWaitingStillGetsItsExactFrame) {
  TestServer t;
  const pb::Session plane = t.library_session("plane");
  pb::Session st;
  ASSERT_TRUE(t.set_constraints(plane.name(), benchmark_constraints("plane"), &st).ok());
  const auto& name = plane.name();
  EXPECT_FALSE(update(t, pipelined(name, "alice", 9, 0.2, false, /*dragging=*/true)).superseded());

  grpc::CompletionQueue cq;
  grpc::ClientContext beta_ctx;
  pb::SetBetaRequest beta_req;
  beta_req.set_name(name);
  beta_req.mutable_beta()->set_value(0.37);
  pb::Session beta_out;
  grpc::Status beta_status;
  auto beta_call = t.stub->AsyncSetBeta(&beta_ctx, beta_req, &cq);
  beta_call->Finish(&beta_out, &beta_status, reinterpret_cast<void*>(100));
  // Nothing tells a client its call reached the strand; the first β > 0 on the 40K plane
  // takes seconds, so short pauses order the arrivals.
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const std::int64_t sequences[2] = {11, 10};
  const bool dragging[2] = {false, true};
  const double z[2] = {0.5, 0.4};
  grpc::ClientContext ctxs[2];
  pb::Frame frames[2];
  grpc::Status statuses[2];
  std::unique_ptr<grpc::ClientAsyncResponseReader<pb::Frame>> calls[2];
  for (int i = 0; i < 2; ++i) {
    calls[i] = t.stub->AsyncUpdateHandles(
        &ctxs[i], pipelined(name, "alice", sequences[i], z[i], true, dragging[i]), &cq);
    calls[i]->Finish(&frames[i], &statuses[i], reinterpret_cast<void*>(std::intptr_t{i}));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  void* tag;
  bool ok;
  for (int done = 0; done < 3 && cq.Next(&tag, &ok); ++done) {
  }
  ASSERT_TRUE(beta_status.ok()) << beta_status.error_message();
  ASSERT_TRUE(statuses[0].ok()) << statuses[0].error_message();
  ASSERT_TRUE(statuses[1].ok()) << statuses[1].error_message();
  EXPECT_TRUE(frames[0].superseded()) << "11 waited while 10 arrived";
  ASSERT_FALSE(frames[1].superseded()) << "the newest arrival is solved";
  EXPECT_EQ(frames[1].sequence(), 10);
  EXPECT_TRUE(frames[1].exact()) << "solved as the drag's last update asked";
  EXPECT_FALSE(frames[1].positions().empty());
  ASSERT_EQ(frames[1].transforms_size(), 1);
  EXPECT_EQ(frames[1].transforms(0).translation().z(), 0.5) << "at 11's pose";
  EXPECT_EQ(handle_z(t, name), 0.5) << "10 did not undo 11's move";
}

}  // namespace
}  // namespace hdeform::testing

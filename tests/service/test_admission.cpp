// Admission is bounded: a flood of calls on one session (--max-session-queue) or on the
// whole server (--max-queued-calls) is refused on arrival with RESOURCE_EXHAUSTED naming the
// flag, before any work; every admitted call is answered and the server goes on serving.
// Real server over loopback; each call factorizes a 40K-vertex system (tens of ms), so the
// flood arrives while the first admitted call still runs.
#include "service_fixture.h"

#include <latch>
#include <thread>

using namespace hdeform::testing;

namespace {

pb::Session grid_session(TestServer& t) {
  pb::Session s;
  EXPECT_TRUE(t.upload(grid_off(201), "grid.off", &s).ok());  // 40,401 vertices
  const auto st = t.set_constraints(s.name(), grid_strips(), &s);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return s;
}

// `calls` SetBeta calls with distinct β (each a new factorization), released together;
// session k % sessions.size() for call k. Returns each call's status.
std::vector<grpc::Status> flood(TestServer& t, const std::vector<pb::Session>& sessions,
                                int calls) {
  std::vector<grpc::Status> out(static_cast<std::size_t>(calls));
  std::latch go(calls);
  std::vector<std::thread> threads;
  for (int k = 0; k < calls; ++k)
    threads.emplace_back([&, k] {
      go.arrive_and_wait();
      pb::Session s;
      out[static_cast<std::size_t>(k)] =
          t.set_beta(sessions[static_cast<std::size_t>(k) % sessions.size()].name(),
                     0.01 * (k + 1), &s);
    });
  for (auto& th : threads) th.join();
  return out;
}

void expect_refused_naming(const std::vector<grpc::Status>& statuses, const char* flag) {
  int ok = 0, refused = 0;
  for (const auto& st : statuses) {
    if (st.ok()) {
      ++ok;
      continue;
    }
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
    EXPECT_NE(st.error_message().find(flag), std::string::npos) << st.error_message();
    ++refused;
  }
  EXPECT_GE(ok, 1);
  EXPECT_GE(refused, 1) << "no call of the flood was refused";
}

}  // namespace

TEST(Admission, AFloodOnOneSessionIsRefusedBeyondItsQueue) {
  hdeform::service::ServerOptions o;
  o.request.max_session_queue = 2;
  TestServer t(o);
  const pb::Session s = grid_session(t);
  expect_refused_naming(flood(t, {s}, 16), "--max-session-queue");
  // Still serving: the session reads and changes as before.
  pb::Session after;
  EXPECT_TRUE(t.set_beta(s.name(), 0.5, &after).ok());
  EXPECT_DOUBLE_EQ(after.beta().value(), 0.5);
}

TEST(Admission, AFloodAcrossSessionsIsRefusedBeyondTheServersQueue) {
  hdeform::service::ServerOptions o;
  o.workers = 1;
  o.request.max_queued_calls = 1;
  TestServer t(o);
  std::vector<pb::Session> sessions;
  for (int k = 0; k < 6; ++k) sessions.push_back(grid_session(t));
  expect_refused_naming(flood(t, sessions, 12), "--max-queued-calls");
  pb::Session after;
  EXPECT_TRUE(t.set_beta(sessions[0].name(), 0.5, &after).ok());
}

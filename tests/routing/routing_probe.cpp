// A tiny gRPC client of hdeform.v1 for the routing test (tests/routing/routing_test.sh).
//
//   routing_probe create  ADDR KEY MESH        → prints the session name
//   routing_probe get     ADDR NAME KEY|- N    → N GetSession calls; prints "ok=K CODE=n …"
//   routing_probe count   ADDR                 → number of sessions on that server
//   routing_probe has     ADDR NAME            → exit 0 iff the server holds the session
//   routing_probe export  ADDR NAME KEY FILE   → writes the session's Snapshot
//   routing_probe import  ADDR FILE ID         → ImportSession under ID; prints the name
//   routing_probe drag    ADDR ID MESH SECONDS → failover client (below); prints a report
//   routing_probe crash   ADDR ID MESH PID SECONDS → kill -9 mid-drag client (below)
//
// KEY is sent as the x-session-id metadata ("-": no header). Every call also presents
// `authorization: Bearer $HDEFORM_TOKEN` when that variable is set (the replicas' operator
// token), except `drag`, which uses the tokens its session was created with.
#include "hdeform/v1/deform.grpc.pb.h"

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <csignal>
#include <optional>
#include <vector>
#include <sys/types.h>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <thread>
#include <iostream>
#include <map>
#include <sstream>
#include <string>

namespace pb = hdeform::v1;

namespace {

std::unique_ptr<pb::Deformation::Stub> connect(const std::string& addr) {
  // A restarted server is found again within half a second (gRPC's default reconnect
  // backoff grows to minutes; the restart test times the way back).
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 500);
  auto channel = grpc::CreateCustomChannel(addr, grpc::InsecureChannelCredentials(), args);
  if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10))) {
    std::cerr << "routing_probe: cannot connect to " << addr << "\n";
    std::exit(2);
  }
  return pb::Deformation::NewStub(channel);
}

void prepare(grpc::ClientContext& ctx, const std::string& key, const std::string& token = "") {
  if (!key.empty() && key != "-") ctx.AddMetadata("x-session-id", key);
  const char* env = std::getenv("HDEFORM_TOKEN");
  const std::string t = !token.empty() ? token : (env ? env : "");
  if (!t.empty()) ctx.AddMetadata("authorization", "Bearer " + t);
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
}

int fail(const std::string& what, const grpc::Status& s) {
  std::cerr << "routing_probe: " << what << ": " << s.error_code() << ": " << s.error_message()
            << "\n";
  return 1;
}

double coord(const pb::Vec3& v, int k) { return k == 0 ? v.x() : k == 1 ? v.y() : v.z(); }

// The failover client (tests/routing/failover_test.sh): creates session ID on MESH through
// ADDR (nginx) with its x-session-id header, fixes the bottom tenth along the longest axis,
// takes the top tenth as the handle, then drags it with UpdateHandles for SECONDS (one move
// after another, each with a new translation) using only the session's own edit token. A
// call that fails is retried once after 100 ms (the documented client policy); a retry that
// fails too is an error. At the end it reads the session with the view token and checks the
// pose is the last acknowledged move. Prints key=value pairs; exit 0 iff all held.
using Clock = std::chrono::steady_clock;

// A session ID on MESH through ADDR with the bottom tenth (longest axis) fixed and the top
// tenth as its handle; nullopt after printing the error.
std::optional<pb::Session> dragged_session(pb::Deformation::Stub& stub, const std::string& id,
                                           const std::string& mesh) {
  pb::Session s;
  {
    grpc::ClientContext ctx;
    prepare(ctx, id);
    auto writer = stub.CreateSession(&ctx, &s);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_library_mesh(mesh);
    req.mutable_header()->set_session_id(id);
    writer->Write(req);
    writer->WritesDone();
    if (auto st = writer->Finish(); !st.ok()) return fail("CreateSession", st), std::nullopt;
  }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (coord(s.bbox_max(), k) - coord(s.bbox_min(), k) >
        coord(s.bbox_max(), axis) - coord(s.bbox_min(), axis))
      axis = k;
  const double lo = coord(s.bbox_min(), axis), hi = coord(s.bbox_max(), axis);
  pb::SetConstraintsRequest c;
  c.set_name(s.name());
  auto set_axis = [axis](pb::Vec3* v, double x) {
    if (axis == 0) v->set_x(x);
    if (axis == 1) v->set_y(x);
    if (axis == 2) v->set_z(x);
  };
  auto* f = c.mutable_constraints()->mutable_fixed()->add_selectors()->mutable_half_space();
  set_axis(f->mutable_normal(), -1);
  f->set_offset(-(lo + 0.1 * (hi - lo)));
  auto* h = c.mutable_constraints()->add_handles()->add_selectors()->mutable_half_space();
  set_axis(h->mutable_normal(), 1);
  h->set_offset(hi - 0.1 * (hi - lo));
  {
    grpc::ClientContext ctx;
    prepare(ctx, id, s.edit_token());
    pb::Session out;
    if (auto st = stub.SetConstraints(&ctx, c, &out); !st.ok())
      return fail("SetConstraints", st), std::nullopt;
  }
  return s;
}

// Move k of a drag: the handle translated by k mm along x (so a pose tells its move).
grpc::Status move(pb::Deformation::Stub& stub, const pb::Session& s, std::int64_t k,
                  pb::Frame* frame) {
  grpc::ClientContext ctx;
  prepare(ctx, s.name().substr(9), s.edit_token());
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
  pb::UpdateHandlesRequest u;
  u.set_name(s.name());
  u.set_sequence(k);
  u.add_transforms()->mutable_translation()->set_x(1e-3 * static_cast<double>(k));
  return stub.UpdateHandles(&ctx, u, frame);
}

grpc::Status get_session(pb::Deformation::Stub& stub, const pb::Session& s, pb::Session* out,
                         int deadline_ms = 60'000) {
  grpc::ClientContext ctx;
  prepare(ctx, s.name().substr(9), s.view_token());
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(deadline_ms));
  pb::GetSessionRequest g;
  g.set_name(s.name());
  return stub.GetSession(&ctx, g, out);
}

std::int64_t move_of(const pb::Session& s) {
  return s.transforms_size() == 1 ? std::llround(s.transforms(0).translation().x() / 1e-3) : -1;
}

int drag(pb::Deformation::Stub& stub, const std::string& id, const std::string& mesh,
         double seconds) {
  const auto session = dragged_session(stub, id, mesh);
  if (!session) return 1;
  const pb::Session& s = *session;
  auto move = [&](std::int64_t k, pb::Frame* frame) { return ::move(stub, s, k, frame); };
  const auto t0 = Clock::now();
  std::int64_t k = 0, acked = 0, acked_version = 0, failures = 0;
  double gap_ms = 0;
  auto last_ok = Clock::now();
  while (Clock::now() - t0 < std::chrono::duration<double>(seconds)) {
    ++k;
    pb::Frame frame;
    auto st = move(k, &frame);
    if (!st.ok()) {
      ++failures;
      std::cerr << "routing_probe drag: move " << k << " failed (" << st.error_code() << ": "
                << st.error_message() << "); retrying once\n";
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      st = move(k, &frame);
      if (!st.ok()) return fail("UpdateHandles retry of move " + std::to_string(k), st);
    }
    const auto now = Clock::now();
    gap_ms = std::max(gap_ms, std::chrono::duration<double, std::milli>(now - last_ok).count());
    last_ok = now;
    acked = k;
    acked_version = frame.version();
  }
  pb::Session after;
  if (auto st = get_session(stub, s, &after); !st.ok()) return fail("GetSession", st);
  const bool pose = move_of(after) == acked;
  std::cout << "session=" << after.name() << " moves=" << acked << " failures=" << failures
            << " gap_ms=" << static_cast<long>(gap_ms) << " version=" << after.version()
            << " acked_version=" << acked_version << " pose=" << (pose ? "same" : "DIFFERENT")
            << "\n";
  return pose && after.name() == "sessions/" + id && after.version() == acked_version ? 0 : 1;
}

// kill -9 mid-drag (tests/routing/restart_test.sh): drags session ID for SECONDS, then kills
// the server PID with SIGKILL itself (so the kill time is exact) and waits — while the script
// restarts the server on the same state — until GetSession answers again. Reports the move
// the restored pose shows against the moves acknowledged before the kill: how much of the
// drag was lost (the durable-state contract: at most the last 250 ms), and the time from the
// kill to the first answer. Then drags on for a few moves with the same tokens.
int crash(pb::Deformation::Stub& stub, const std::string& id, const std::string& mesh,
          pid_t pid, double seconds) {
  const auto session = dragged_session(stub, id, mesh);
  if (!session) return 1;
  const pb::Session& s = *session;
  std::vector<Clock::time_point> acked(1, Clock::now());  // acked[k]: when move k was answered
  const auto t0 = Clock::now();
  while (Clock::now() - t0 < std::chrono::duration<double>(seconds)) {
    pb::Frame frame;
    const auto k = static_cast<std::int64_t>(acked.size());
    if (auto st = move(stub, s, k, &frame); !st.ok()) return fail("move", st);
    acked.push_back(Clock::now());
  }
  const auto t_kill = Clock::now();
  ::kill(pid, SIGKILL);
  const std::int64_t last = static_cast<std::int64_t>(acked.size()) - 1;
  pb::Session back;
  grpc::Status st;
  for (int i = 0; i < 600; ++i) {
    st = get_session(stub, s, &back, 2000);
    if (st.ok()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (!st.ok()) return fail("GetSession after the restart", st);
  const double back_ms = std::chrono::duration<double, std::milli>(Clock::now() - t_kill).count();
  const std::int64_t restored = move_of(back);
  // The restored pose is an acknowledged move (or the one in flight); what is lost is the
  // span of moves acknowledged after it.
  double lost_ms = 0;
  if (restored >= 0 && restored < last)
    lost_ms = std::chrono::duration<double, std::milli>(acked[static_cast<std::size_t>(last)] -
                                                        acked[static_cast<std::size_t>(restored)])
                  .count();
  pb::Frame frame;
  const auto after = move(stub, s, last + 1, &frame);
  std::cout << "session=" << back.name() << " moves=" << last << " restored_move=" << restored
            << " lost_ms=" << static_cast<long>(lost_ms) << " back_after_ms="
            << static_cast<long>(back_ms) << " next_move=" << (after.ok() ? "ok" : "FAILED")
            << "\n";
  if (!after.ok()) return fail("a move after the restart", after);
  return back.name() == "sessions/" + id && restored >= 0 && restored <= last + 1 &&
                 lost_ms <= 250
             ? 0
             : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: routing_probe create|get|count|has|export|import|drag ADDR …\n";
    return 2;
  }
  const std::string cmd = argv[1];
  auto stub = connect(argv[2]);

  if (cmd == "create" && argc == 5) {
    grpc::ClientContext ctx;
    prepare(ctx, argv[3]);
    pb::Session session;
    auto writer = stub->CreateSession(&ctx, &session);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_library_mesh(argv[4]);
    req.mutable_header()->set_session_id(argv[3]);
    writer->Write(req);
    writer->WritesDone();
    grpc::Status s = writer->Finish();
    if (!s.ok()) return fail("CreateSession", s);
    std::cout << session.name() << "\n";
    return 0;
  }
  if (cmd == "get" && argc == 6) {
    std::map<std::string, int> codes;
    const int n = std::stoi(argv[5]);
    for (int i = 0; i < n; ++i) {
      grpc::ClientContext ctx;
      prepare(ctx, argv[4]);
      pb::GetSessionRequest req;
      req.set_name(argv[3]);
      pb::Session session;
      grpc::Status s = stub->GetSession(&ctx, req, &session);
      ++codes[s.ok() ? "ok" : "code" + std::to_string(s.error_code())];
    }
    std::string sep;
    for (const auto& [k, v] : codes) std::cout << sep << k << "=" << v, sep.assign(1, ' ');
    std::cout << "\n";
    return 0;
  }
  if (cmd == "count" && argc == 3) {
    grpc::ClientContext ctx;
    prepare(ctx, "-");
    pb::ListSessionsResponse resp;
    grpc::Status s = stub->ListSessions(&ctx, pb::ListSessionsRequest(), &resp);
    if (!s.ok()) return fail("ListSessions", s);
    std::cout << resp.sessions_size() << "\n";
    return 0;
  }
  if (cmd == "has" && argc == 4) {
    grpc::ClientContext ctx;
    prepare(ctx, "-");
    pb::GetSessionRequest req;
    req.set_name(argv[3]);
    pb::Session session;
    return stub->GetSession(&ctx, req, &session).ok() ? 0 : 1;
  }
  if (cmd == "export" && argc == 6) {
    grpc::ClientContext ctx;
    prepare(ctx, argv[4]);
    pb::ExportSessionRequest req;
    req.set_name(argv[3]);
    pb::Snapshot snap;
    grpc::Status s = stub->ExportSession(&ctx, req, &snap);
    if (!s.ok()) return fail("ExportSession", s);
    std::ofstream out(argv[5], std::ios::binary);
    snap.SerializeToOstream(&out);
    return out ? 0 : 1;
  }
  if (cmd == "import" && argc == 5) {
    pb::ImportSessionRequest req;
    std::ifstream in(argv[3], std::ios::binary);
    if (!req.mutable_snapshot()->ParseFromIstream(&in)) {
      std::cerr << "routing_probe: cannot read " << argv[3] << "\n";
      return 1;
    }
    req.set_session_id(argv[4]);
    grpc::ClientContext ctx;
    prepare(ctx, argv[4]);
    pb::Session session;
    grpc::Status s = stub->ImportSession(&ctx, req, &session);
    if (!s.ok()) return fail("ImportSession", s);
    std::cout << session.name() << "\n";
    return 0;
  }
  if (cmd == "drag" && argc == 6) return drag(*stub, argv[3], argv[4], std::stod(argv[5]));
  if (cmd == "crash" && argc == 7)
    return crash(*stub, argv[3], argv[4], static_cast<pid_t>(std::stol(argv[5])),
                 std::stod(argv[6]));
  std::cerr << "routing_probe: bad arguments\n";
  return 2;
}

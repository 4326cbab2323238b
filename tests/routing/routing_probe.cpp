// A tiny gRPC client of hdeform.v1 for the routing test (tests/routing/routing_test.sh).
//
//   routing_probe create  ADDR KEY MESH        → prints the session name
//   routing_probe get     ADDR NAME KEY|- N    → N GetSession calls; prints "ok=K CODE=n …"
//   routing_probe count   ADDR                 → number of sessions on that server
//   routing_probe has     ADDR NAME            → exit 0 iff the server holds the session
//   routing_probe export  ADDR NAME KEY FILE   → writes the session's Snapshot
//   routing_probe import  ADDR FILE ID         → ImportSession under ID; prints the name
//
// KEY is sent as the x-session-id metadata ("-": no header).
#include "hdeform/v1/deform.grpc.pb.h"

#include <grpcpp/grpcpp.h>

#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>

namespace pb = hdeform::v1;

namespace {

std::unique_ptr<pb::Deformation::Stub> connect(const std::string& addr) {
  auto channel = grpc::CreateChannel(addr, grpc::InsecureChannelCredentials());
  if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10))) {
    std::cerr << "routing_probe: cannot connect to " << addr << "\n";
    std::exit(2);
  }
  return pb::Deformation::NewStub(channel);
}

void prepare(grpc::ClientContext& ctx, const std::string& key) {
  if (!key.empty() && key != "-") ctx.AddMetadata("x-session-id", key);
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
}

int fail(const std::string& what, const grpc::Status& s) {
  std::cerr << "routing_probe: " << what << ": " << s.error_code() << ": " << s.error_message()
            << "\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: routing_probe create|get|count|has|export|import ADDR …\n";
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
  std::cerr << "routing_probe: bad arguments\n";
  return 2;
}

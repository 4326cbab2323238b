// Client-chosen session ids (CreateSessionHeader.session_id, ImportSessionRequest.session_id).
#include "service_fixture.h"

using namespace hdeform::testing;

TEST(ServiceSessionId, CreateUsesTheClientsId) {
  TestServer t;
  pb::Session s;
  auto st = t.create_library("cactus", &s, "my-Session_01");
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(s.name(), "sessions/my-Session_01");

  // Taken: ALREADY_EXISTS (library and upload alike), the first session is untouched.
  pb::Session dup;
  st = t.create_library("cactus", &dup, "my-Session_01");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ALREADY_EXISTS) << st.error_message();
  {
    grpc::ClientContext ctx;
    auto writer = t.stub->CreateSession(&ctx, &dup);
    pb::CreateSessionRequest req;
    req.mutable_header()->set_filename("cactus.off");
    req.mutable_header()->set_session_id("my-Session_01");
    writer->Write(req);
    pb::CreateSessionRequest chunk;
    chunk.set_chunk(slurp(data_path("botsch-sorkine/cactus.off")));
    writer->Write(chunk);
    writer->WritesDone();
    EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::ALREADY_EXISTS);
  }

  // Malformed: INVALID_ARGUMENT.
  for (const std::string& bad : std::vector<std::string>{"has space", "sessions/x", "dot.dot", "ümlaut", std::string(65, 'a')}) {
    st = t.create_library("cactus", &dup, bad);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_NE(st.error_message().find("session_id"), std::string::npos) << st.error_message();
  }
  // 64 characters is fine; empty: the server picks one.
  st = t.create_library("cactus", &dup, std::string(64, 'Z'));
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(dup.name(), "sessions/" + std::string(64, 'Z'));
  st = t.create_library("cactus", &dup, "");
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(dup.name().size(), std::string("sessions/").size() + 16);

  pb::ListSessionsResponse list;
  ASSERT_TRUE(t.list_sessions(&list).ok());
  EXPECT_EQ(list.sessions_size(), 3);

  // The id works as a name, with or without the prefix.
  pb::Session got;
  ASSERT_TRUE(t.get_session("my-Session_01", &got).ok());
  EXPECT_EQ(got.name(), s.name());
}

TEST(ServiceSessionId, ImportUsesTheClientsId) {
  TestServer t;
  pb::Session s;
  ASSERT_TRUE(t.create_library("cactus", &s, "original").ok());
  pb::Session c;
  ASSERT_TRUE(t.set_constraints(s.name(), cactus_constraints(), &c).ok());
  pb::Snapshot snap;
  ASSERT_TRUE(t.export_session(s.name(), &snap).ok());
  pb::Session imported;
  auto st = t.import_session(snap, &imported, "original");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ALREADY_EXISTS) << st.error_message();
  st = t.import_session(snap, &imported, "no/slash");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();

  st = t.import_session(snap, &imported, "copy-1");
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(imported.name(), "sessions/copy-1");
  EXPECT_TRUE(imported.constrained());

  // After the original is gone its id is free again (the failover re-import).
  ASSERT_TRUE(t.delete_session(s.name()).ok());
  st = t.import_session(snap, &imported, "original");
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(imported.name(), "sessions/original");

  // A failed import does not keep the id.
  pb::Snapshot broken = snap;
  broken.clear_transforms();
  broken.add_transforms();
  broken.add_transforms();  // 2 transforms for 1 handle
  st = t.import_session(broken, &imported, "broken");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  st = t.import_session(snap, &imported, "broken");
  EXPECT_TRUE(st.ok()) << st.error_message();
}

// Issue 9, access: capability tokens per session over loopback against a real Server. Every
// call here goes through `bare_stub` (no operator token) with the tokens a test chooses.
#include "service_fixture.h"

#include "service/access/access.h"

#include <set>

using namespace hdeform::testing;
using grpc::StatusCode;

namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A context presenting `tokens` (each as its own `authorization: Bearer …` entry).
std::unique_ptr<grpc::ClientContext> as(const std::vector<std::string>& tokens) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  for (const auto& t : tokens) ctx->AddMetadata("authorization", "Bearer " + t);
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  return ctx;
}

// A library session made by a client with no operator token; its answer carries the tokens.
pb::Session create(TestServer& t, const std::string& mesh = "cactus", const std::string& id = "") {
  grpc::ClientContext ctx;
  pb::Session out;
  auto writer = t.bare_stub->CreateSession(&ctx, &out);
  pb::CreateSessionRequest req;
  req.mutable_header()->set_library_mesh(mesh);
  req.mutable_header()->set_session_id(id);
  writer->Write(req);
  writer->WritesDone();
  const auto st = writer->Finish();
  EXPECT_TRUE(st.ok()) << st.error_message();
  return out;
}

struct Calls {
  TestServer& t;
  std::string name;

  grpc::Status get(const std::vector<std::string>& tokens) {
    pb::GetSessionRequest r;
    r.set_name(name);
    pb::Session out;
    return t.bare_stub->GetSession(as(tokens).get(), r, &out);
  }
  grpc::Status set_constraints(const std::vector<std::string>& tokens) {
    pb::SetConstraintsRequest r;
    r.set_name(name);
    *r.mutable_constraints() = cactus_constraints();
    pb::Session out;
    return t.bare_stub->SetConstraints(as(tokens).get(), r, &out);
  }
  grpc::Status set_beta(const std::vector<std::string>& tokens) {
    pb::SetBetaRequest r;
    r.set_name(name);
    r.mutable_beta()->set_value(0.1);
    pb::Session out;
    return t.bare_stub->SetBeta(as(tokens).get(), r, &out);
  }
  grpc::Status update(const std::vector<std::string>& tokens) {
    pb::UpdateHandlesRequest r;
    r.set_name(name);
    *r.add_transforms() = cactus_transform();
    pb::Frame out;
    return t.bare_stub->UpdateHandles(as(tokens).get(), r, &out);
  }
  grpc::Status mesh(const std::vector<std::string>& tokens) {
    pb::GetMeshRequest r;
    r.set_name(name);
    r.set_format(pb::MESH_FORMAT_OFF);
    auto ctx = as(tokens);
    auto reader = t.bare_stub->GetMesh(ctx.get(), r);
    pb::MeshChunk c;
    while (reader->Read(&c)) {
    }
    return reader->Finish();
  }
  // The first event of a WatchSession (the state), then cancel.
  grpc::Status watch(const std::vector<std::string>& tokens) {
    pb::WatchSessionRequest r;
    r.set_name(name);
    auto ctx = as(tokens);
    auto reader = t.bare_stub->WatchSession(ctx.get(), r);
    pb::SessionEvent e;
    if (reader->Read(&e)) {
      EXPECT_TRUE(e.has_state());
      ctx->TryCancel();
      reader->Finish();
      return grpc::Status::OK;
    }
    return reader->Finish();
  }
  grpc::Status deform(const std::vector<std::string>& tokens) {
    auto ctx = as(tokens);
    auto stream = t.bare_stub->Deform(ctx.get());
    stream->Write(deform_request(name, 1, cactus_transform()));
    stream->WritesDone();
    pb::Frame f;
    while (stream->Read(&f)) {
    }
    return stream->Finish();
  }
  grpc::Status sweep(const std::vector<std::string>& tokens) {
    pb::SweepRequest r;
    r.set_name(name);
    r.add_betas(0);
    pb::SweepResponse out;
    return t.bare_stub->Sweep(as(tokens).get(), r, &out);
  }
  grpc::Status export_(const std::vector<std::string>& tokens, pb::Snapshot* out = nullptr) {
    pb::ExportSessionRequest r;
    r.set_name(name);
    pb::Snapshot s;
    return t.bare_stub->ExportSession(as(tokens).get(), r, out ? out : &s);
  }
  grpc::Status rotate(const std::vector<std::string>& tokens, pb::Session* out = nullptr) {
    pb::RotateTokensRequest r;
    r.set_name(name);
    pb::Session s;
    return t.bare_stub->RotateTokens(as(tokens).get(), r, out ? out : &s);
  }
  grpc::Status remove(const std::vector<std::string>& tokens) {
    pb::DeleteSessionRequest r;
    r.set_name(name);
    pb::DeleteSessionResponse out;
    return t.bare_stub->DeleteSession(as(tokens).get(), r, &out);
  }
};

std::set<std::string> listed(TestServer& t, const std::vector<std::string>& tokens) {
  pb::ListSessionsResponse out;
  const auto st = t.bare_stub->ListSessions(as(tokens).get(), {}, &out);
  EXPECT_TRUE(st.ok()) << st.error_message();
  std::set<std::string> names;
  for (const auto& s : out.sessions()) names.insert(s.name());
  return names;
}

}  // namespace

TEST(SecurityAccess, CreateReturnsTwoFreshStrongTokensThatNothingElseReturns) {
  TestServer t;
  const pb::Session a = create(t), b = create(t);
  for (const auto* s : {&a, &b}) {
    EXPECT_EQ(s->edit_token().size(), 64u);  // 256 bits as hex
    EXPECT_EQ(s->view_token().size(), 64u);
    EXPECT_NE(s->edit_token(), s->view_token());
  }
  EXPECT_NE(a.edit_token(), b.edit_token());
  EXPECT_NE(a.view_token(), b.view_token());
  // Reading the session never hands a token out again.
  pb::GetSessionRequest r;
  r.set_name(a.name());
  pb::Session got;
  ASSERT_TRUE(t.bare_stub->GetSession(as({a.edit_token()}).get(), r, &got).ok());
  EXPECT_TRUE(got.edit_token().empty());
  EXPECT_TRUE(got.view_token().empty());
  for (const auto& s : listed(t, {a.edit_token()})) EXPECT_FALSE(s.empty());
  pb::ListSessionsResponse all;
  ASSERT_TRUE(t.stub->ListSessions(as({}).get(), {}, &all).ok());
  for (const auto& s : all.sessions()) {
    EXPECT_TRUE(s.edit_token().empty());
    EXPECT_TRUE(s.view_token().empty());
  }
}

TEST(SecurityAccess, EveryCallOnASessionNeedsItsToken) {
  TestServer t;
  const pb::Session s = create(t);
  const pb::Session other = create(t);
  Calls c{t, s.name()};
  const std::vector<std::pair<const char*, std::function<grpc::Status(std::vector<std::string>)>>>
      calls = {
          {"GetSession", [&](auto tok) { return c.get(tok); }},
          {"GetMesh", [&](auto tok) { return c.mesh(tok); }},
          {"WatchSession", [&](auto tok) { return c.watch(tok); }},
          {"SetConstraints", [&](auto tok) { return c.set_constraints(tok); }},
          {"SetBeta", [&](auto tok) { return c.set_beta(tok); }},
          {"UpdateHandles", [&](auto tok) { return c.update(tok); }},
          {"Deform", [&](auto tok) { return c.deform(tok); }},
          {"Sweep", [&](auto tok) { return c.sweep(tok); }},
          {"ExportSession", [&](auto tok) { return c.export_(tok); }},
          {"RotateTokens", [&](auto tok) { return c.rotate(tok); }},
          {"DeleteSession", [&](auto tok) { return c.remove(tok); }},
      };
  for (const auto& [op, call] : calls) {
    SCOPED_TRACE(op);
    auto st = call({});
    EXPECT_EQ(st.error_code(), StatusCode::UNAUTHENTICATED) << st.error_message();
    EXPECT_TRUE(contains(st.error_message(), std::string(op) + " on " + s.name()))
        << st.error_message();
    EXPECT_TRUE(contains(st.error_message(), "authorization: Bearer")) << st.error_message();
    // Another session's tokens, and made-up ones, open nothing.
    for (const auto& wrong : {other.edit_token(), other.view_token(), std::string(64, 'a'),
                              std::string("x")}) {
      st = call({wrong});
      EXPECT_EQ(st.error_code(), StatusCode::PERMISSION_DENIED) << st.error_message();
      EXPECT_TRUE(contains(st.error_message(), "opens no session of that name")) << st.error_message();
    }
  }
  // Nothing above changed the session.
  pb::Session now;
  pb::GetSessionRequest r;
  r.set_name(s.name());
  ASSERT_TRUE(t.bare_stub->GetSession(as({s.view_token()}).get(), r, &now).ok());
  EXPECT_EQ(now.version(), s.version());
  EXPECT_FALSE(now.constrained());
}

TEST(SecurityAccess, TheViewTokenOnlyReads) {
  TestServer t;
  const pb::Session s = create(t);
  Calls c{t, s.name()};
  ASSERT_TRUE(c.set_constraints({s.edit_token()}).ok());
  const std::vector<std::string> view = {s.view_token()};
  EXPECT_TRUE(c.get(view).ok());
  EXPECT_TRUE(c.mesh(view).ok());
  EXPECT_TRUE(c.watch(view).ok());
  for (auto st : {c.set_constraints(view), c.set_beta(view), c.update(view), c.deform(view),
                  c.sweep(view), c.export_(view), c.rotate(view), c.remove(view)}) {
    EXPECT_EQ(st.error_code(), StatusCode::PERMISSION_DENIED) << st.error_message();
    EXPECT_TRUE(contains(st.error_message(), "needs the session's edit token")) << st.error_message();
    EXPECT_TRUE(contains(st.error_message(), "view token (read-only)")) << st.error_message();
  }
  // The edit token does everything.
  const std::vector<std::string> edit = {s.edit_token()};
  for (auto st : {c.get(edit), c.mesh(edit), c.watch(edit), c.set_beta(edit), c.update(edit),
                  c.deform(edit), c.sweep(edit), c.export_(edit)})
    EXPECT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(c.remove(edit).ok());
  // A deleted session's tokens open nothing; only the operator learns it is gone.
  EXPECT_EQ(c.get(edit).error_code(), StatusCode::PERMISSION_DENIED);
  pb::Session none;
  EXPECT_EQ(t.get_session(s.name(), &none).error_code(), StatusCode::NOT_FOUND);
}

// Issue 35.12: without a token that opens it, an id that does not exist answers exactly as
// one that does (status and text, the name aside), so ids cannot be probed; the operator
// alone gets NOT_FOUND.
TEST(SecurityAccess, AnUnknownIdAnswersLikeAnExistingOneWithoutItsToken) {
  TestServer t;
  const pb::Session s = create(t);
  const pb::Session other = create(t);
  const std::string unknown = "sessions/" + std::string(16, '7');
  Calls known{t, s.name()}, missing{t, unknown};
  const std::vector<std::function<grpc::Status(Calls&, std::vector<std::string>)>> calls = {
      [](Calls& c, auto tok) { return c.get(tok); },
      [](Calls& c, auto tok) { return c.mesh(tok); },
      [](Calls& c, auto tok) { return c.watch(tok); },
      [](Calls& c, auto tok) { return c.set_constraints(tok); },
      [](Calls& c, auto tok) { return c.set_beta(tok); },
      [](Calls& c, auto tok) { return c.update(tok); },
      [](Calls& c, auto tok) { return c.deform(tok); },
      [](Calls& c, auto tok) { return c.sweep(tok); },
      [](Calls& c, auto tok) { return c.export_(tok); },
      [](Calls& c, auto tok) { return c.rotate(tok); },
      [](Calls& c, auto tok) { return c.remove(tok); },
  };
  const auto without_name = [](std::string text, const std::string& name) {
    for (auto at = text.find(name); at != std::string::npos; at = text.find(name))
      text.replace(at, name.size(), "NAME");
    return text;
  };
  for (std::size_t i = 0; i < calls.size(); ++i) {
    SCOPED_TRACE(i);
    for (const auto& tokens : std::vector<std::vector<std::string>>{
             {}, {other.edit_token()}, {other.view_token()}, {"x"}, {std::string(64, 'a')}}) {
      const auto a = calls[i](known, tokens), b = calls[i](missing, tokens);
      EXPECT_NE(a.error_code(), StatusCode::OK);
      EXPECT_EQ(a.error_code(), b.error_code()) << a.error_message() << " | " << b.error_message();
      EXPECT_EQ(without_name(a.error_message(), s.name()),
                without_name(b.error_message(), unknown));
    }
  }
  pb::Session none;
  EXPECT_EQ(t.get_session(unknown, &none).error_code(), StatusCode::NOT_FOUND);
}

TEST(SecurityAccess, TokensAreReadFromBearerHeadersInAnyCase) {
  TestServer t;
  const pb::Session s = create(t);
  pb::GetSessionRequest r;
  r.set_name(s.name());
  pb::Session out;
  for (const std::string& value :
       {"Bearer " + s.view_token(), "bearer " + s.view_token(), s.view_token(),
        "Bearer junk, Bearer " + s.view_token()}) {
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", value);
    const auto st = t.bare_stub->GetSession(&ctx, r, &out);
    EXPECT_TRUE(st.ok()) << value << ": " << st.error_message();
  }
}

TEST(SecurityAccess, ListShowsOnlyTheSessionsWhoseTokensArePresented) {
  TestServer t;
  const pb::Session a = create(t), b = create(t), c = create(t);
  EXPECT_TRUE(listed(t, {}).empty());
  EXPECT_TRUE(listed(t, {"made-up"}).empty());
  EXPECT_EQ(listed(t, {a.view_token()}), std::set<std::string>{a.name()});
  EXPECT_EQ(listed(t, {a.edit_token(), b.view_token()}),
            (std::set<std::string>{a.name(), b.name()}));
  // The operator sees all.
  EXPECT_EQ(listed(t, {kTestAdminToken}), (std::set<std::string>{a.name(), b.name(), c.name()}));
}

TEST(SecurityAccess, RotatingRevokesEveryEarlierToken) {
  TestServer t;
  const pb::Session s = create(t);
  Calls c{t, s.name()};
  pb::Session rotated;
  ASSERT_TRUE(c.rotate({s.edit_token()}, &rotated).ok());
  EXPECT_EQ(rotated.edit_token().size(), 64u);
  EXPECT_NE(rotated.edit_token(), s.edit_token());
  EXPECT_NE(rotated.view_token(), s.view_token());
  EXPECT_EQ(c.get({s.view_token()}).error_code(), StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(c.set_beta({s.edit_token()}).error_code(), StatusCode::PERMISSION_DENIED);
  EXPECT_TRUE(c.get({rotated.view_token()}).ok());
  EXPECT_TRUE(c.set_constraints({rotated.edit_token()}).ok());
}

TEST(SecurityAccess, ImportByMeshHashAloneNeedsAnEditTokenOnThatMesh) {
  TestServer t;
  // Someone uploads a private mesh.
  pb::Session owner;
  ASSERT_TRUE(t.upload(grid_off(12), "private.off", &owner).ok());
  // (The fixture's upload used the operator stub; its tokens are in the answer.)
  ASSERT_FALSE(owner.edit_token().empty());
  pb::ImportSessionRequest req;
  req.mutable_snapshot()->set_mesh_hash(owner.mesh_hash());
  req.mutable_snapshot()->set_filename("private.off");
  pb::Session out;
  for (const std::vector<std::string>& tokens :
       {std::vector<std::string>{}, {owner.view_token()}, {create(t).edit_token()}}) {
    const auto st = t.bare_stub->ImportSession(as(tokens).get(), req, &out);
    EXPECT_EQ(st.error_code(), StatusCode::NOT_FOUND) << st.error_message();
    EXPECT_TRUE(contains(st.error_message(), "needs the edit token of a live session on that mesh"))
        << st.error_message();
  }
  const auto st = t.bare_stub->ImportSession(as({owner.edit_token()}).get(), req, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(out.mesh_hash(), owner.mesh_hash());
  EXPECT_EQ(out.edit_token().size(), 64u);
  EXPECT_NE(out.edit_token(), owner.edit_token());
  // The bytes themselves, or a library mesh, need no token.
  pb::ImportSessionRequest lib;
  lib.mutable_snapshot()->set_library_mesh("bar");
  EXPECT_TRUE(t.bare_stub->ImportSession(as({}).get(), lib, &out).ok());
}

TEST(SecurityAccess, AChosenIdCannotBeSquattedOrOpenedByItsName) {
  TestServer t;
  const pb::Session mine = create(t, "cactus", "team-demo");
  ASSERT_EQ(mine.name(), "sessions/team-demo");
  // Someone else asking for the same id gets no session and no tokens.
  grpc::ClientContext ctx;
  pb::Session theirs;
  auto writer = t.bare_stub->CreateSession(&ctx, &theirs);
  pb::CreateSessionRequest req;
  req.mutable_header()->set_library_mesh("bar");
  req.mutable_header()->set_session_id("team-demo");
  writer->Write(req);
  writer->WritesDone();
  EXPECT_EQ(writer->Finish().error_code(), StatusCode::ALREADY_EXISTS);
  EXPECT_TRUE(theirs.edit_token().empty());
  // Knowing the name opens nothing.
  Calls c{t, "sessions/team-demo"};
  EXPECT_EQ(c.remove({}).error_code(), StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(c.remove({"guess"}).error_code(), StatusCode::PERMISSION_DENIED);
  EXPECT_TRUE(c.get({mine.view_token()}).ok());
}

// Issue 35.9: an operator token opens every session, so a guessable one is refused when the
// server is built (hdeform-server exits 2 with the same text: security.operator_token).
TEST(SecurityAccess, AGuessableOperatorTokenIsRefused) {
  using hdeform::service::operator_token_problem;
  for (const std::string& weak : {std::string(20, ' '), std::string(16, 'a'), std::string(40, 'a'),
                                 std::string("abababababababababababababababababab"),
                                 std::string("0123456789abcdef0123456789abcde"),  // 31
                                 std::string("0123456789abcdef 0123456789abcdef"),
                                 std::string("0123456789abcdef,0123456789abcdef"),
                                 std::string("0123456789abcdef\x01" "0123456789abcdef")}) {
    EXPECT_FALSE(operator_token_problem(weak).empty()) << "'" << weak << "'";
    hdeform::service::ServerOptions o;
    o.admin_token = weak;
    o.listen_address.clear();
    EXPECT_THROW(hdeform::service::Server{o}, std::invalid_argument) << weak;
  }
  for (int i = 0; i < 100; ++i) {
    const auto token = hdeform::service::new_token();
    EXPECT_EQ(token.size(), 64u);
    EXPECT_EQ(operator_token_problem(token), "") << token;
  }
  EXPECT_EQ(operator_token_problem("0123456789abcdef0123456789abcdef"), "");
  EXPECT_EQ(operator_token_problem(kTestAdminToken), "");
}

// Issue 35.7: two users who upload the same bytes share one prepared mesh, but each session
// shows only the name its own creator gave — in Session.mesh_name and in ExportSession.
TEST(SecurityAccess, AnUploadShowsOnlyItsOwnCreatorsFileName) {
  TestServer t;
  const std::string bytes = slurp(data_path("botsch-sorkine/bar.off"));
  pb::Session alice, bob;
  ASSERT_TRUE(t.upload(bytes, "alice-secret-merger.off", &alice).ok());
  ASSERT_TRUE(t.upload(bytes, "bob.OFF", &bob).ok());
  ASSERT_EQ(alice.mesh_hash(), bob.mesh_hash());  // one shared mesh
  EXPECT_EQ(alice.mesh_name(), "alice-secret-merger.off");
  EXPECT_EQ(bob.mesh_name(), "bob.OFF");
  Calls c{t, bob.name()};
  pb::Snapshot snap;
  ASSERT_TRUE(c.export_({bob.edit_token()}, &snap).ok());
  EXPECT_EQ(snap.filename(), "bob.OFF");
  // An import by hash alone, with no file name: a neutral name in the mesh's format.
  pb::Snapshot by_hash;
  by_hash.set_mesh_hash(bob.mesh_hash());
  pb::ImportSessionRequest r;
  *r.mutable_snapshot() = by_hash;
  pb::Session carol;
  ASSERT_TRUE(t.bare_stub->ImportSession(as({bob.edit_token()}).get(), r, &carol).ok());
  EXPECT_EQ(carol.mesh_name(), "upload.off");
  // A name whose extension is not the bytes' format gets the format's extension.
  r.mutable_snapshot()->set_filename("dave.obj");
  pb::Session dave;
  ASSERT_TRUE(t.bare_stub->ImportSession(as({bob.edit_token()}).get(), r, &dave).ok());
  EXPECT_EQ(dave.mesh_name(), "dave.obj.off");
  for (const auto& s : {bob, carol, dave}) {
    pb::Session got;
    pb::GetSessionRequest g;
    g.set_name(s.name());
    ASSERT_TRUE(t.bare_stub->GetSession(as({s.edit_token()}).get(), g, &got).ok());
    EXPECT_EQ(got.mesh_name().find("alice"), std::string::npos) << got.mesh_name();
    Calls e{t, s.name()};
    ASSERT_TRUE(e.export_({s.edit_token()}, &snap).ok());
    EXPECT_EQ(snap.filename().find("alice"), std::string::npos) << snap.filename();
  }
}

// Revocation is immediate: RotateTokens ends every open stream opened with a token that no
// longer grants what it needs (UNAUTHENTICATED, naming the rotation), and DeleteSession ends
// open Deform streams (NOT_FOUND); streams opened with the operator token go on. Real server
// over loopback.
#include "service_fixture.h"

#include <chrono>
#include <thread>

using namespace hdeform::testing;
using grpc::StatusCode;
using Clock = std::chrono::steady_clock;

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr auto kPrompt = std::chrono::milliseconds(1000);  // the sanitizers slow every call
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr auto kPrompt = std::chrono::milliseconds(1000);
#else
constexpr auto kPrompt = std::chrono::milliseconds(100);
#endif
#else
constexpr auto kPrompt = std::chrono::milliseconds(100);
#endif

std::unique_ptr<grpc::ClientContext> as(const std::string& token) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->AddMetadata("authorization", "Bearer " + token);
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  return ctx;
}

struct Opened {
  TestServer t;
  pb::Session s;
  Opened() {
    s = t.library_session("cactus");
    pb::Session out;
    grpc::ClientContext ctx;
    pb::SetConstraintsRequest r;
    r.set_name(s.name());
    *r.mutable_constraints() = cactus_constraints();
    EXPECT_TRUE(t.stub->SetConstraints(&ctx, r, &out).ok());
  }
  pb::Session rotate() {
    pb::RotateTokensRequest r;
    r.set_name(s.name());
    pb::Session out;
    EXPECT_TRUE(t.bare_stub->RotateTokens(as(s.edit_token()).get(), r, &out).ok());
    return out;
  }
};

// Reads until the stream ends; the time from `since` to its end.
template <class Reader, class Message>
Clock::duration until_end(Reader& reader, Message& m, Clock::time_point since) {
  while (reader.Read(&m)) {
  }
  return Clock::now() - since;
}

TEST(SecurityRevocation, RotateEndsAWatchOpenedWithTheOldViewToken) {
  Opened o;
  pb::WatchSessionRequest r;
  r.set_name(o.s.name());
  auto ctx = as(o.s.view_token());
  auto reader = o.t.bare_stub->WatchSession(ctx.get(), r);
  pb::SessionEvent e;
  ASSERT_TRUE(reader->Read(&e));  // the state: the stream is open
  // An operator's watch on the same session is not affected.
  grpc::ClientContext op_ctx;
  auto op_reader = o.t.stub->WatchSession(&op_ctx, r);
  ASSERT_TRUE(op_reader->Read(&e));

  o.rotate();
  const auto t0 = Clock::now();
  const auto took = until_end(*reader, e, t0);
  const grpc::Status st = reader->Finish();
  EXPECT_EQ(st.error_code(), StatusCode::UNAUTHENTICATED) << st.error_message();
  EXPECT_NE(st.error_message().find("rotated"), std::string::npos) << st.error_message();
  EXPECT_LE(took, kPrompt);

  // The operator's stream still gets what changes (a β change's state).
  pb::Session out;
  ASSERT_TRUE(o.t.set_beta(o.s.name(), 0.2, &out).ok());
  bool saw_beta = false;
  while (!saw_beta && op_reader->Read(&e))
    saw_beta = e.has_state() && e.state().beta().value() == 0.2;
  EXPECT_TRUE(saw_beta);
  op_ctx.TryCancel();
  op_reader->Finish();
}

TEST(SecurityRevocation, RotateEndsADeformStreamOpenedWithTheOldEditToken) {
  Opened o;
  auto ctx = as(o.s.edit_token());
  auto stream = o.t.bare_stub->Deform(ctx.get());
  ASSERT_TRUE(stream->Write(deform_request(o.s.name(), 1, translation(0, 0, 0.1))));
  pb::Frame f;
  ASSERT_TRUE(stream->Read(&f));  // one frame: the stream is open and bound

  const pb::Session rotated = o.rotate();
  const auto t0 = Clock::now();
  const auto took = until_end(*stream, f, t0);
  const grpc::Status st = stream->Finish();
  EXPECT_EQ(st.error_code(), StatusCode::UNAUTHENTICATED) << st.error_message();
  EXPECT_NE(st.error_message().find("rotated"), std::string::npos) << st.error_message();
  EXPECT_LE(took, kPrompt);

  // The new edit token opens a new stream.
  auto ctx2 = as(rotated.edit_token());
  auto again = o.t.bare_stub->Deform(ctx2.get());
  ASSERT_TRUE(again->Write(deform_request(o.s.name(), 2, translation(0, 0, 0.2))));
  EXPECT_TRUE(again->Read(&f));
  again->WritesDone();
  EXPECT_TRUE(again->Finish().ok());
}

TEST(SecurityRevocation, DeleteEndsAnOpenDeformStream) {
  Opened o;
  auto ctx = as(o.s.edit_token());
  auto stream = o.t.bare_stub->Deform(ctx.get());
  ASSERT_TRUE(stream->Write(deform_request(o.s.name(), 1, translation(0, 0, 0.1))));
  pb::Frame f;
  ASSERT_TRUE(stream->Read(&f));
  ASSERT_TRUE(o.t.delete_session(o.s.name()).ok());
  const auto t0 = Clock::now();
  const auto took = until_end(*stream, f, t0);
  const grpc::Status st = stream->Finish();
  EXPECT_EQ(st.error_code(), StatusCode::NOT_FOUND) << st.error_message();
  EXPECT_NE(st.error_message().find("deleted"), std::string::npos) << st.error_message();
  EXPECT_LE(took, kPrompt);
  // Another session keeps being served throughout.
  pb::Session other = o.t.library_session("bar");
  pb::Session got;
  EXPECT_TRUE(o.t.get_session(other.name(), &got).ok());
}

}  // namespace

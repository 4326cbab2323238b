// MESHOPT_DELTA (deform.proto FrameEncoding): the per-stream encoder (service/frame_delta.h)
// against the client's stream decoder (client-cli/frame_decode.h): every frame decodes to
// exactly its quantization on the key frame's grid, within QUANTIZED's stated bounds; key
// frames come when the proto says; then over loopback: a WatchSession drag in MESHOPT_DELTA,
// and the calls that cannot carry it refuse it by name.
#include "frame_decode.h"
#include "frame_test_util.h"
#include "service/frames/frame_delta.h"
#include "service/frames/frame_encoding.h"
#include "service_fixture.h"

#include <chrono>
#include <omp.h>
#include <thread>

namespace hdeform::testing {
namespace {

namespace svc = ::hdeform::service;

#if defined(__SANITIZE_THREAD__)
constexpr bool kThreadSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
constexpr bool kThreadSanitizer = true;
#else
constexpr bool kThreadSanitizer = false;
#endif
#else
constexpr bool kThreadSanitizer = false;
#endif

// `f` with every position moved by `shift` · (a smooth field of the position): a drag step.
pb::Frame moved(const pb::Frame& f, float shift) {
  auto p = floats_of(f.positions());
  for (std::size_t i = 0; i < p.size(); i += 3) {
    p[i] += shift * std::sin(0.01f * p[i + 2]);
    p[i + 1] += 0.5f * shift;
  }
  pb::Frame out = f;
  out.set_positions(float_bytes(p));
  return out;
}

// What a QUANTIZED frame on `grid` decodes to: the exact target of a MESHOPT_DELTA frame.
cli::DecodedFrame quantized_on(const pb::Frame& f32, const pb::Box& grid, std::size_t n) {
  std::string bytes(svc::kQuantizedVertexBytes * n, '\0');
  const auto p = floats_of(f32.positions()), nr = floats_of(f32.normals());
  svc::quantize_onto(p, nr, grid, reinterpret_cast<unsigned char*>(bytes.data()));
  pb::Frame q;
  q.set_encoding(pb::FRAME_ENCODING_QUANTIZED);
  q.set_vertices(bytes);
  *q.mutable_position_box() = grid;
  return decode_frame(q, n, 0);
}

TEST(FrameDelta, EveryFrameDecodesToItsQuantizationOnTheKeyGrid) {
  const std::size_t n = 20000, t = 100;
  pb::Frame f = random_frame(n, t, 11);
  svc::FrameDeltaEncoder enc;
  cli::FrameStreamDecoder dec;
  std::size_t key_bytes = 0, delta_bytes = 0;
  for (int k = 0; k < 8; ++k) {
    if (k > 0) f = moved(f, 0.05f);
    pb::Frame out;
    enc.encode(f, &out);
    EXPECT_EQ(out.encoding(), pb::FRAME_ENCODING_MESHOPT_DELTA);
    EXPECT_EQ(out.delta(), k > 0) << "frame " << k;
    EXPECT_TRUE(out.positions().empty() && out.normals().empty());
    (k == 0 ? key_bytes : delta_bytes) = out.vertices().size();
    const auto d = dec.decode(out, n, t);
    const auto want = quantized_on(f, out.position_box(), n);
    ASSERT_EQ(d.positions, want.positions) << "frame " << k << ": deltas must not drift";
    ASSERT_EQ(d.normals, want.normals) << "frame " << k;
    expect_within_stated_bounds(f, d, out.position_box(), out.energies_max());
  }
  EXPECT_EQ(enc.key_frames(), 1u);
  EXPECT_EQ(enc.delta_frames(), 7u);
  // The same grid, small smooth moves: the deltas pack far tighter than the key frame.
  EXPECT_LT(delta_bytes * 2, key_bytes) << "key " << key_bytes << " B, delta " << delta_bytes << " B";
  std::printf("[ measured ] %zu vertices: key frame %zu B, delta frame %zu B\n", n, key_bytes,
              delta_bytes);
}

// Frames from 16,384 vertices are quantized, boxed and differenced on the OpenMP team: one
// and two threads give the same bytes, and a single vertex off the grid anywhere (here in the
// second thread's half) still makes a key frame.
TEST(FrameDelta, LargeFramesEncodeTheSameOnOneAndTwoThreads) {
  if (kThreadSanitizer)
    GTEST_SKIP() << "the OpenMP runtime is not instrumented for TSan (scripts/tsan.sh: one thread)";
  const std::size_t n = 50000;
  const pb::Frame f0 = random_frame(n, 0, 21), f1 = moved(f0, 0.05f);
  auto stray = floats_of(f1.positions());
  stray[3 * (n - 10) + 1] += 1e4f;
  pb::Frame f2 = f1;
  f2.set_positions(float_bytes(stray));
  auto run = [&](int threads) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
    svc::FrameDeltaEncoder enc;
    std::vector<pb::Frame> out(4);
    enc.encode(f0, &out[0]);
    enc.encode(f1, &out[1]);
    enc.encode(f2, &out[2]);
    pb::FrameFormat meshopt;
    meshopt.set_encoding(pb::FRAME_ENCODING_MESHOPT);
    svc::encode_frame_to(f1, meshopt, false, &out[3]);
    omp_set_num_threads(before);
    return out;
  };
  const auto one = run(1), two = run(2);
  for (std::size_t k = 0; k < one.size(); ++k) {
    EXPECT_EQ(one[k].vertices(), two[k].vertices()) << "frame " << k;
    EXPECT_EQ(one[k].position_box().SerializeAsString(), two[k].position_box().SerializeAsString())
        << "frame " << k;
  }
  EXPECT_FALSE(two[0].delta());
  EXPECT_TRUE(two[1].delta());
  EXPECT_FALSE(two[2].delta()) << "a vertex off the grid must force a key frame";
}

TEST(FrameDelta, KeyFramesComeWhenTheGridOrTheStreamChanges) {
  const std::size_t n = 500;
  pb::Frame f = random_frame(n, 0, 5);
  svc::FrameDeltaEncoder enc;
  cli::FrameStreamDecoder dec;
  auto send = [&](const pb::Frame& frame, std::size_t count) {
    pb::Frame out;
    enc.encode(frame, &out);
    const auto d = dec.decode(out, count, 0);
    if (!out.vertices().empty()) {
      const auto want = quantized_on(frame, out.position_box(), count);
      EXPECT_EQ(d.positions, want.positions);
    }
    return out;
  };
  EXPECT_FALSE(send(f, n).delta());
  EXPECT_TRUE(send(moved(f, 0.01f), n).delta());
  // Far outside the grid (the margin is 1/8 of the largest side): a new key frame.
  const auto far = moved(f, 5e4f);
  EXPECT_FALSE(send(far, n).delta());
  EXPECT_TRUE(send(moved(far, 0.01f), n).delta());
  // Normals gone: a key frame (normal bytes 0), and again when they return.
  pb::Frame bare = far;
  bare.clear_normals();
  EXPECT_FALSE(send(bare, n).delta());
  EXPECT_FALSE(send(far, n).delta());
  // Another vertex count: a key frame.
  const pb::Frame small = random_frame(n / 2, 0, 6);
  EXPECT_FALSE(send(small, n / 2).delta());
  // A superseded frame (no buffers) changes nothing: the next frame is still a delta.
  pb::Frame superseded;
  superseded.set_superseded(true);
  EXPECT_TRUE(send(superseded, n / 2).vertices().empty());
  EXPECT_TRUE(send(moved(small, 0.01f), n / 2).delta());
  // reset(): the stream sent another encoding in between.
  enc.reset();
  EXPECT_FALSE(send(moved(small, 0.02f), n / 2).delta());
  // A NaN position leaves every grid: a key frame, not a silent clamp.
  auto p = floats_of(small.positions());
  p[4] = std::nanf("");
  pb::Frame nan_frame = small;
  nan_frame.set_positions(float_bytes(p));
  pb::Frame out;
  enc.encode(nan_frame, &out);
  EXPECT_FALSE(out.delta());
}

TEST(FrameDelta, TheStreamDecoderRefusesDeltasItCannotPlace) {
  const std::size_t n = 300;
  const pb::Frame f = random_frame(n, 0, 9);
  svc::FrameDeltaEncoder enc;
  pb::Frame key, delta, delta2;
  enc.encode(f, &key);
  enc.encode(moved(f, 0.01f), &delta);
  enc.encode(moved(f, 0.02f), &delta2);
  auto message = [](auto&& call) {
    try {
      call();
    } catch (const cli::FrameDecodeError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  {  // A delta with no key frame before it.
    cli::FrameStreamDecoder dec;
    EXPECT_NE(message([&] { dec.decode(delta, n, 0); }).find("no key frame"), std::string::npos);
  }
  {  // The stateless decoder says what it needs.
    EXPECT_NE(message([&] { decode_frame(delta, n, 0); }).find("FrameStreamDecoder"),
              std::string::npos);
  }
  {  // A delta after a key frame of another vertex count, then a corrupt one: later deltas
     // fail until a key frame heals the stream.
    cli::FrameStreamDecoder dec;
    svc::FrameDeltaEncoder other;
    pb::Frame small_key;
    other.encode(random_frame(n / 2, 0, 1), &small_key);
    dec.decode(small_key, n / 2, 0);
    EXPECT_NE(message([&] { dec.decode(delta, n, 0); }).find("another vertex count"),
              std::string::npos);
    EXPECT_NE(message([&] { dec.decode(delta2, n, 0); }).find("no key frame"), std::string::npos);
    dec.decode(key, n, 0);
    pb::Frame corrupt = delta;
    corrupt.mutable_vertices()->resize(corrupt.vertices().size() / 2);
    EXPECT_NE(message([&] { dec.decode(corrupt, n, 0); }).find("not a meshopt vertex buffer"),
              std::string::npos);
    EXPECT_NE(message([&] { dec.decode(delta2, n, 0); }).find("no key frame"), std::string::npos);
    dec.decode(key, n, 0);
    EXPECT_NO_THROW(dec.decode(delta, n, 0));
  }
}

// The cactus transform scaled from identity: `s` = 0 is the rest pose, 1 the benchmark's.
pb::HandleTransform partial_transform(double s) {
  const pb::HandleTransform full = cactus_transform();
  pb::HandleTransform t;
  for (int i = 0; i < 16; ++i) {
    const double id = (i % 5 == 0) ? 1.0 : 0.0;
    t.add_matrix(id + s * (full.matrix(i) - id));
  }
  return t;
}

pb::UpdateHandlesRequest drag_step(const std::string& name, std::int64_t seq, bool dragging) {
  pb::UpdateHandlesRequest req;
  req.set_name(name);
  req.set_sequence(seq);
  *req.add_transforms() = partial_transform(0.1 * static_cast<double>(seq));
  req.set_dragging(dragging);
  return req;  // FLOAT32 answers: the exact reference for what the watcher decodes
}

TEST(FrameDeltaService, AWatcherDecodesADragInMeshoptDeltaToTheServersFrames) {
  TestServer t;
  const auto s = constrained_cactus(t);
  const std::size_t n = s.vertex_count(), tris = s.triangle_count();
  grpc::ClientContext wctx;
  pb::WatchSessionRequest wreq;
  wreq.set_name(s.name());
  wreq.mutable_format()->set_encoding(pb::FRAME_ENCODING_MESHOPT_DELTA);
  wreq.mutable_format()->set_exact_as_float32(true);
  auto watch = t.stub->WatchSession(&wctx, wreq);
  pb::SessionEvent ev;
  ASSERT_TRUE(watch->Read(&ev) && ev.has_state());

  // Two drags: 1–5 dragging then 6 exact; 7–9 dragging then 10 exact. Each update waits
  // for its frame on the watch stream: a watcher that is behind gets the newest frame only
  // (latest wins), so back-to-back updates would make the counts below depend on the load.
  cli::FrameStreamDecoder dec;
  int keys = 0, deltas = 0, exact = 0;
  for (std::int64_t seq = 1; seq <= 10; ++seq) {
    grpc::ClientContext ctx;
    pb::Frame ref;
    const bool dragging = seq != 6 && seq != 10;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, drag_step(s.name(), seq, dragging), &ref).ok());
    std::int64_t last = 0;
    while (last != seq && watch->Read(&ev)) {
      if (!ev.has_frame()) continue;
      const pb::Frame& f = ev.frame();
      last = f.sequence();
      ASSERT_EQ(last, seq) << "one update, one frame";
      const auto d = dec.decode(f, n, tris);
      if (f.encoding() == pb::FRAME_ENCODING_FLOAT32) {
        ++exact;
        EXPECT_TRUE(f.exact());
        EXPECT_FALSE(dragging);
        EXPECT_EQ(f.positions(), ref.positions()) << "the frame ending a drag is the server's";
        continue;
      }
      ASSERT_EQ(f.encoding(), pb::FRAME_ENCODING_MESHOPT_DELTA);
      (f.delta() ? deltas : keys) += 1;
      expect_within_stated_bounds(ref, d, f.position_box(), 0);
    }
    ASSERT_EQ(last, seq);
  }
  EXPECT_EQ(exact, 2);
  EXPECT_EQ(keys, 2) << "each drag starts with a key frame (after the exact float32 one)";
  EXPECT_EQ(deltas, 6) << "the rest of each drag is deltas";
  wctx.TryCancel();
  watch->Finish();
}

TEST(FrameDeltaService, CallsThatMayDropFramesRefuseMeshoptDeltaByName) {
  TestServer t;
  const auto s = constrained_cactus(t);
  pb::Frame f;
  {
    grpc::ClientContext ctx;
    auto req = drag_step(s.name(), 1, true);
    req.mutable_format()->set_encoding(pb::FRAME_ENCODING_MESHOPT_DELTA);
    const auto st = t.stub->UpdateHandles(&ctx, req, &f);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("UpdateHandles: frame encoding MESHOPT_DELTA needs a stream"),
              std::string::npos)
        << st.error_message();
  }
  {
    grpc::ClientContext ctx;
    auto stream = t.stub->Deform(&ctx);
    auto req = deform_request(s.name(), 2, cactus_transform());
    req.mutable_format()->set_encoding(pb::FRAME_ENCODING_MESHOPT_DELTA);
    stream->Write(req);
    stream->WritesDone();
    while (stream->Read(&f)) {
    }
    const auto st = stream->Finish();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("Deform: frame encoding MESHOPT_DELTA"), std::string::npos)
        << st.error_message();
  }
  grpc::ClientContext ctx;  // the session still serves
  EXPECT_TRUE(t.stub->UpdateHandles(&ctx, drag_step(s.name(), 3, false), &f).ok());
}

// Watchers encode on the worker pool (not on the session's strand): one that goes away while
// its frame is being encoded must neither crash nor leak (ASan / TSan runs), and the others
// keep getting frames.
TEST(FrameDeltaService, WatchersThatLeaveMidEncodeHurtNoOne) {
  TestServer t;
  const auto s = constrained_cactus(t);
  grpc::ClientContext keep_ctx;
  pb::WatchSessionRequest keep;
  keep.set_name(s.name());
  keep.mutable_format()->set_encoding(pb::FRAME_ENCODING_MESHOPT_DELTA);
  auto kept = t.stub->WatchSession(&keep_ctx, keep);
  pb::SessionEvent ev;
  ASSERT_TRUE(kept->Read(&ev) && ev.has_state());
  for (int round = 0; round < 6; ++round) {
    std::vector<std::unique_ptr<grpc::ClientContext>> ctxs;
    std::vector<std::unique_ptr<grpc::ClientReader<pb::SessionEvent>>> readers;
    for (int k = 0; k < 4; ++k) {
      pb::WatchSessionRequest req;
      req.set_name(s.name());
      req.mutable_format()->set_encoding(k % 2 ? pb::FRAME_ENCODING_MESHOPT_DELTA
                                               : pb::FRAME_ENCODING_QUANTIZED);
      ctxs.push_back(std::make_unique<grpc::ClientContext>());
      readers.push_back(t.stub->WatchSession(ctxs.back().get(), req));
      ASSERT_TRUE(readers.back()->Read(&ev) && ev.has_state());
    }
    grpc::ClientContext ctx;
    pb::Frame f;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, drag_step(s.name(), round + 1, true), &f).ok());
    for (auto& c : ctxs) c->TryCancel();  // while their frames may still be encoding
    for (auto& r : readers) {
      while (r->Read(&ev)) {
      }
      r->Finish();
    }
    // The watcher that stayed gets this round's frame and decodes it.
    std::int64_t seen = 0;
    while (seen != round + 1 && kept->Read(&ev))
      if (ev.has_frame()) seen = ev.frame().sequence();
    ASSERT_EQ(seen, round + 1);
  }
  keep_ctx.TryCancel();
  kept->Finish();
}

// Each MESHOPT_DELTA watcher encodes every frame for itself: --max-delta-watchers caps them
// per session (RESOURCE_EXHAUSTED naming the flag); other watchers are not counted, and a
// watcher that leaves frees its place.
TEST(FrameDeltaService, DeltaWatchersAreCappedPerSession) {
  service::ServerOptions options;
  options.request.max_delta_watchers = 2;
  TestServer t(options);
  const auto s = constrained_cactus(t);
  auto open = [&](pb::FrameEncoding enc, grpc::ClientContext* ctx) {
    pb::WatchSessionRequest req;
    req.set_name(s.name());
    req.mutable_format()->set_encoding(enc);
    return t.stub->WatchSession(ctx, req);
  };
  pb::SessionEvent ev;
  grpc::ClientContext c1, c2, c3, c4;
  auto w1 = open(pb::FRAME_ENCODING_MESHOPT_DELTA, &c1);
  auto w2 = open(pb::FRAME_ENCODING_MESHOPT_DELTA, &c2);
  ASSERT_TRUE(w1->Read(&ev) && w2->Read(&ev));
  auto w3 = open(pb::FRAME_ENCODING_MESHOPT_DELTA, &c3);
  EXPECT_FALSE(w3->Read(&ev));
  const auto st = w3->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(st.error_message().find("2 MESHOPT_DELTA watchers, the limit (--max-delta-watchers)"),
            std::string::npos)
      << st.error_message();
  auto w4 = open(pb::FRAME_ENCODING_MESHOPT, &c4);  // not a delta watcher: not counted
  EXPECT_TRUE(w4->Read(&ev) && ev.has_state());
  c1.TryCancel();
  w1->Finish();
  bool reopened = false;  // the place frees once the server has seen the first one go
  for (int i = 0; i < 100 && !reopened; ++i) {
    grpc::ClientContext c5;
    auto w5 = open(pb::FRAME_ENCODING_MESHOPT_DELTA, &c5);
    reopened = w5->Read(&ev) && ev.has_state();
    c5.TryCancel();
    w5->Finish();
    if (!reopened) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_TRUE(reopened);
  c2.TryCancel();
  c4.TryCancel();
  w2->Finish();
  w4->Finish();
}

}  // namespace
}  // namespace hdeform::testing

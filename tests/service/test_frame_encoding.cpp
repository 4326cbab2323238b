// Frame encodings (deform.proto FrameEncoding): the server's encoder against the client's
// decoder (client-cli/frame_decode.h) and against the error bounds the proto states; then
// over loopback: UpdateHandles, Deform and WatchSession in every encoding, exact frames as
// float32 on request, omitted buffers, and coalescing pipelined updates.
#include "engine/simd/cpu_features.h"
#include "frame_decode.h"
#include "frame_test_util.h"
#include "service/frames/encoded_frames.h"
#include "service/frames/frame_encoding.h"
#include "service_fixture.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/reflection.h>
#include <google/protobuf/util/message_differencer.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <thread>

namespace hdeform::testing {
namespace {

namespace svc = ::hdeform::service;
using cli::decode_frame;

TEST(FrameEncoding, QuantizedAndMeshoptDecodeWithinTheStatedBounds) {
  const std::size_t n = 20000, t = 39000;
  const pb::Frame f32 = random_frame(n, t, 7);
  auto shared = std::make_shared<const pb::Frame>(f32);
  for (auto enc : {pb::FRAME_ENCODING_QUANTIZED, pb::FRAME_ENCODING_MESHOPT}) {
    pb::FrameFormat fmt;
    fmt.set_encoding(enc);
    const auto out = svc::encode_frame(shared, fmt);
    ASSERT_NE(out.get(), shared.get());
    EXPECT_EQ(out->encoding(), enc);
    EXPECT_TRUE(out->positions().empty());
    EXPECT_TRUE(out->normals().empty());
    if (enc == pb::FRAME_ENCODING_QUANTIZED) {
      EXPECT_EQ(out->vertices().size(), 8 * n);
    }
    EXPECT_EQ(out->energies().size(), 2 * t);
    const auto q = decode_frame(*out, n, t);
    expect_within_stated_bounds(f32, q, out->position_box(), out->energies_max());
  }
}

TEST(FrameEncoding, MeshoptIsTheQuantizedBufferLosslessly) {
  const pb::Frame f32 = random_frame(5000, 0, 3);
  pb::FrameFormat quantized, meshopt;
  quantized.set_encoding(pb::FRAME_ENCODING_QUANTIZED);
  meshopt.set_encoding(pb::FRAME_ENCODING_MESHOPT);
  pb::Frame q, m;
  ASSERT_TRUE(svc::encode_frame_to(f32, quantized, false, &q));
  ASSERT_TRUE(svc::encode_frame_to(f32, meshopt, false, &m));
  const auto dq = decode_frame(q, 5000, 0), dm = decode_frame(m, 5000, 0);
  EXPECT_EQ(dq.positions, dm.positions);
  EXPECT_EQ(dq.normals, dm.normals);
}

TEST(FrameEncoding, OctahedralNormalsAreWithinOnePointTwoDegreesEverywhere) {
  // A dense sweep over the sphere, poles, axes and the octahedron's folds included.
  double worst = 0;
  const int steps = 400;
  for (int a = 0; a <= steps; ++a)
    for (int b = 0; b < 2 * steps; ++b) {
      const double th = M_PI * a / steps, ph = M_PI * b / steps;
      const float n[3] = {float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)),
                          float(std::cos(th))};
      std::int8_t q[2];
      svc::octahedral_encode(n, q);
      float d[3];
      cli::octahedral_decode(q[0], q[1], d);
      worst = std::max(worst, angle_deg(n, d));
    }
  std::printf("[ measured ] octahedral int8: worst %.3f°\n", worst);
  EXPECT_LE(worst, 1.2);
  EXPECT_GT(worst, 0.05);  // it is a lossy code: a zero here would mean the test is vacuous
}

TEST(FrameEncoding, FlatAxesEmptyFramesAndZeroEnergiesDecode) {
  std::vector<float> p = {1, 2, 3, 4, 2, 3, 1, 2, 3}, nr = {0, 0, 1, 0, 0, -1, 1, 0, 0};
  pb::Frame f;
  f.set_positions(float_bytes(p));
  f.set_normals(float_bytes(nr));
  f.set_energies(float_bytes({0.f}));
  pb::FrameFormat fmt;
  fmt.set_encoding(pb::FRAME_ENCODING_MESHOPT);
  pb::Frame out;
  ASSERT_TRUE(svc::encode_frame_to(f, fmt, false, &out));
  const auto d = decode_frame(out, 3, 1);
  for (std::size_t i = 0; i < p.size(); ++i) EXPECT_FLOAT_EQ(d.positions[i], p[i]);
  EXPECT_NEAR(d.normals[5], -1.f, 1e-6);
  EXPECT_EQ(d.energies, std::vector<float>{0.f});
  pb::Frame empty;
  ASSERT_TRUE(svc::encode_frame_to(pb::Frame{}, fmt, false, &empty));
  EXPECT_TRUE(decode_frame(empty, 0, 0).positions.empty());
}

// The AVX2 quantization (quantize_avx2.cpp) against the generic loops: the same bytes and the
// same inside/outside answer on ordinary frames, on exact ties, on each cause of "outside"
// alone, and on NaN, infinities, signed zeros, subnormals and the largest float.
TEST(FrameEncoding, TheAvx2QuantizationWritesTheGenericBytes) {
  if (!isa_supported(Isa::avx2)) GTEST_SKIP() << "this CPU has no AVX2";
  const Isa before = kernel_isa();
  auto quantize = [](Isa isa, const std::vector<float>& p, const std::vector<float>& nr,
                     const pb::Box& box, bool* inside) {
    EXPECT_TRUE(set_kernel_isa(isa));
    std::vector<unsigned char> out(8 * (p.size() / 3), 0xAB);
    *inside = svc::quantize_onto(p, nr, box, out.data());
    return out;
  };
  auto expect_same = [&](const std::vector<float>& p, const std::vector<float>& nr,
                         const pb::Box& box, bool inside_expected, const char* what) {
    bool in_generic = false, in_avx2 = false;
    const auto generic = quantize(Isa::generic, p, nr, box, &in_generic);
    const auto avx2 = quantize(Isa::avx2, p, nr, box, &in_avx2);
    EXPECT_TRUE(generic == avx2) << what;
    EXPECT_EQ(in_generic, inside_expected) << what;
    EXPECT_EQ(in_avx2, inside_expected) << what;
  };
  const std::size_t n = 1003;  // not a multiple of 8: the generic loop does the last 3
  const pb::Frame f = random_frame(n, 0, 11);
  std::vector<float> p = floats_of(f.positions()), nr = floats_of(f.normals());
  const pb::Box box = svc::bounding_box(p);
  expect_same(p, nr, box, true, "random frame");
  expect_same(p, {}, box, true, "no normals");
  {  // large enough for the generic loop to run on the OpenMP team (chunks of 8192 vertices)
    const pb::Frame big = random_frame(20011, 0, 12);
    std::vector<float> bp = floats_of(big.positions()), bn = floats_of(big.normals());
    const pb::Box bbox = svc::bounding_box(bp);
    expect_same(bp, bn, bbox, true, "20011 vertices");
    bp[3 * 19000 + 1] = static_cast<float>(bbox.max().y()) + 1;
    expect_same(bp, bn, bbox, false, "20011 vertices, one outside in the last chunk");
  }

  // Odd values, each inside the part the AVX2 loop does: NaN, infinities, signed zeros,
  // subnormals (a normal whose 1 / L1 norm is +inf), the largest float (a grid coordinate far
  // beyond 2^63, clamped to the edge).
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float odd[] = {0.0f, -0.0f, nan, inf, -inf, 1e-30f, -1e-30f, 1.0f, -1.0f, 0.5f,
                       std::numeric_limits<float>::denorm_min(), -1e-39f,
                       std::numeric_limits<float>::max(), -1e20f};
  std::vector<float> q = p, m = nr;
  for (std::size_t i = 0; i < 8 * 60; ++i)
    m[i] = odd[(i * 7 + i / 14) % std::size(odd)];  // every normal component meets every value
  for (std::size_t i = 0; i < 8 * 6; ++i) q[3 * i + i % 3] = odd[i % std::size(odd)];
  expect_same(p, m, box, true, "odd normals");
  expect_same(q, m, box, false, "odd positions");
  // Exact ties: on the box [0, 65535]³ the grid step is 1, so k + 0.5 is a tie in t.
  pb::Box unit;
  for (auto* c : {unit.mutable_min(), unit.mutable_max()}) {
    const float v = c == unit.mutable_min() ? 0.0f : 65535.0f;
    c->set_x(v);
    c->set_y(v);
    c->set_z(v);
  }
  std::vector<float> ties(3 * 64);
  for (std::size_t i = 0; i < ties.size(); ++i)
    ties[i] = i % 7 == 0 ? 65534.5f : i % 5 == 0 ? -0.5f : static_cast<float>(i % 61) + 0.5f;
  expect_same(ties, {}, unit, true, "ties to even");
  // Each cause of "outside" alone, in the AVX2 part, with a clean tail (the last 3 vertices
  // are the generic loop's, which would answer for the whole call).
  const float step_x = static_cast<float>((box.max().x() - box.min().x()) / 65535.0);
  auto one_off = [&](std::size_t at, float value, const pb::Box& grid, std::vector<float> v,
                     const char* what) {
    v[at] = value;
    expect_same(v, nr, grid, false, what);
  };
  one_off(3 * 13 + 1, static_cast<float>(box.max().y()) + 0.01f, box, p, "one vertex above");
  one_off(3 * 45, static_cast<float>(box.min().x()) - step_x, box, p, "one vertex below");
  one_off(3 * 33 + 1, nan, box, p, "one NaN");
  ties[3 * 9] = 65535.5f;  // the first tie that rounds above the grid
  expect_same(ties, {}, unit, false, "one tie above the grid");
  pb::Box flat = box;
  flat.mutable_max()->set_z(flat.min().z());
  std::vector<float> on_flat = p;
  for (std::size_t i = 0; i < n; ++i) on_flat[3 * i + 2] = flat.min().z();
  expect_same(on_flat, nr, flat, true, "flat axis, every vertex on it");
  one_off(3 * 21 + 2, static_cast<float>(flat.min().z()) + 1e-3f, flat, on_flat,
          "flat axis, one vertex off it");

  // The box: the same bits (zeros as +0), and a NaN after the first vertex ignored, also
  // when it follows a lane's extreme value or ends a lane.
  auto box_of = [](Isa isa, const std::vector<float>& v) {
    EXPECT_TRUE(set_kernel_isa(isa));
    return svc::bounding_box(v).SerializeAsString();
  };
  std::vector<float> zeros(3 * 40, 0.0f);
  for (std::size_t i = 0; i < zeros.size(); i += 2) zeros[i] = -0.0f;
  for (const auto* v : {&p, &ties, &on_flat, &zeros}) {
    EXPECT_EQ(box_of(Isa::generic, *v), box_of(Isa::avx2, *v));
  }
  // The AVX2 loop starts at vertex 1: vertices 1 + j + 8b share lane j.
  std::vector<float> with_nan = p;
  with_nan[3 * 1] = static_cast<float>(box.min().x()) - 1;  // lane 0: the minimum, then NaN
  with_nan[3 * 9] = nan;
  with_nan[3 * 2] = static_cast<float>(box.max().x()) + 1;  // lane 1: the maximum, then NaN
  with_nan[3 * 10] = nan;
  with_nan[3 * 992 + 2] = static_cast<float>(box.min().z()) - 1;  // lane 7 of the last two
  with_nan[3 * 1000 + 2] = nan;                                   // blocks: NaN ends it
  EXPECT_EQ(box_of(Isa::generic, with_nan), box_of(Isa::avx2, with_nan));
  for (Isa isa : {Isa::generic, Isa::avx2}) {
    ASSERT_TRUE(set_kernel_isa(isa));
    const pb::Box b = svc::bounding_box(with_nan);
    EXPECT_EQ(b.min().x(), with_nan[3 * 1]);
    EXPECT_EQ(b.max().x(), with_nan[3 * 2]);
    EXPECT_EQ(b.min().z(), with_nan[3 * 992 + 2]);
  }
  EXPECT_FALSE(std::signbit(svc::bounding_box(zeros).min().x()));

  // Energies: the scale and every uint16, with values that are not finite or below 0, and a
  // scale so small that e · (1 / max) overflows.
  auto energies_of = [](Isa isa, const std::vector<float>& e, float* top) {
    EXPECT_TRUE(set_kernel_isa(isa));
    return svc::quantize_energies(e, top);
  };
  std::vector<float> e(1003);
  for (std::size_t l = 0; l < e.size(); ++l) e[l] = static_cast<float>((l * 37) % 101) * 0.25f;
  std::vector<float> odd_e = e;
  for (std::size_t l = 0; l < 64; ++l) odd_e[l * 3] = odd[l % std::size(odd)];
  std::vector<float> tiny(40, 1e-45f);  // the smallest subnormal: 1 / max is +inf
  tiny[3] = 0.0f;
  for (const auto* v : {&e, &odd_e, &tiny}) {
    float top_generic = -1, top_avx2 = -2;
    const std::string generic = energies_of(Isa::generic, *v, &top_generic);
    EXPECT_TRUE(generic == energies_of(Isa::avx2, *v, &top_avx2));  // (no dump of 2 KB)
    EXPECT_EQ(top_generic, top_avx2);
  }
  set_kernel_isa(before);
}

// Sets every field of `m` that is not skipped to a non-default value (recursively).
void fill_every_field(google::protobuf::Message* m, const std::set<std::string>& skip) {
  const auto* d = m->GetDescriptor();
  const auto* r = m->GetReflection();
  using FD = google::protobuf::FieldDescriptor;
  for (int i = 0; i < d->field_count(); ++i) {
    const FD* f = d->field(i);
    if (skip.count(f->name())) continue;
    if (f->is_repeated()) {
      if (f->cpp_type() == FD::CPPTYPE_MESSAGE) fill_every_field(r->AddMessage(m, f), {});
      else if (f->cpp_type() == FD::CPPTYPE_DOUBLE) r->AddDouble(m, f, 0.5 + i);
      continue;
    }
    switch (f->cpp_type()) {
      case FD::CPPTYPE_INT32: r->SetInt32(m, f, 3 + i); break;
      case FD::CPPTYPE_INT64: r->SetInt64(m, f, 1000 + i); break;
      case FD::CPPTYPE_DOUBLE: r->SetDouble(m, f, 0.25 + i); break;
      case FD::CPPTYPE_FLOAT: r->SetFloat(m, f, 0.75f + i); break;
      case FD::CPPTYPE_BOOL: r->SetBool(m, f, true); break;
      case FD::CPPTYPE_STRING: r->SetString(m, f, "x" + std::to_string(i)); break;
      case FD::CPPTYPE_ENUM: r->SetEnumValue(m, f, 1); break;
      case FD::CPPTYPE_MESSAGE: fill_every_field(r->MutableMessage(m, f), {}); break;
      default: ADD_FAILURE() << "field type of " << f->full_name() << " not covered"; break;
    }
  }
}

TEST(FrameEncoding, AnEncodedFrameKeepsEveryOtherField) {
  // Reflection fills every field, so a field added to Frame later and not copied fails here.
  const std::set<std::string> buffers = {"positions", "normals", "energies", "vertices",
                                         "position_box", "energies_max", "encoding", "delta"};
  pb::Frame header;
  fill_every_field(&header, buffers);
  header.set_superseded(false);  // a superseded frame has no buffers to encode
  pb::Frame f = header;
  *f.mutable_positions() = float_bytes({1, 2, 3});
  *f.mutable_normals() = float_bytes({0, 0, 1});
  pb::FrameFormat fmt;
  fmt.set_encoding(pb::FRAME_ENCODING_QUANTIZED);
  pb::Frame out;
  ASSERT_TRUE(svc::encode_frame_to(f, fmt, false, &out));
  google::protobuf::util::MessageDifferencer diff;
  for (const auto& name : buffers) diff.IgnoreField(pb::Frame::descriptor()->FindFieldByName(name));
  std::string report;
  diff.ReportDifferencesToString(&report);
  EXPECT_TRUE(diff.Compare(header, out)) << report;
  // omit_buffers: the same header, no buffers.
  ASSERT_TRUE(svc::encode_frame_to(f, pb::FrameFormat{}, true, &out));
  EXPECT_TRUE(diff.Compare(header, out)) << report;
  EXPECT_TRUE(out.positions().empty() && out.vertices().empty() && out.normals().empty());
}

TEST(FrameEncoding, ExactFramesGoAsFloat32OnlyWhenAsked) {
  pb::Frame f;
  f.set_exact(true);
  pb::FrameFormat fmt;
  fmt.set_encoding(pb::FRAME_ENCODING_MESHOPT);
  EXPECT_EQ(svc::encoding_for(f, fmt), pb::FRAME_ENCODING_MESHOPT);
  fmt.set_exact_as_float32(true);
  EXPECT_EQ(svc::encoding_for(f, fmt), pb::FRAME_ENCODING_FLOAT32);
  f.set_exact(false);
  EXPECT_EQ(svc::encoding_for(f, fmt), pb::FRAME_ENCODING_MESHOPT);
}

// Watchers of one session share each frame's encodes: one per encoding, for the newest frame.
TEST(FrameEncoding, WatchersShareOneEncodePerEncoding) {
  service::EncodedFrameCache cache;
  auto first = std::make_shared<pb::SessionEvent>();
  *first->mutable_frame() = random_frame(500, 900, 11);
  std::shared_ptr<const pb::SessionEvent> event = first;
  pb::FrameFormat meshopt, quantized, float32;
  meshopt.set_encoding(pb::FRAME_ENCODING_MESHOPT);
  quantized.set_encoding(pb::FRAME_ENCODING_QUANTIZED);
  const auto a = cache.get(event, meshopt);
  const auto b = cache.get(event, meshopt);
  EXPECT_EQ(a, b);  // the same encoded event, not an equal one
  EXPECT_EQ(cache.encodes(), 1);
  pb::Frame expected;
  ASSERT_TRUE(service::encode_frame_to(event->frame(), meshopt, false, &expected));
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(a->frame(), expected));
  const auto q = cache.get(event, quantized);
  EXPECT_NE(q, a);
  EXPECT_EQ(q->frame().encoding(), pb::FRAME_ENCODING_QUANTIZED);
  EXPECT_EQ(cache.get(event, float32), event);  // FLOAT32 goes out as broadcast
  EXPECT_EQ(cache.encodes(), 2);
  // A newer frame replaces the older one's encodings.
  auto second = std::make_shared<pb::SessionEvent>();
  *second->mutable_frame() = random_frame(500, 900, 12);
  const auto c = cache.get(second, meshopt);
  EXPECT_NE(c->frame().vertices(), a->frame().vertices());
  EXPECT_EQ(cache.encodes(), 3);
  // Non-frame events pass through.
  auto state = std::make_shared<pb::SessionEvent>();
  state->mutable_state()->set_version(4);
  EXPECT_EQ(cache.get(state, meshopt), state);
}

TEST(FrameDecode, MalformedFramesAreRefusedWithTheirReason) {
  pb::FrameFormat fmt;
  fmt.set_encoding(pb::FRAME_ENCODING_MESHOPT);
  pb::Frame good;
  ASSERT_TRUE(svc::encode_frame_to(random_frame(100, 10, 1), fmt, false, &good));
  auto expect_refused = [](const pb::Frame& f, std::size_t n, std::size_t t, const char* what) {
    try {
      decode_frame(f, n, t);
      ADD_FAILURE() << "decoded: " << what;
    } catch (const cli::FrameDecodeError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  pb::Frame f = good;
  f.mutable_vertices()->resize(f.vertices().size() / 2);
  expect_refused(f, 100, 10, "not a meshopt vertex buffer");
  expect_refused(good, 300, 10, "not a meshopt vertex buffer");
  expect_refused(good, 100, 11, "energies");
  f = good;
  f.mutable_position_box()->mutable_min()->set_x(1e9);
  expect_refused(f, 100, 10, "position_box");
  f = good;
  f.set_energies_max(-1);
  expect_refused(f, 100, 10, "energies_max");
  f = good;
  f.set_encoding(pb::FRAME_ENCODING_QUANTIZED);
  expect_refused(f, 100, 10, "vertices");
  f.set_encoding(static_cast<pb::FrameEncoding>(9));
  expect_refused(f, 100, 10, "unknown");
  pb::Frame g;
  g.set_positions(std::string(11, '\0'));
  expect_refused(g, 1, 0, "positions");
}

// ---- over loopback --------------------------------------------------------------------

pb::UpdateHandlesRequest move(const std::string& name, std::int64_t seq, pb::FrameEncoding enc,
                              bool dragging = false) {
  pb::UpdateHandlesRequest req;
  req.set_name(name);
  req.set_sequence(seq);
  *req.add_transforms() = cactus_transform();
  req.set_energies(true);
  req.set_dragging(dragging);
  req.mutable_format()->set_encoding(enc);
  return req;
}

TEST(FrameEncodingService, UpdateHandlesAnswersInTheEncodingAskedAndDecodesToTheExactFrame) {
  TestServer t;
  const auto s = constrained_cactus(t);
  const std::size_t n = s.vertex_count(), tris = s.triangle_count();
  pb::Frame exact;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, move(s.name(), 1, pb::FRAME_ENCODING_FLOAT32), &exact).ok());
  }
  ASSERT_EQ(exact.encoding(), pb::FRAME_ENCODING_FLOAT32);
  std::size_t bytes[3] = {cli::frame_buffer_bytes(exact), 0, 0};
  for (auto enc : {pb::FRAME_ENCODING_QUANTIZED, pb::FRAME_ENCODING_MESHOPT}) {
    pb::Frame f;
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, move(s.name(), 2, enc), &f).ok());
    EXPECT_EQ(f.encoding(), enc);
    EXPECT_TRUE(f.exact());
    EXPECT_TRUE(f.has_measures());
    bytes[enc] = cli::frame_buffer_bytes(f);
    // Same transforms, same exact solve: the decoded frame is the float32 one within bounds.
    expect_within_stated_bounds(exact, decode_frame(f, n, tris), f.position_box(), f.energies_max());
  }
  std::printf("[ measured ] cactus (%zu vertices) bytes per frame with energies: float32 %zu, "
              "quantized %zu, meshopt %zu\n", n, bytes[0], bytes[1], bytes[2]);
  EXPECT_LE(bytes[1] * 2, bytes[0]);
  EXPECT_LT(bytes[2], bytes[1]);

  // exact_as_float32: exact frames come as float32, drag frames as asked.
  auto req = move(s.name(), 3, pb::FRAME_ENCODING_MESHOPT);
  req.mutable_format()->set_exact_as_float32(true);
  pb::Frame f;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, req, &f).ok());
  }
  EXPECT_EQ(f.encoding(), pb::FRAME_ENCODING_FLOAT32);
  EXPECT_EQ(f.positions(), exact.positions());
  req.set_dragging(true);
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, req, &f).ok());
  }
  if (!f.exact()) {
    EXPECT_EQ(f.encoding(), pb::FRAME_ENCODING_MESHOPT);
  }

  // omit_buffers: the frame's header only.
  req = move(s.name(), 4, pb::FRAME_ENCODING_FLOAT32);
  req.set_omit_buffers(true);
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, req, &f).ok());
  }
  EXPECT_EQ(cli::frame_buffer_bytes(f), 0u);
  EXPECT_EQ(f.sequence(), 4);
  EXPECT_TRUE(f.has_measures());
  EXPECT_GT(f.version(), exact.version());
}

// FLOAT64: the solve's own doubles, checked against GetMesh's OBJ (%.17g, an independent
// path to the same solve; the cactus is an OBJ, so base order is engine order).
TEST(FrameEncodingService, Float64FramesAreTheSolvesDoublesAndWatchersRefuseThem) {
  TestServer t;
  const auto s = constrained_cactus(t);
  const std::size_t n = s.vertex_count(), tris = s.triangle_count();
  pb::Frame f32, f64;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(t.stub->UpdateHandles(&ctx, move(s.name(), 1, pb::FRAME_ENCODING_FLOAT32), &f32).ok());
  }
  {
    grpc::ClientContext ctx;
    const auto st = t.stub->UpdateHandles(&ctx, move(s.name(), 2, pb::FRAME_ENCODING_FLOAT64), &f64);
    ASSERT_TRUE(st.ok()) << st.error_message();
  }
  ASSERT_EQ(f64.encoding(), pb::FRAME_ENCODING_FLOAT64);
  EXPECT_TRUE(f64.exact());
  EXPECT_TRUE(f64.has_measures());
  EXPECT_EQ(f64.sequence(), 2);
  ASSERT_EQ(f64.positions().size(), 24 * n);
  ASSERT_EQ(f64.normals().size(), 24 * n);
  EXPECT_EQ(f64.energies(), f32.energies());  // energies stay float32
  std::vector<double> p(3 * n), nrm(3 * n);
  std::memcpy(p.data(), f64.positions().data(), f64.positions().size());
  std::memcpy(nrm.data(), f64.normals().data(), f64.normals().size());
  const auto d32 = decode_frame(f32, n, tris);
  std::size_t not_float = 0;
  for (std::size_t i = 0; i < 3 * n; ++i) {
    EXPECT_EQ(static_cast<float>(p[i]), d32.positions[i]) << i;  // same solve, rounded
    EXPECT_EQ(static_cast<float>(nrm[i]), d32.normals[i]) << i;
    not_float += static_cast<double>(static_cast<float>(p[i])) != p[i];
  }
  EXPECT_GT(not_float, n);  // doubles, not widened floats

  std::istringstream obj(t.deformed(s.name(), pb::MESH_FORMAT_OBJ));
  std::string line;
  std::size_t v = 0;
  while (std::getline(obj, line)) {
    if (line.rfind("v ", 0) != 0) continue;
    std::istringstream xyz(line.substr(2));
    double c[3];
    xyz >> c[0] >> c[1] >> c[2];
    for (int k = 0; k < 3; ++k) EXPECT_EQ(c[k], p[3 * v + k]) << "vertex " << v;
    ++v;
  }
  EXPECT_EQ(v, n);

  // The CLI's decoder reads it (rounded to its float32 frame).
  EXPECT_EQ(decode_frame(f64, n, tris).positions, d32.positions);

  // Watchers share float32 frames: FLOAT64 there is refused, naming the stream.
  grpc::ClientContext wctx;
  pb::WatchSessionRequest wreq;
  wreq.set_name(s.name());
  wreq.mutable_format()->set_encoding(pb::FRAME_ENCODING_FLOAT64);
  auto reader = t.stub->WatchSession(&wctx, wreq);
  pb::SessionEvent ev;
  EXPECT_FALSE(reader->Read(&ev));
  const auto st = reader->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("WatchSession: frame encoding FLOAT64"), std::string::npos)
      << st.error_message();

  // A Deform stream's frames come as doubles too.
  grpc::ClientContext dctx;
  auto stream = t.stub->Deform(&dctx);
  auto req = deform_request(s.name(), 3, cactus_transform());
  req.mutable_format()->set_encoding(pb::FRAME_ENCODING_FLOAT64);
  ASSERT_TRUE(stream->Write(req));
  pb::Frame fd;
  ASSERT_TRUE(stream->Read(&fd));
  EXPECT_EQ(fd.encoding(), pb::FRAME_ENCODING_FLOAT64);
  EXPECT_EQ(fd.positions(), f64.positions());  // same transforms, same exact solve
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST(FrameEncodingService, UnknownEncodingsAreInvalidArgumentsEverywhere) {
  TestServer t;
  const auto s = constrained_cactus(t);
  const auto bad = static_cast<pb::FrameEncoding>(7);
  pb::Frame f;
  {
    grpc::ClientContext ctx;
    const auto st = t.stub->UpdateHandles(&ctx, move(s.name(), 1, bad), &f);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("unknown frame encoding 7"), std::string::npos)
        << st.error_message();
  }
  {
    grpc::ClientContext ctx;
    pb::WatchSessionRequest req;
    req.set_name(s.name());
    req.mutable_format()->set_encoding(bad);
    auto reader = t.stub->WatchSession(&ctx, req);
    pb::SessionEvent ev;
    EXPECT_FALSE(reader->Read(&ev));
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  }
  {
    grpc::ClientContext ctx;
    auto stream = t.stub->Deform(&ctx);
    auto req = deform_request(s.name(), 1, cactus_transform());
    req.mutable_format()->set_encoding(bad);
    stream->Write(req);
    stream->WritesDone();
    while (stream->Read(&f)) {
    }
    EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  }
  // The session still serves.
  grpc::ClientContext ctx;
  EXPECT_TRUE(t.stub->UpdateHandles(&ctx, move(s.name(), 2, pb::FRAME_ENCODING_MESHOPT), &f).ok());
}

TEST(FrameEncodingService, DeformAndWatchStreamsCarryTheirOwnEncodings) {
  TestServer t;
  const auto s = constrained_cactus(t);
  const std::size_t n = s.vertex_count(), tris = s.triangle_count();
  // A watcher in MESHOPT and one in FLOAT32 see the same frames, each in its encoding.
  grpc::ClientContext wctx_m, wctx_f;
  pb::WatchSessionRequest wm, wf;
  wm.set_name(s.name());
  wm.mutable_format()->set_encoding(pb::FRAME_ENCODING_MESHOPT);
  wf.set_name(s.name());
  auto watch_m = t.stub->WatchSession(&wctx_m, wm);
  auto watch_f = t.stub->WatchSession(&wctx_f, wf);
  pb::SessionEvent ev;
  ASSERT_TRUE(watch_m->Read(&ev) && ev.has_state());
  ASSERT_TRUE(watch_f->Read(&ev) && ev.has_state());

  grpc::ClientContext ctx;
  auto stream = t.stub->Deform(&ctx);
  auto req = deform_request(s.name(), 1, cactus_transform());
  req.mutable_format()->set_encoding(pb::FRAME_ENCODING_QUANTIZED);
  ASSERT_TRUE(stream->Write(req));
  pb::Frame f1;
  ASSERT_TRUE(stream->Read(&f1));
  EXPECT_EQ(f1.encoding(), pb::FRAME_ENCODING_QUANTIZED);
  // A later message without a format keeps the stream's; one with a format changes it.
  ASSERT_TRUE(stream->Write(deform_request("", 2, cactus_transform())));
  pb::Frame f2;
  ASSERT_TRUE(stream->Read(&f2));
  EXPECT_EQ(f2.encoding(), pb::FRAME_ENCODING_QUANTIZED);
  req = deform_request("", 3, cactus_transform());
  req.mutable_format()->set_encoding(pb::FRAME_ENCODING_FLOAT32);
  ASSERT_TRUE(stream->Write(req));
  pb::Frame f3;
  ASSERT_TRUE(stream->Read(&f3));
  EXPECT_EQ(f3.encoding(), pb::FRAME_ENCODING_FLOAT32);
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
  expect_within_stated_bounds(f3, decode_frame(f1, n, tris), f1.position_box(), 0);

  // Each watcher sees the last frame (sequence 3) in its own encoding.
  for (auto* w : {watch_m.get(), watch_f.get()}) {
    pb::Frame last;
    while (last.sequence() != 3 && w->Read(&ev))
      if (ev.has_frame()) last = ev.frame();
    ASSERT_EQ(last.sequence(), 3);
    const auto d = decode_frame(last, n, tris);
    if (w == watch_m.get()) {
      EXPECT_EQ(last.encoding(), pb::FRAME_ENCODING_MESHOPT);
      expect_within_stated_bounds(f3, d, last.position_box(), 0);
    } else {
      EXPECT_EQ(last.encoding(), pb::FRAME_ENCODING_FLOAT32);
      EXPECT_EQ(last.positions(), f3.positions());
    }
  }
  wctx_m.TryCancel();
  wctx_f.TryCancel();
  watch_m->Finish();
  watch_f->Finish();
}

// Coalescing: updates queued behind a slow call on the session's strand (a β change on the
// 40K-vertex plane) are superseded by the newest; beyond --max-pending-updates they are
// refused. The newest is solved and its frame is the session's state.
TEST(FrameEncodingService, CoalescingUpdatesLetTheNewestWinWithinTheLimit) {
  service::ServerOptions options;
  options.request.max_pending_updates = 3;
  TestServer t(options);
  const pb::Session plane = t.library_session("plane");
  pb::Session st;
  ASSERT_TRUE(t.set_constraints(plane.name(), benchmark_constraints("plane"), &st).ok());

  pb::Session beta_out;
  grpc::ClientContext beta_ctx;
  pb::SetBetaRequest beta_req;
  beta_req.set_name(plane.name());
  beta_req.mutable_beta()->set_value(0.37);
  grpc::CompletionQueue cq;
  auto beta_call = t.stub->AsyncSetBeta(&beta_ctx, beta_req, &cq);
  grpc::Status beta_status;
  beta_call->Finish(&beta_out, &beta_status, reinterpret_cast<void*>(100));
  // Nothing tells a client that its call reached the strand; the β change takes seconds
  // (a first β > 0 factorization on the 40K plane), so a short pause lets it arrive first.
  std::this_thread::sleep_for(std::chrono::milliseconds(50));

  constexpr int kUpdates = 5;
  grpc::ClientContext ctxs[kUpdates];
  pb::Frame frames[kUpdates];
  grpc::Status statuses[kUpdates];
  std::unique_ptr<grpc::ClientAsyncResponseReader<pb::Frame>> calls[kUpdates];
  for (int i = 0; i < kUpdates; ++i) {
    pb::UpdateHandlesRequest req;
    req.set_name(plane.name());
    req.set_sequence(i + 1);
    *req.add_transforms() = translation(0, 0, 0.01 * (i + 1));
    req.set_coalesce(true);
    calls[i] = t.stub->AsyncUpdateHandles(&ctxs[i], req, &cq);
    calls[i]->Finish(&frames[i], &statuses[i], reinterpret_cast<void*>(std::intptr_t{i}));
  }
  void* tag;
  bool ok;
  for (int done = 0; done < kUpdates + 1 && cq.Next(&tag, &ok); ++done) {
  }
  ASSERT_TRUE(beta_status.ok()) << beta_status.error_message();
  int superseded = 0, solved = 0, refused = 0;
  for (int i = 0; i < kUpdates; ++i) {
    if (statuses[i].error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
      EXPECT_NE(statuses[i].error_message().find("--max-pending-updates"), std::string::npos);
      ++refused;
      continue;
    }
    ASSERT_TRUE(statuses[i].ok()) << statuses[i].error_message();
    EXPECT_EQ(frames[i].sequence(), i + 1);
    if (frames[i].superseded()) {
      ++superseded;
      EXPECT_EQ(cli::frame_buffer_bytes(frames[i]), 0u);
    } else {
      ++solved;
    }
  }
  std::printf("[ measured ] %d superseded, %d solved, %d refused\n", superseded, solved, refused);
  // All five were sent while the β change held the strand (it takes far longer than five
  // sends on loopback): three waited (the limit), two were refused, the newest waiting won.
  EXPECT_EQ(refused, kUpdates - 3);
  EXPECT_EQ(solved, 1);
  EXPECT_EQ(superseded, 2);
  int newest = -1;
  for (int i = 0; i < kUpdates; ++i)
    if (statuses[i].ok() && !frames[i].superseded()) newest = i;
  // Concurrent calls may reach the server in any order, so "newest" is arrival order: the
  // solved one ran last on the strand, after every superseded one committed its move.
  ASSERT_GE(newest, 0);
  for (int i = 0; i < kUpdates; ++i)
    if (statuses[i].ok() && frames[i].superseded()) {
      EXPECT_LT(frames[i].version(), frames[newest].version()) << "an older update won";
    }
  pb::GetSessionRequest get;
  get.set_name(plane.name());
  pb::Session after;
  grpc::ClientContext get_ctx;
  ASSERT_TRUE(t.stub->GetSession(&get_ctx, get, &after).ok());
  ASSERT_EQ(after.transforms_size(), 1);
  EXPECT_EQ(after.transforms(0).translation().z(), 0.01 * (newest + 1))
      << "the session keeps the newest update's move";
  // The slots are free again: a next coalescing update is solved.
  pb::UpdateHandlesRequest req;
  req.set_name(plane.name());
  req.set_sequence(9);
  *req.add_transforms() = translation(0, 0, 0.5);
  req.set_coalesce(true);
  pb::Frame last;
  grpc::ClientContext ctx;
  ASSERT_TRUE(t.stub->UpdateHandles(&ctx, req, &last).ok());
  EXPECT_FALSE(last.superseded());
  EXPECT_FALSE(last.positions().empty());
}

}  // namespace
}  // namespace hdeform::testing

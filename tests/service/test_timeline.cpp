// Timeline and animation export (docs/api.md "Timeline and animation"), on a real server over
// loopback: keys set, read and interpolated; the animated GLB's every sample equals the
// server's own exact frame of that pose (a full deformation, not a blend of key positions);
// β steps; limits and bad inputs named; tokens; the timeline's life with constraints,
// watchers, export/import and named snapshots.
#include "editors_fixture.h"

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <numbers>

namespace hdeform::testing {
namespace {

pb::HandleTransform moved(double x, double y, double z, double angle_x = 0) {
  pb::HandleTransform t = translation(x, y, z);
  auto* q = t.mutable_rotation();
  q->set_w(std::cos(angle_x / 2));
  q->set_x(std::sin(angle_x / 2));
  return t;
}

pb::Keyframe key(double time, std::vector<pb::HandleTransform> ts) {
  pb::Keyframe k;
  k.set_time_s(time);
  for (auto& t : ts) *k.add_transforms() = t;
  return k;
}

// Three keys: both handles rise, the second also turns 90° about x.
pb::Timeline three_keys() {
  pb::Timeline t;
  *t.add_keys() = key(0, {moved(0, 0, 0), moved(0, 0, 0)});
  *t.add_keys() = key(1, {moved(0, 0, 0.5), moved(0, 0, 0.2, std::numbers::pi / 2)});
  *t.add_keys() = key(2, {moved(0, 0, 1), moved(0, 0, 0.4, std::numbers::pi / 2)});
  return t;
}

struct Timeline : TwoHandles {
  using TwoHandles::TwoHandles;
  grpc::Status set(const pb::Timeline& timeline, pb::Timeline* out = nullptr,
                   const std::string& token = "", std::int64_t config_version = 0) {
    pb::SetTimelineRequest r;
    r.set_name(s.name());
    *r.mutable_timeline() = timeline;
    r.set_client_id("a1");
    r.set_expected_config_version(config_version);
    pb::Timeline resp;
    return t.bare_stub->SetTimeline(as(token.empty() ? s.edit_token() : token).get(), r,
                                    out ? out : &resp);
  }
  pb::Timeline get(const std::string& token = "") {
    pb::GetTimelineRequest r;
    r.set_name(s.name());
    pb::Timeline out;
    const auto st = t.bare_stub->GetTimeline(as(token.empty() ? s.view_token() : token).get(), r, &out);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return out;
  }
  grpc::Status pose(double time, pb::Keyframe* out) {
    pb::PoseAtRequest r;
    r.set_name(s.name());
    r.set_time_s(time);
    return t.bare_stub->PoseAt(as(s.view_token()).get(), r, out);
  }
  grpc::Status export_animation(const pb::ExportAnimationRequest& request, std::string* glb,
                                const std::string& token = "") {
    auto ctx = as(token.empty() ? s.edit_token() : token);
    pb::ExportAnimationRequest r = request;
    r.set_name(s.name());
    auto reader = t.bare_stub->ExportAnimation(ctx.get(), r);
    pb::MeshChunk chunk;
    glb->clear();
    while (reader->Read(&chunk)) glb->append(chunk.data());
    return reader->Finish();
  }
  // The server's exact frame of a pose (UpdateHandles), as float32 positions.
  std::vector<float> frame_of(const pb::Keyframe& pose) {
    std::vector<pb::HandleTransform> ts(pose.transforms().begin(), pose.transforms().end());
    pb::Frame f;
    const auto st = update("", {}, ts, &f);
    EXPECT_TRUE(st.ok()) << st.error_message();
    std::vector<float> p(f.positions().size() / 4);
    std::memcpy(p.data(), f.positions().data(), f.positions().size());
    return p;
  }
};

tinygltf::Model load(const std::string& glb) {
  tinygltf::TinyGLTF io;
  tinygltf::Model model;
  std::string err, warn;
  EXPECT_TRUE(io.LoadBinaryFromMemory(&model, &err, &warn,
                                      reinterpret_cast<const unsigned char*>(glb.data()),
                                      static_cast<unsigned int>(glb.size())))
      << err;
  return model;
}

const float* floats(const tinygltf::Model& m, int accessor) {
  const auto& a = m.accessors[static_cast<std::size_t>(accessor)];
  const auto& v = m.bufferViews[static_cast<std::size_t>(a.bufferView)];
  return reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
}

// Sample k's positions: base + target k − 1.
std::vector<float> sample(const tinygltf::Model& m, std::size_t k) {
  const auto& prim = m.meshes[0].primitives[0];
  const auto n = m.accessors[static_cast<std::size_t>(prim.attributes.at("POSITION"))].count;
  const float* base = floats(m, prim.attributes.at("POSITION"));
  std::vector<float> p(base, base + 3 * n);
  if (k > 0) {
    const float* d = floats(m, prim.targets[k - 1].at("POSITION"));
    for (std::size_t i = 0; i < 3 * n; ++i) p[i] += d[i];
  }
  return p;
}

double max_diff(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double d = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    d = std::max(d, std::abs(double{a[i]} - double{b[i]}));
  return d;
}

TEST(Timeline, SetGetAndPoseAtInterpolate) {
  Timeline f;
  pb::Timeline out;
  auto st = f.set(three_keys(), &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(out.keys_size(), 3);
  EXPECT_EQ(out.version(), f.state().version());
  const pb::Timeline got = f.get();
  EXPECT_EQ(got.keys_size(), 3);
  EXPECT_EQ(got.keys(1).transforms(1).translation().z(), 0.2);
  pb::Keyframe mid;
  ASSERT_TRUE(f.pose(0.5, &mid).ok());
  ASSERT_EQ(mid.transforms_size(), 2);
  EXPECT_NEAR(mid.transforms(0).translation().z(), 0.25, 1e-15);
  // Half of a 90° turn about x.
  EXPECT_NEAR(mid.transforms(1).rotation().x(), std::sin(std::numbers::pi / 8), 1e-12);
  EXPECT_TRUE(mid.transforms(1).has_pivot());  // the rest centroid, made explicit
  EXPECT_FALSE(mid.has_beta());
  pb::Keyframe after;
  ASSERT_TRUE(f.pose(7, &after).ok());
  EXPECT_EQ(after.transforms(0).translation().z(), 1);  // the last key holds
}

// A key's easing rules its segment: PoseAt eases 0 → 1 s, not 1 → 2 s; an unknown value
// is refused naming the key; a change of a key's easing alone is a new timeline (a step).
TEST(Timeline, AKeysEasingRulesItsSegment) {
  Timeline f;
  pb::Timeline t = three_keys();
  t.mutable_keys(0)->set_easing(pb::EASING_SMOOTHSTEP);
  auto st = f.set(t);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(f.get().keys(0).easing(), pb::EASING_SMOOTHSTEP);
  EXPECT_FALSE(f.get().keys(1).has_easing());
  pb::Keyframe pose;
  ASSERT_TRUE(f.pose(0.25, &pose).ok());  // u = 0.25 eased: 0.15625 of 0.5
  EXPECT_NEAR(pose.transforms(0).translation().z(), 0.5 * 0.15625, 1e-15);
  ASSERT_TRUE(f.pose(1.25, &pose).ok());  // the timeline's linear: 0.5 + 0.25 · 0.5
  EXPECT_NEAR(pose.transforms(0).translation().z(), 0.625, 1e-15);
  t.mutable_keys(1)->set_easing(static_cast<pb::Easing>(7));
  st = f.set(t);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("keys[1].easing: unknown value 7"), std::string::npos)
      << st.error_message();
  const auto version = f.get().version();
  t.mutable_keys(1)->set_easing(pb::EASING_LINEAR);  // the same as unset, but said: a change
  ASSERT_TRUE(f.set(t).ok());
  EXPECT_TRUE(f.get().keys(1).has_easing());
  EXPECT_EQ(f.get().version(), version);  // the pose did not change
}

TEST(Timeline, EverySampleIsTheServersExactFrameOfThatPose) {
  Timeline f;
  ASSERT_TRUE(f.set(three_keys()).ok());
  pb::ExportAnimationRequest r;
  r.set_fps(4);  // 0, 0.25, …, 2: 9 samples
  std::string glb;
  auto st = f.export_animation(r, &glb);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const auto model = load(glb);
  ASSERT_EQ(model.meshes[0].primitives[0].targets.size(), 8u);
  ASSERT_EQ(model.animations.size(), 1u);
  const float* times = floats(model, model.animations[0].samplers[0].input);
  std::vector<float> key0, key1;
  for (std::size_t k = 0; k < 9; ++k) {
    EXPECT_EQ(times[k], static_cast<float>(0.25 * static_cast<double>(k)));
    pb::Keyframe pose;
    ASSERT_TRUE(f.pose(0.25 * static_cast<double>(k), &pose).ok());
    const auto exact = f.frame_of(pose);
    // Coordinates ≤ 4: float32 spacing 5e-7, the delta's own rounding at most as much.
    EXPECT_LT(max_diff(sample(model, k), exact), 2e-6) << "sample " << k;
    if (k == 0) key0 = exact;
    if (k == 4) key1 = exact;
  }
  // An in-between is a deformation of the slerped pose, not the blend of key positions: the
  // turning handle's region moves on an arc, so the blend is visibly off at t = 0.5.
  std::vector<float> blend(key0.size());
  for (std::size_t i = 0; i < blend.size(); ++i) blend[i] = 0.5f * (key0[i] + key1[i]);
  EXPECT_GT(max_diff(sample(model, 2), blend), 1e-2);
}

TEST(Timeline, BetaStepsFromTheKeyThatSetsIt) {
  Timeline f;
  pb::Timeline t = three_keys();
  t.mutable_keys(1)->mutable_beta()->set_value(0.5);
  ASSERT_TRUE(f.set(t).ok());
  pb::Keyframe before, after;
  ASSERT_TRUE(f.pose(0.9, &before).ok());
  ASSERT_TRUE(f.pose(1.5, &after).ok());
  EXPECT_FALSE(before.has_beta());
  ASSERT_TRUE(after.has_beta());
  EXPECT_EQ(after.beta().value(), 0.5);
  // Sample t = 2 (the last) is deformed at β = 0.5: equal to the session's frame at that β.
  pb::ExportAnimationRequest r;
  r.set_fps(1);
  std::string glb;
  ASSERT_TRUE(f.export_animation(r, &glb).ok());
  const auto model = load(glb);
  pb::Keyframe last;
  ASSERT_TRUE(f.pose(2, &last).ok());
  const auto at_zero = f.frame_of(last);
  pb::Session out;
  ASSERT_TRUE(f.t.set_beta(f.s.name(), 0.5, &out).ok());
  const auto at_half = f.frame_of(last);
  EXPECT_LT(max_diff(sample(model, 2), at_half), 2e-6);
  EXPECT_GT(max_diff(at_half, at_zero), 1e-3);  // β matters here, so the check can fail
}

TEST(Timeline, EnergiesBecomeColorTargets) {
  Timeline f;
  ASSERT_TRUE(f.set(three_keys()).ok());
  pb::ExportAnimationRequest r;
  r.set_fps(2);
  r.set_energies(true);
  r.set_up(pb::UP_AXIS_Z);
  std::string glb;
  ASSERT_TRUE(f.export_animation(r, &glb).ok());
  const auto model = load(glb);
  const auto& prim = model.meshes[0].primitives[0];
  ASSERT_EQ(prim.attributes.count("COLOR_0"), 1u);
  for (const auto& target : prim.targets) EXPECT_EQ(target.count("COLOR_0"), 1u);
  ASSERT_EQ(model.scenes[0].nodes.size(), 1u);
  EXPECT_EQ(model.nodes[static_cast<std::size_t>(model.scenes[0].nodes[0])].name, "z-up to y-up");
}

TEST(Timeline, LimitsAndBadInputsAreNamed) {
  Timeline f;
  auto expect = [](const grpc::Status& st, grpc::StatusCode code, const std::string& part) {
    EXPECT_EQ(st.error_code(), code) << st.error_message();
    EXPECT_NE(st.error_message().find(part), std::string::npos) << st.error_message();
  };
  std::string glb;
  pb::ExportAnimationRequest r;
  expect(f.export_animation(r, &glb), grpc::StatusCode::FAILED_PRECONDITION, "no timeline");
  pb::Keyframe k;
  expect(f.pose(1, &k), grpc::StatusCode::FAILED_PRECONDITION, "no timeline");

  pb::Timeline bad = three_keys();
  bad.mutable_keys(2)->set_time_s(0.5);
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "keys[2]: time 0.5 s must be after");
  bad = three_keys();
  bad.mutable_keys(1)->mutable_transforms()->RemoveLast();
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "keys[1]: 1 transforms for 2 handles");
  bad = three_keys();
  bad.mutable_keys(0)->mutable_transforms(0)->mutable_rotation()->set_w(3);
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "keys[0].transforms[0]");
  bad = three_keys();
  bad.mutable_keys(0)->mutable_beta()->set_automatic(true);
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "keys[0].beta");
  bad = three_keys();
  bad.mutable_keys(0)->mutable_beta()->set_value(1.5);
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "keys[0].beta");
  bad = pb::Timeline();
  for (int i = 0; i < 6; ++i) {
    *bad.add_keys() = key(i, {moved(0, 0, 0), moved(0, 0, 0)});
    bad.mutable_keys(i)->mutable_beta()->set_value(0.1 * i);
  }
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "more than 4 distinct β");
  bad = three_keys();
  bad.set_easing(static_cast<pb::Easing>(7));
  expect(f.set(bad), grpc::StatusCode::INVALID_ARGUMENT, "easing");
  EXPECT_EQ(f.get().keys_size(), 0);  // nothing of a refused timeline was kept

  ASSERT_TRUE(f.set(three_keys()).ok());
  r.set_fps(1000);
  expect(f.export_animation(r, &glb), grpc::StatusCode::INVALID_ARGUMENT, "fps");
  r.set_fps(24);
  r.set_start_s(2);
  r.set_end_s(1);
  expect(f.export_animation(r, &glb), grpc::StatusCode::INVALID_ARGUMENT, "start_s");
  r.set_start_s(0);
  r.set_end_s(1e300);
  expect(f.export_animation(r, &glb), grpc::StatusCode::RESOURCE_EXHAUSTED,
         "--max-animation-frames");
  r.set_end_s(30);  // 721 samples > 600
  expect(f.export_animation(r, &glb), grpc::StatusCode::RESOURCE_EXHAUSTED,
         "--max-animation-frames");
  // The view token reads the timeline but neither sets it nor exports (exports solve).
  EXPECT_EQ(f.get(f.s.view_token()).keys_size(), 3);
  EXPECT_EQ(f.set(three_keys(), nullptr, f.s.view_token()).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  r = pb::ExportAnimationRequest();
  EXPECT_EQ(f.export_animation(r, &glb, f.s.view_token()).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  // A change made against an old constraint/β state is refused.
  pb::Session out;
  ASSERT_TRUE(f.t.set_beta(f.s.name(), 0.1, &out).ok());
  expect(f.set(three_keys(), nullptr, "", f.s.config_version()), grpc::StatusCode::ABORTED,
         "reload");
}

void expect_status(const grpc::Status& st, grpc::StatusCode code, const std::string& part) {
  EXPECT_EQ(st.error_code(), code) << st.error_message();
  EXPECT_NE(st.error_message().find(part), std::string::npos) << st.error_message();
}

TEST(Timeline, FrameAndByteLimitsComeFromTheFlags) {
  service::ServerOptions options;
  options.request.max_animation_frames = 10;
  Timeline f(options);
  ASSERT_TRUE(f.set(three_keys()).ok());
  pb::ExportAnimationRequest r;
  r.set_fps(5);  // 11 samples over 2 s
  std::string glb;
  expect_status(f.export_animation(r, &glb), grpc::StatusCode::RESOURCE_EXHAUSTED,
                "11 exceeds the limit of 10 (--max-animation-frames)");
  r.set_fps(4);  // 9 samples: fine
  EXPECT_TRUE(f.export_animation(r, &glb).ok());

  options.request.max_animation_frames = 600;
  options.request.max_animation_bytes = 100'000;
  Timeline g(options);
  ASSERT_TRUE(g.set(three_keys()).ok());
  r.set_fps(24);  // 49 samples of 169 vertices: ≈ 200 KB
  expect_status(g.export_animation(r, &glb), grpc::StatusCode::RESOURCE_EXHAUSTED,
                "(--max-animation-bytes)");
  // The server goes on: a small export still works.
  r.set_fps(1);
  EXPECT_TRUE(g.export_animation(r, &glb).ok());
}

// New constraints renumber the handles, so the keys go with them — but never silently
// another editor's: refused naming them unless discard_timeline, and Undo brings them back.
TEST(Timeline, NewConstraintsDropItOnlyWhenAskedAndUndoBringsItBack) {
  Timeline f;
  ASSERT_TRUE(f.set(three_keys()).ok());  // set by client "a1"
  auto ctx = as(f.s.view_token());
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
  pb::WatchSessionRequest w;
  w.set_name(f.s.name());
  auto reader = f.t.bare_stub->WatchSession(ctx.get(), w);
  pb::SessionEvent e;
  auto next_keys = [&] {
    while (reader->Read(&e))
      if (e.has_timeline()) return e.timeline().keys_size();
    return -1;
  };
  EXPECT_EQ(next_keys(), 3);  // the timeline comes on join
  pb::SetConstraintsRequest c;
  c.set_name(f.s.name());
  c.set_client_id("b2");
  *c.mutable_constraints()->mutable_fixed()->add_selectors() = box(-1, -0.01, 4, 0.01);
  *c.mutable_constraints()->add_handles()->add_selectors() = box(2.9, 2.6, 3.2, 3);
  pb::Session out;
  auto st = f.t.bare_stub->SetConstraints(as(f.s.edit_token()).get(), c, &out);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_NE(st.error_message().find("3 key(s)"), std::string::npos) << st.error_message();
  EXPECT_NE(st.error_message().find("discard_timeline"), std::string::npos) << st.error_message();
  EXPECT_EQ(f.get().keys_size(), 3);
  EXPECT_EQ(f.state().constraints().handles_size(), 2);  // nothing applied

  c.set_discard_timeline(true);
  st = f.t.bare_stub->SetConstraints(as(f.s.edit_token()).get(), c, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(next_keys(), 0);
  EXPECT_EQ(f.get().keys_size(), 0);
  EXPECT_EQ(out.constraints().handles_size(), 1);

  pb::UndoRequest u;
  u.set_name(f.s.name());
  u.set_client_id("b2");
  st = f.t.bare_stub->Undo(as(f.s.edit_token()).get(), u, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(next_keys(), 3);
  const pb::Timeline back = f.get();
  ASSERT_EQ(back.keys_size(), 3);
  EXPECT_EQ(back.keys(1).transforms(1).translation().z(), 0.2);
  EXPECT_EQ(out.constraints().handles_size(), 2);
  pb::Keyframe mid;
  EXPECT_TRUE(f.pose(0.5, &mid).ok());  // usable again: the keys match the handles

  // The same client's own keys go without asking (Undo still brings them back).
  c.set_discard_timeline(false);
  c.set_client_id("a1");
  st = f.t.bare_stub->SetConstraints(as(f.s.edit_token()).get(), c, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(f.get().keys_size(), 0);
  ctx->TryCancel();
  reader->Finish();
}

TEST(Timeline, TravelsWithExportImportButNotInNamedSnapshots) {
  Timeline f;
  pb::Timeline t = three_keys();
  t.set_easing(pb::EASING_SMOOTHSTEP);
  ASSERT_TRUE(f.set(t).ok());
  pb::Snapshot snap;
  ASSERT_TRUE(f.t.export_session(f.s.name(), &snap).ok());
  EXPECT_EQ(snap.timeline().keys_size(), 3);
  pb::Session copy;
  ASSERT_TRUE(f.t.import_session(snap, &copy).ok());
  pb::GetTimelineRequest r;
  r.set_name(copy.name());
  pb::Timeline got;
  ASSERT_TRUE(f.t.bare_stub->GetTimeline(as(copy.view_token()).get(), r, &got).ok());
  EXPECT_EQ(got.keys_size(), 3);
  EXPECT_EQ(got.easing(), pb::EASING_SMOOTHSTEP);

  pb::SaveSnapshotRequest save;
  save.set_name(f.s.name());
  save.set_snapshot("pose");
  pb::NamedSnapshot named;
  ASSERT_TRUE(f.t.bare_stub->SaveSnapshot(as(f.s.edit_token()).get(), save, &named).ok());
  EXPECT_FALSE(named.snapshot().has_timeline());
}

}  // namespace
}  // namespace hdeform::testing

namespace hdeform::testing {
namespace {

// ExportRig (docs/api.md "Rig export"): the report on the first chunk, the key TRS, limits
// and bad inputs. The GLB itself is checked by tinygltf here and by the Khronos validator and
// three.js in tests/browser/rig_glb.mjs.
grpc::Status export_rig(Timeline& f, const pb::ExportRigRequest& request, std::string* glb,
                        pb::RigReport* report, const std::string& token = "") {
  auto ctx = as(token.empty() ? f.s.edit_token() : token);
  pb::ExportRigRequest r = request;
  r.set_name(f.s.name());
  auto reader = f.t.bare_stub->ExportRig(ctx.get(), r);
  pb::MeshChunk chunk;
  glb->clear();
  bool first = true;
  while (reader->Read(&chunk)) {
    EXPECT_EQ(chunk.has_rig_report(), first);
    if (first && report) *report = chunk.rig_report();
    first = false;
    glb->append(chunk.data());
  }
  return reader->Finish();
}

TEST(RigExport, ReportsEveryPoseAndAnimatesTheKeysAboutTheBindPivots) {
  Timeline f;
  ASSERT_TRUE(f.set(three_keys()).ok());
  std::string glb;
  pb::RigReport report;
  const auto st = export_rig(f, {}, &glb, &report);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(report.joints(), 3);
  EXPECT_EQ(report.influences(), 4);
  ASSERT_EQ(report.poses_size(), 4);  // current, then keys at 0, 1, 2 s
  EXPECT_TRUE(report.poses(0).current());
  EXPECT_EQ(report.poses(2).time_s(), 1.0);
  EXPECT_LT(report.poses(1).max(), 1e-12);  // key 0 is the rest pose: LBS and solve agree
  EXPECT_GT(report.poses(3).max(), report.poses(3).rms());
  EXPECT_GT(report.bbox_diagonal(), 0);

  const tinygltf::Model m = load(glb);
  ASSERT_EQ(m.skins.size(), 1u);
  EXPECT_EQ(m.skins[0].joints.size(), 3u);
  ASSERT_EQ(m.animations.size(), 1u);
  // Handle 0 at key 1 is a pure translation (0, 0, 0.5): its joint sits at bind + t, bind
  // being the handle's pivot (here its rest centroid, Session.pivots).
  const int joint0 = m.skins[0].joints[1];
  int found = 0;
  for (const auto& ch : m.animations[0].channels) {
    if (ch.target_node != joint0 || ch.target_path != "translation") continue;
    ++found;
    const auto& sampler = m.animations[0].samplers[static_cast<std::size_t>(ch.sampler)];
    const float* t = floats(m, sampler.output);
    const auto& pivot = f.s.pivots(0);
    EXPECT_NEAR(t[3 + 0], pivot.x(), 1e-6);
    EXPECT_NEAR(t[3 + 1], pivot.y(), 1e-6);
    EXPECT_NEAR(t[3 + 2], pivot.z() + 0.5, 1e-6);
  }
  EXPECT_EQ(found, 1);

  pb::ExportRigRequest still;
  still.set_skip_animation(true);
  still.set_influences(8);
  ASSERT_TRUE(export_rig(f, still, &glb, &report).ok());
  EXPECT_EQ(report.poses_size(), 1);
  EXPECT_EQ(report.influences(), 8);
  EXPECT_TRUE(load(glb).animations.empty());
}

TEST(RigExport, BadInputsAndLimitsAreNamedAndTheServerGoesOn) {
  service::ServerOptions options;
  options.request.max_animation_bytes = 20'000;
  Timeline f(options);
  std::string glb;
  pb::ExportRigRequest r;
  r.set_influences(5);
  expect_status(export_rig(f, r, &glb, nullptr), grpc::StatusCode::INVALID_ARGUMENT,
                "ExportRig influences: 5 is not 4 or 8");
  r.set_influences(4);
  r.set_up(static_cast<pb::UpAxis>(7));
  expect_status(export_rig(f, r, &glb, nullptr), grpc::StatusCode::INVALID_ARGUMENT,
                "ExportRig up: unknown up axis 7");
  r.set_up(pb::UP_AXIS_Z);
  expect_status(export_rig(f, r, &glb, nullptr, f.s.view_token()),
                grpc::StatusCode::PERMISSION_DENIED, "");
  // A sheared handle has no glTF TRS.
  pb::HandleTransform shear;
  for (double v : {1.0, 0.2, 0.0, 0.2, 1.0, 0.0, 0.0, 0.0, 1.0}) shear.mutable_stretch()->add_m(v);
  ASSERT_TRUE(f.update("", {0}, {shear}).ok());
  expect_status(export_rig(f, r, &glb, nullptr), grpc::StatusCode::FAILED_PRECONDITION,
                "handle 0 (the current pose) has a stretch that is not axis-aligned");
  ASSERT_TRUE(f.update("", {0}, {moved(0, 0, 0.5)}).ok());
  EXPECT_TRUE(export_rig(f, r, &glb, nullptr).ok());
  // 169 vertices fit in 20 KB; 256 keys of two handles do not.
  pb::Timeline many;
  for (int k = 0; k < 256; ++k) *many.add_keys() = key(k, {moved(0, 0, 0), moved(0, 0, 0)});
  ASSERT_TRUE(f.set(many).ok());
  expect_status(export_rig(f, r, &glb, nullptr), grpc::StatusCode::RESOURCE_EXHAUSTED,
                "(--max-animation-bytes)");
  r.set_skip_animation(true);
  EXPECT_TRUE(export_rig(f, r, &glb, nullptr).ok());
}

}  // namespace
}  // namespace hdeform::testing

// ExportSession → ImportSession reproduces the deformation bit for bit.
#include "service_fixture.h"

using namespace hdeform::testing;

namespace {
pb::Snapshot export_session(TestServer& t, const std::string& name, bool include_mesh) {
  pb::Snapshot snap;
  auto st = t.export_session(name, &snap, include_mesh);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return snap;
}
}  // namespace

TEST(ServiceSnapshot, LibraryMeshRoundTripIsBitForBit) {
  TestServer t;
  const pb::Session s = t.library_session("cactus");
  pb::Session c;
  ASSERT_TRUE(t.set_constraints(s.name(), cactus_constraints(), &c).ok());
  ASSERT_TRUE(t.set_beta(s.name(), 0.3, &c).ok());
  pb::Frame f;
  ASSERT_TRUE(t.update(s.name(), 1, {cactus_transform()}, &f).ok());

  const pb::Snapshot snap = export_session(t, s.name(), false);
  EXPECT_EQ(snap.library_mesh(), "cactus");
  EXPECT_EQ(snap.mesh_hash(), s.mesh_hash());
  EXPECT_TRUE(snap.mesh_bytes().empty());
  ASSERT_EQ(snap.transforms_size(), 1);

  pb::Session imported;
  auto st = t.import_session(snap, &imported);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_NE(imported.name(), s.name());
  EXPECT_EQ(imported.mesh_hash(), s.mesh_hash());
  EXPECT_DOUBLE_EQ(imported.beta().value(), 0.3);
  EXPECT_TRUE(imported.constrained());

  EXPECT_EQ(t.deformed(imported.name(), pb::MESH_FORMAT_OFF),
            t.deformed(s.name(), pb::MESH_FORMAT_OFF));
  EXPECT_EQ(t.deformed(imported.name(), pb::MESH_FORMAT_GLB),
            t.deformed(s.name(), pb::MESH_FORMAT_GLB));
  // And the imported session's own frames match the original's.
  pb::Frame g;
  ASSERT_TRUE(t.update(imported.name(), 1, {cactus_transform()}, &g).ok());
  EXPECT_EQ(g.positions(), f.positions());
}

TEST(ServiceSnapshot, UploadWithMeshMovesToAnotherServer) {
  TestServer a, b;
  pb::Session s;
  ASSERT_TRUE(a.upload(slurp(data_path("models/knight.off")), "knight.off", &s).ok());
  pb::Constraints c;
  auto* fixed = c.mutable_fixed()->add_selectors()->mutable_half_space();
  fixed->mutable_normal()->set_y(-1);
  fixed->set_offset(-(s.bbox_min().y() + 0.15 * (s.bbox_max().y() - s.bbox_min().y())));
  auto* handle = c.add_handles()->add_selectors()->mutable_half_space();
  handle->mutable_normal()->set_y(1);
  handle->set_offset(s.bbox_min().y() + 0.85 * (s.bbox_max().y() - s.bbox_min().y()));
  pb::Session out;
  auto st = a.set_constraints(s.name(), c, &out);
  ASSERT_TRUE(st.ok()) << st.error_message();
  pb::HandleTransform t = translation(0.05, 0.02, 0);
  t.mutable_rotation()->set_w(std::cos(0.2));
  t.mutable_rotation()->set_x(std::sin(0.2));
  t.set_uniform_scale(1.1);
  pb::Frame f;
  ASSERT_TRUE(a.update(s.name(), 1, {t}, &f).ok());

  // Without the mesh, another server cannot know it.
  pb::Session imported;
  EXPECT_EQ(b.import_session(export_session(a, s.name(), false), &imported).error_code(),
            grpc::StatusCode::NOT_FOUND);

  const pb::Snapshot snap = export_session(a, s.name(), true);
  EXPECT_FALSE(snap.mesh_bytes().empty());
  st = b.import_session(snap, &imported);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(imported.mesh_hash(), s.mesh_hash());
  // Another server solves again: equal up to the solver's rounding (ASan runs showed 1e-15).
  expect_same_mesh_text(b.deformed(imported.name(), pb::MESH_FORMAT_OFF),
                        a.deformed(s.name(), pb::MESH_FORMAT_OFF));

  // A snapshot whose hash does not match its mesh is refused.
  pb::Snapshot wrong = snap;
  wrong.set_mesh_hash("0123456789abcdef");
  EXPECT_EQ(b.import_session(wrong, &imported).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
}

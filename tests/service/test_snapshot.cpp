// ExportSession → ImportSession reproduces the deformation bit for bit.
#include "engine/io/mesh_io.h"
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

// Outputs keep what the user gave: a binary PLY comes back binary (unless asked otherwise),
// a z-up model's GLB gets the root rotation, and unknown values are refused.
TEST(ServiceOutputs, BinaryPlyStaysBinaryAndUpZRotatesTheGlb) {
  TestServer t;
  const std::string off = grid_off(6);
  const hdeform::LoadedMesh mesh = hdeform::read_mesh_bytes(off, "g.off");
  hdeform::WriteOptions binary;
  binary.binary_ply = true;
  const std::string ply =
      hdeform::write_mesh_bytes(hdeform::MeshFileFormat::ply, mesh.mesh.V, mesh.mesh.F, nullptr, binary);
  pb::Session s;
  ASSERT_TRUE(t.upload(ply, "g.ply", &s).ok());
  auto get = [&](pb::MeshFormat f, pb::UpAxis up, pb::PlyEncoding enc, std::string* out) {
    grpc::ClientContext ctx;
    pb::GetMeshRequest r;
    r.set_name(s.name());
    r.set_format(f);
    r.set_up(up);
    r.set_ply_encoding(enc);
    auto reader = t.stub->GetMesh(&ctx, r);
    pb::MeshChunk c;
    out->clear();
    while (reader->Read(&c)) *out += c.data();
    return reader->Finish();
  };
  std::string bytes;
  ASSERT_TRUE(get(pb::MESH_FORMAT_PLY, pb::UP_AXIS_Y, pb::PLY_ENCODING_AS_INPUT, &bytes).ok());
  EXPECT_EQ(bytes.rfind("ply\nformat binary_little_endian", 0), 0u);
  ASSERT_TRUE(get(pb::MESH_FORMAT_PLY, pb::UP_AXIS_Y, pb::PLY_ENCODING_ASCII, &bytes).ok());
  EXPECT_EQ(bytes.rfind("ply\nformat ascii", 0), 0u);
  // The positions of the binary output are the upload's, bit for bit.
  ASSERT_TRUE(get(pb::MESH_FORMAT_PLY, pb::UP_AXIS_Y, pb::PLY_ENCODING_BINARY, &bytes).ok());
  EXPECT_EQ(hdeform::read_mesh_bytes(bytes, "x.ply").mesh.V, mesh.mesh.V);
  ASSERT_TRUE(get(pb::MESH_FORMAT_GLB, pb::UP_AXIS_Z, pb::PLY_ENCODING_AS_INPUT, &bytes).ok());
  EXPECT_NE(bytes.find("z-up to y-up"), std::string::npos);
  EXPECT_EQ(hdeform::read_mesh_bytes(bytes, "x.glb").mesh.V,
            mesh.mesh.V.cast<float>().cast<double>().eval());
  auto st = get(pb::MESH_FORMAT_GLB, static_cast<pb::UpAxis>(7), pb::PLY_ENCODING_AS_INPUT, &bytes);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("unknown up axis 7"), std::string::npos) << st.error_message();
  st = get(pb::MESH_FORMAT_PLY, pb::UP_AXIS_Y, static_cast<pb::PlyEncoding>(9), &bytes);
  EXPECT_NE(st.error_message().find("unknown PLY encoding 9"), std::string::npos);
}

// GetMesh's glb_compression: quantized and meshopt GLBs come over loopback; a compression for a
// text format, an unknown value, or a glTF upload's rewritten GLB is refused by name, and the
// session keeps serving.
TEST(ServiceOutputs, CompressedGlbAndItsBadRequests) {
  TestServer t;
  const std::string off = grid_off(6);
  const hdeform::LoadedMesh mesh = hdeform::read_mesh_bytes(off, "g.off");
  pb::Session s;
  ASSERT_TRUE(t.upload(off, "g.off", &s).ok());
  auto get = [&](const std::string& name, pb::MeshFormat f, int compression, bool rest,
                 std::string* out) {
    grpc::ClientContext ctx;
    pb::GetMeshRequest r;
    r.set_name(name);
    r.set_format(f);
    r.set_rest(rest);
    r.set_glb_compression(static_cast<pb::GlbCompression>(compression));
    auto reader = t.stub->GetMesh(&ctx, r);
    pb::MeshChunk c;
    out->clear();
    while (reader->Read(&c)) *out += c.data();
    return reader->Finish();
  };
  std::string plain, quantized, meshopt;
  ASSERT_TRUE(get(s.name(), pb::MESH_FORMAT_GLB, pb::GLB_COMPRESSION_NONE, false, &plain).ok());
  ASSERT_TRUE(get(s.name(), pb::MESH_FORMAT_GLB, pb::GLB_COMPRESSION_QUANTIZED, false, &quantized).ok());
  ASSERT_TRUE(get(s.name(), pb::MESH_FORMAT_GLB, pb::GLB_COMPRESSION_MESHOPT, true, &meshopt).ok());
  // The engine's writer itself (tests/engine/test_glb_compressed.cpp checks its contents).
  hdeform::WriteOptions q, m;
  q.glb_compression = hdeform::GlbCompression::quantized;
  m.glb_compression = hdeform::GlbCompression::meshopt;
  EXPECT_EQ(quantized, hdeform::write_mesh_bytes(hdeform::MeshFileFormat::glb, mesh.mesh.V,
                                                 mesh.mesh.F, nullptr, q));
  EXPECT_EQ(meshopt, hdeform::write_mesh_bytes(hdeform::MeshFileFormat::glb, mesh.mesh.V,
                                               mesh.mesh.F, nullptr, m));
  EXPECT_LT(quantized.size(), plain.size());

  std::string bytes;
  auto st = get(s.name(), pb::MESH_FORMAT_OBJ, pb::GLB_COMPRESSION_QUANTIZED, false, &bytes);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("glb_compression applies to GLB only, not to MESH_FORMAT_OBJ"),
            std::string::npos) << st.error_message();
  st = get(s.name(), pb::MESH_FORMAT_GLB, 5, false, &bytes);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("unknown glb_compression 5"), std::string::npos)
      << st.error_message();

  // A glTF upload: its deformed GLB is the upload rewritten, never compressed; its rest mesh is.
  pb::Session g;
  ASSERT_TRUE(t.upload(plain, "g.glb", &g).ok());
  st = get(g.name(), pb::MESH_FORMAT_GLB, pb::GLB_COMPRESSION_MESHOPT, false, &bytes);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("glTF upload rewritten"), std::string::npos)
      << st.error_message();
  EXPECT_TRUE(get(g.name(), pb::MESH_FORMAT_GLB, pb::GLB_COMPRESSION_MESHOPT, true, &bytes).ok());
  // And a compressed GLB uploaded back is refused by name.
  pb::Session back;
  st = t.upload(quantized, "q.glb", &back);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("requires the glTF extension KHR_mesh_quantization"),
            std::string::npos) << st.error_message();
  // Nothing was lost: the first session still serves.
  EXPECT_TRUE(get(s.name(), pb::MESH_FORMAT_GLB, pb::GLB_COMPRESSION_NONE, false, &bytes).ok());
  EXPECT_EQ(bytes, plain);
}

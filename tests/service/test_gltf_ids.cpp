// Selector.base_ids on a glTF upload whose vertices are split at a seam: the ids are base-GLB
// (frame buffer) indices, mapped through the reader's weld map to engine ids.
#include "engine/io/mesh_io.h"
#include "service_fixture.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

namespace hdeform::testing {
namespace {

// A flat 7×5 grid (x = 0.5 i, y = 0.5 j) written as GLB in two blocks that both carry the
// seam column i = 3: left block L(i, j) = 4 j + i for i = 0..3 (base ids 0..19), right block
// R(i, j) = 20 + 4 j + (i − 3) for i = 3..6 (base ids 20..39). The reader welds the 5
// duplicated positions: 40 base vertices, 35 engine vertices; engine ids follow first
// occurrence, so L(i, j) keeps its id, R(3, j) becomes L(3, j) and R(i > 3, j) becomes
// 20 + 3 j + (i − 4).
constexpr int kBase = 40, kEngine = 35;
int L(int i, int j) { return 4 * j + i; }
int R(int i, int j) { return 20 + 4 * j + (i - 3); }
int engine_of_R(int i, int j) { return i == 3 ? L(3, j) : 20 + 3 * j + (i - 4); }

std::string seam_grid_glb() {
  Vertices V(kBase, 3);
  for (int j = 0; j < 5; ++j) {
    for (int i = 0; i <= 3; ++i) V.row(L(i, j)) << 0.5 * i, 0.5 * j, 0.0;
    for (int i = 3; i <= 6; ++i) V.row(R(i, j)) << 0.5 * i, 0.5 * j, 0.0;
  }
  std::vector<std::array<int, 3>> tris;
  auto quads = [&](int i0, int i1, auto id) {
    for (int j = 0; j < 4; ++j)
      for (int i = i0; i < i1; ++i) {
        tris.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        tris.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      }
  };
  quads(0, 3, L);
  quads(3, 6, R);
  Triangles F(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t)
    F.row(static_cast<Eigen::Index>(t)) << tris[t][0], tris[t][1], tris[t][2];
  return write_mesh_bytes(MeshFileFormat::glb, V, F);
}

void add_base_ids(pb::Region* region, const std::vector<int>& ids) {
  auto* s = region->add_selectors()->mutable_base_ids();
  for (int id : ids) s->add_ids(id);
}

std::vector<int> ids_of(const pb::VertexIds& v) { return {v.ids().begin(), v.ids().end()}; }

std::vector<float> floats(const std::string& bytes) {
  std::vector<float> out(bytes.size() / sizeof(float));
  std::memcpy(out.data(), bytes.data(), out.size() * sizeof(float));
  return out;
}

pb::HandleTransform translate_z(double dz) {
  pb::HandleTransform t;
  t.mutable_translation()->set_z(dz);
  return t;
}

// fixed: column 0 (left block); handle 0: column 6 (right block; base ids 23..39, beyond
// the engine's 35 vertices); handle 1: the seam vertex at (1.5, 1), by its RIGHT copy only.
pb::Constraints seam_constraints() {
  pb::Constraints c;
  std::vector<int> fixed, right;
  for (int j = 0; j < 5; ++j) {
    fixed.push_back(L(0, j));
    right.push_back(R(6, j));
  }
  add_base_ids(c.mutable_fixed(), fixed);
  add_base_ids(c.add_handles(), right);
  add_base_ids(c.add_handles(), {R(3, 2)});
  return c;
}

TEST(GltfBaseIds, SeamUploadResolvesThroughTheWeldMap) {
  TestServer ts;
  pb::Session s;
  auto st = ts.upload(seam_grid_glb(), "seam-grid.glb", &s);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(s.vertex_count(), kBase);
  EXPECT_FALSE(s.has_base_constraints());

  pb::Session after;
  st = ts.set_constraints(s.name(), seam_constraints(), &after);
  ASSERT_TRUE(st.ok()) << st.error_message();

  // Engine ids in `constraints` …
  std::vector<int> fixed_engine, right_engine, right_base;
  for (int j = 0; j < 5; ++j) {
    fixed_engine.push_back(L(0, j));
    right_engine.push_back(engine_of_R(6, j));
    right_base.push_back(R(6, j));
  }
  ASSERT_EQ(after.constraints().handles_size(), 2);
  EXPECT_EQ(ids_of(after.constraints().fixed()), fixed_engine);
  EXPECT_EQ(ids_of(after.constraints().handles(0)), right_engine);
  EXPECT_EQ(ids_of(after.constraints().handles(1)), (std::vector<int>{L(3, 2)}));
  // … and base-GLB ids in `base_constraints`: both copies of the seam vertex.
  ASSERT_TRUE(after.has_base_constraints());
  ASSERT_EQ(after.base_constraints().handles_size(), 2);
  EXPECT_EQ(ids_of(after.base_constraints().fixed()), fixed_engine);  // left block: same ids
  EXPECT_EQ(ids_of(after.base_constraints().handles(0)), right_base);
  EXPECT_EQ(ids_of(after.base_constraints().handles(1)), (std::vector<int>{L(3, 2), R(3, 2)}));

  pb::Frame frame;
  st = ts.update(s.name(), 1, {translate_z(1.0), translate_z(0.5)}, &frame);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const std::vector<float> P = floats(frame.positions());
  ASSERT_EQ(P.size(), 3u * kBase);
  auto z = [&](int v) { return P[3 * v + 2]; };
  for (int j = 0; j < 5; ++j) {
    SCOPED_TRACE("row " + std::to_string(j));
    EXPECT_EQ(z(L(0, j)), 0.0f);                // fixed
    EXPECT_NEAR(z(R(6, j)), 1.0f, 1e-5);        // handle 0 at its target
    EXPECT_FLOAT_EQ(P[3 * R(6, j)], 3.0f);      // x unchanged by a z translation
    for (int k = 0; k < 3; ++k)                 // seam copies coincide exactly
      EXPECT_EQ(P[3 * L(3, j) + k], P[3 * R(3, j) + k]) << "coordinate " << k;
  }
  // The seam vertex named by its right copy is at its target in both copies.
  EXPECT_NEAR(z(L(3, 2)), 0.5f, 1e-5);
  EXPECT_NEAR(z(R(3, 2)), 0.5f, 1e-5);
  // The free vertices follow harmonically (strictly between the fixed and the handle).
  EXPECT_GT(z(L(2, 2)), 0.0f);
  EXPECT_LT(z(R(5, 1)), 1.0f);
  EXPECT_GT(z(R(5, 1)), 0.0f);

  // GetMesh GLB (rest and current) is in the same 40-vertex base layout as the frame.
  for (bool rest : {true, false}) {
    SCOPED_TRACE(rest ? "rest GLB" : "current GLB");
    std::string glb;
    st = ts.get_mesh(s.name(), rest, pb::MESH_FORMAT_GLB, &glb);
    ASSERT_TRUE(st.ok()) << st.error_message();
    const LoadedMesh back = read_mesh_bytes(glb, "back.glb");
    ASSERT_EQ(back.input_to_engine.size(), static_cast<std::size_t>(kBase));
    const Vertices Vb = back.to_input_layout(back.mesh.V);
    for (int v = 0; v < kBase; ++v)
      EXPECT_FLOAT_EQ(static_cast<float>(Vb(v, 2)), rest ? 0.0f : z(v)) << "vertex " << v;
  }

  // The base ids of the seam vertex's left copy name the same engine vertex.
  pb::Constraints left = seam_constraints();
  left.mutable_handles(1)->mutable_selectors(0)->mutable_base_ids()->set_ids(0, L(3, 2));
  st = ts.set_constraints(s.name(), left, &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(ids_of(after.constraints().handles(1)), (std::vector<int>{L(3, 2)}));
  // … and so do engine ids (Selector.ids).
  pb::Constraints engine = seam_constraints();
  engine.mutable_handles(1)->clear_selectors();
  engine.mutable_handles(1)->add_selectors()->mutable_ids()->add_ids(L(3, 2));
  st = ts.set_constraints(s.name(), engine, &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(ids_of(after.base_constraints().handles(1)), (std::vector<int>{L(3, 2), R(3, 2)}));
}

TEST(GltfBaseIds, OutOfRangeBaseIdIsInvalidArgument) {
  TestServer ts;
  pb::Session s;
  auto st = ts.upload(seam_grid_glb(), "seam-grid.glb", &s);
  ASSERT_TRUE(st.ok()) << st.error_message();

  pb::Constraints c = seam_constraints();
  c.mutable_handles(0)->mutable_selectors(0)->mutable_base_ids()->add_ids(kBase);
  pb::Session after;
  st = ts.set_constraints(s.name(), c, &after);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("base vertex id 40"), std::string::npos) << st.error_message();
  EXPECT_NE(st.error_message().find("handle 0"), std::string::npos) << st.error_message();

  // Engine ids keep the engine's range: 36 is a base id but not an engine id.
  pb::Constraints e = seam_constraints();
  e.mutable_handles(1)->clear_selectors();
  e.mutable_handles(1)->add_selectors()->mutable_ids()->add_ids(kEngine + 1);
  st = ts.set_constraints(s.name(), e, &after);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("vertex id 36"), std::string::npos) << st.error_message();

  c = seam_constraints();
  c.mutable_fixed()->mutable_selectors(0)->mutable_base_ids()->add_ids(-1);
  st = ts.set_constraints(s.name(), c, &after);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("base vertex id -1"), std::string::npos) << st.error_message();
}

TEST(GltfBaseIds, LocalBetaRegionTakesBaseIds) {
  TestServer ts;
  pb::Session s;
  auto st = ts.upload(seam_grid_glb(), "seam-grid.glb", &s);
  ASSERT_TRUE(st.ok()) << st.error_message();
  pb::Session after;
  ASSERT_TRUE(ts.set_constraints(s.name(), seam_constraints(), &after).ok());

  pb::Beta b;
  b.set_value(0.1);
  auto* local = b.add_local();
  local->set_beta(0.5);
  add_base_ids(local->mutable_region(), {R(5, 2), R(6, 4)});  // 39: beyond the engine's 35
  st = ts.set_beta(s.name(), b, &after);
  ASSERT_TRUE(st.ok()) << st.error_message();
  pb::Frame frame;
  st = ts.update(s.name(), 1, {translate_z(1.0), translate_z(0.5)}, &frame);
  ASSERT_TRUE(st.ok()) << st.error_message();

  b.mutable_local(0)->mutable_region()->mutable_selectors(0)->mutable_base_ids()->add_ids(kBase);
  st = ts.set_beta(s.name(), b, &after);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("beta.local[0] region"), std::string::npos)
      << st.error_message();
  EXPECT_NE(st.error_message().find("base vertex id 40"), std::string::npos)
      << st.error_message();
}

// For OBJ/OFF/PLY/STL (and library meshes) base ids are engine ids; no base_constraints.
TEST(GltfBaseIds, IdentityLayoutsTakeBaseIdsAsEngineIds) {
  TestServer ts;
  pb::Session s = ts.library_session("cactus");
  pb::Constraints a = benchmark_constraints("cactus");
  pb::Session resolved;
  ASSERT_TRUE(ts.set_constraints(s.name(), a, &resolved).ok());
  EXPECT_FALSE(resolved.has_base_constraints());
  pb::Constraints b;
  add_base_ids(b.mutable_fixed(), ids_of(resolved.constraints().fixed()));
  add_base_ids(b.add_handles(), ids_of(resolved.constraints().handles(0)));
  pb::Session again;
  auto st = ts.set_constraints(s.name(), b, &again);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(again.constraints().SerializeAsString(), resolved.constraints().SerializeAsString());
  EXPECT_FALSE(again.has_base_constraints());
}

// The seam grid dressed as a textured asset: UVs, tangents, a named material with an
// embedded image, named nodes with a transform, and a points primitive. The deformed GLB of
// such an upload keeps all of it and replaces only POSITION and NORMAL (TANGENT dropped).
std::string dressed_glb() {
  const std::string plain = seam_grid_glb();
  tinygltf::TinyGLTF io;
  tinygltf::Model model;
  std::string err, warn;
  EXPECT_TRUE(io.LoadBinaryFromMemory(&model, &err, &warn,
                                      reinterpret_cast<const unsigned char*>(plain.data()),
                                      static_cast<unsigned int>(plain.size())))
      << err;
  auto& data = model.buffers[0].data;
  auto view = [&](const void* bytes, std::size_t n) {
    while (data.size() % 4) data.push_back(0);
    tinygltf::BufferView bv;
    bv.buffer = 0;
    bv.byteOffset = data.size();
    bv.byteLength = n;
    data.insert(data.end(), static_cast<const unsigned char*>(bytes),
                static_cast<const unsigned char*>(bytes) + n);
    model.bufferViews.push_back(bv);
    return static_cast<int>(model.bufferViews.size()) - 1;
  };
  std::vector<float> uv(2 * kBase), tangent(4 * kBase, 0.0f);
  for (int v = 0; v < kBase; ++v) {
    uv[2 * v] = 0.01f * static_cast<float>(v);
    uv[2 * v + 1] = 1.0f - 0.02f * static_cast<float>(v);
    tangent[4 * v] = tangent[4 * v + 3] = 1.0f;
  }
  auto accessor = [&](int bv, int type, std::size_t count) {
    tinygltf::Accessor a;
    a.bufferView = bv;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = type;
    a.count = count;
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size()) - 1;
  };
  auto& prim = model.meshes[0].primitives[0];
  prim.attributes["TEXCOORD_0"] = accessor(view(uv.data(), uv.size() * 4), TINYGLTF_TYPE_VEC2, kBase);
  prim.attributes["TANGENT"] = accessor(view(tangent.data(), tangent.size() * 4), TINYGLTF_TYPE_VEC4, kBase);
  const std::string png = "\x89PNG not really, kept byte for byte";
  tinygltf::Image image;
  image.name = "checker";
  image.mimeType = "image/png";
  image.bufferView = view(png.data(), png.size());
  model.images.push_back(image);
  tinygltf::Texture tex;
  tex.source = 0;
  model.textures.push_back(tex);
  tinygltf::Material mat;
  mat.name = "painted";
  mat.pbrMetallicRoughness.baseColorTexture.index = 0;
  model.materials.push_back(mat);
  prim.material = 0;
  // A second primitive that is not deformed: three points.
  tinygltf::Primitive points;
  points.mode = TINYGLTF_MODE_POINTS;
  const float p3[9] = {9, 9, 9, 8, 8, 8, 7, 7, 7};
  points.attributes["POSITION"] = accessor(view(p3, sizeof p3), TINYGLTF_TYPE_VEC3, 3);
  model.meshes[0].primitives.push_back(points);
  model.nodes[0].name = "body";
  model.nodes[0].translation = {1.0, 2.0, 3.0};
  std::ostringstream os;
  EXPECT_TRUE(io.WriteGltfSceneToStream(&model, os, false, true));
  return os.str();
}

bool keep_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;  // the test's image bytes are not a real PNG: compare them, never decode
}

TEST(GltfOutputs, ADeformedGlbKeepsTheInputsAttributesAndStructure) {
  TestServer t;
  pb::Session s;
  ASSERT_TRUE(t.upload(dressed_glb(), "dressed.glb", &s).ok());
  pb::Session c;
  ASSERT_TRUE(t.set_constraints(s.name(), seam_constraints(), &c).ok());
  pb::Frame frame;
  auto st = t.update(s.name(), 1, {translate_z(0.5), translate_z(-0.25)}, &frame);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const std::string out = t.deformed(s.name(), pb::MESH_FORMAT_GLB);

  tinygltf::TinyGLTF io;
  io.SetImageLoader(keep_image, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(io.LoadBinaryFromMemory(&model, &err, &warn,
                                      reinterpret_cast<const unsigned char*>(out.data()),
                                      static_cast<unsigned int>(out.size())))
      << err;
  auto floats_of = [&](int accessor) {
    const auto& a = model.accessors.at(static_cast<std::size_t>(accessor));
    const auto& bv = model.bufferViews.at(static_cast<std::size_t>(a.bufferView));
    const std::size_t n = a.count * static_cast<std::size_t>(tinygltf::GetNumComponentsInType(a.type));
    std::vector<float> v(n);
    std::memcpy(v.data(), model.buffers[0].data.data() + bv.byteOffset + a.byteOffset, n * 4);
    return v;
  };
  ASSERT_EQ(model.meshes.size(), 1u);
  ASSERT_EQ(model.meshes[0].primitives.size(), 2u);
  const auto& prim = model.meshes[0].primitives[0];
  EXPECT_EQ(floats_of(prim.attributes.at("POSITION")), floats(frame.positions()));
  EXPECT_EQ(floats_of(prim.attributes.at("NORMAL")).size(), 3u * kBase);
  EXPECT_EQ(prim.attributes.count("TANGENT"), 0u);  // stale after deforming: dropped
  const std::vector<float> uv = floats_of(prim.attributes.at("TEXCOORD_0"));
  ASSERT_EQ(uv.size(), 2u * kBase);
  EXPECT_FLOAT_EQ(uv[2 * 7], 0.07f);
  ASSERT_EQ(prim.material, 0);
  EXPECT_EQ(model.materials.at(0).name, "painted");
  ASSERT_EQ(model.images.size(), 1u);
  const auto& ibv = model.bufferViews.at(static_cast<std::size_t>(model.images[0].bufferView));
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(model.buffers[0].data.data() + ibv.byteOffset),
                        ibv.byteLength),
            "\x89PNG not really, kept byte for byte");
  EXPECT_EQ(model.nodes.at(0).name, "body");
  EXPECT_EQ(model.nodes.at(0).translation, (std::vector<double>{1.0, 2.0, 3.0}));
  const auto& points = model.meshes[0].primitives[1];
  EXPECT_EQ(points.mode, TINYGLTF_MODE_POINTS);
  EXPECT_EQ(floats_of(points.attributes.at("POSITION")),
            (std::vector<float>{9, 9, 9, 8, 8, 8, 7, 7, 7}));
  // The base (rest) GLB the viewer loads keeps its plain layout.
  std::string rest;
  ASSERT_TRUE(t.get_mesh(s.name(), true, pb::MESH_FORMAT_GLB, &rest).ok());
  EXPECT_EQ(rest.find("painted"), std::string::npos);
}

}  // namespace
}  // namespace hdeform::testing

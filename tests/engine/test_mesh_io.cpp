// Mesh file I/O: round trips, the data/ meshes, glTF welding, triangulation, errors.
#include "engine/io/mesh_io.h"
#include "engine/io/rewrite_gltf.h"
#include "engine/mesh/validate.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <tuple>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>

#include <unistd.h>

namespace hdeform {
namespace {

const std::string kData = HDEFORM_TEST_DATA;

// A tetrahedron with awkward doubles (not representable in float, extreme exponents).
TriMesh awkward_tetra() {
  TriMesh m;
  m.V.resize(4, 3);
  m.V << 0.1, 1.0 / 3.0, -2.5e17,             //
      std::acos(-1.0), 1e-300, -0.0,            //
      123456789.123456789, -7.0 / 9.0, 5e-324,  //
      std::nextafter(1.0, 2.0), 2.0 / 3.0, -1.0 / 7.0;
  m.F.resize(4, 3);
  m.F << 0, 2, 1,  //
      0, 1, 3,     //
      1, 2, 3,     //
      0, 3, 2;
  return m;
}

void expect_bitwise_equal(const Vertices& a, const Vertices& b) {
  ASSERT_EQ(a.rows(), b.rows());
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (int k = 0; k < 3; ++k) {
      uint64_t x, y;
      double ax = a(i, k), bx = b(i, k);
      std::memcpy(&x, &ax, 8);
      std::memcpy(&y, &bx, 8);
      EXPECT_EQ(x, y) << "vertex " << i << " coordinate " << k << ": " << ax << " vs " << bx;
    }
}

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "(no InvalidInput thrown)";
}

class TextRoundTrip : public ::testing::TestWithParam<MeshFileFormat> {};

TEST_P(TextRoundTrip, ExactDoublesAndSameTriangles) {
  const TriMesh m = awkward_tetra();
  const std::string name = GetParam() == MeshFileFormat::obj ? "t.obj" : GetParam() == MeshFileFormat::off ? "t.off" : "t.ply";
  for (bool with_normals : {false, true}) {
    const Vertices N = vertex_normals(m.V, m.F);
    const std::string bytes = write_mesh_bytes(GetParam(), m.V, m.F, with_normals ? &N : nullptr);
    const LoadedMesh r = read_mesh_bytes(bytes, name);
    expect_bitwise_equal(r.mesh.V, m.V);
    EXPECT_EQ(r.mesh.F, m.F);
    EXPECT_EQ(r.input_triangles, m.F);
    EXPECT_TRUE(r.identity_layout());
    EXPECT_TRUE(r.warnings.empty());
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, TextRoundTrip,
                         ::testing::Values(MeshFileFormat::obj, MeshFileFormat::off, MeshFileFormat::ply));

TEST(MeshIo, GlbRoundTripIsFloat32WithNormalsAndBounds) {
  const TriMesh m = awkward_tetra();
  const std::string bytes = write_mesh_bytes(MeshFileFormat::glb, m.V, m.F);
  ASSERT_GE(bytes.size(), 12u);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");

  const LoadedMesh r = read_mesh_bytes(bytes, "t.glb");
  ASSERT_EQ(r.mesh.num_vertices(), 4);
  EXPECT_EQ(r.mesh.V, m.V.cast<float>().cast<double>().eval());
  EXPECT_EQ(r.mesh.F, m.F);
  EXPECT_TRUE(r.identity_layout());

  // The layout service frames rely on: POSITION (min/max), NORMAL, uint32 indices, one buffer.
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromMemory(&model, &err, &warn,
                                          reinterpret_cast<const unsigned char*>(bytes.data()),
                                          static_cast<unsigned int>(bytes.size())))
      << err;
  ASSERT_EQ(model.buffers.size(), 1u);
  ASSERT_EQ(model.meshes.size(), 1u);
  const auto& prim = model.meshes[0].primitives.at(0);
  const auto& pos = model.accessors.at(static_cast<size_t>(prim.attributes.at("POSITION")));
  const auto& nrm = model.accessors.at(static_cast<size_t>(prim.attributes.at("NORMAL")));
  const auto& ind = model.accessors.at(static_cast<size_t>(prim.indices));
  EXPECT_EQ(pos.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  EXPECT_EQ(nrm.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  EXPECT_EQ(ind.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
  EXPECT_EQ(ind.count, 12u);
  ASSERT_EQ(pos.minValues.size(), 3u);
  ASSERT_EQ(pos.maxValues.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(pos.minValues[static_cast<size_t>(k)], static_cast<double>(static_cast<float>(m.V.col(k).minCoeff())));
    EXPECT_EQ(pos.maxValues[static_cast<size_t>(k)], static_cast<double>(static_cast<float>(m.V.col(k).maxCoeff())));
  }
  // Normals written are the area-weighted ones.
  const auto& bv = model.bufferViews.at(static_cast<size_t>(nrm.bufferView));
  const float* nf = reinterpret_cast<const float*>(model.buffers[0].data.data() + bv.byteOffset + nrm.byteOffset);
  const Vertices N = vertex_normals(m.V, m.F);
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(nf[3 * i + k], static_cast<float>(N(i, k)));
}

TEST(MeshIo, WriteAndReadFiles) {
  const TriMesh m = awkward_tetra();
  const auto dir = std::filesystem::temp_directory_path() / ("hdeform_io_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const char* ext : {"obj", "off", "ply", "glb", "OFF"}) {
    const std::string path = (dir / (std::string("tetra.") + ext)).string();
    write_mesh(path, m.V, m.F);
    const LoadedMesh r = read_mesh(path);
    EXPECT_EQ(r.mesh.F, m.F) << ext;
    if (std::string(ext) == "glb")
      EXPECT_EQ(r.mesh.V, m.V.cast<float>().cast<double>().eval());
    else
      expect_bitwise_equal(r.mesh.V, m.V);
    // In-memory read of the same bytes gives the same mesh.
    const LoadedMesh b = read_mesh_bytes(read_all(path), path);
    EXPECT_EQ(b.mesh.V, r.mesh.V);
    EXPECT_EQ(b.mesh.F, r.mesh.F);
  }
  EXPECT_NE(error_of([&] { write_mesh((dir / "x.stl").string(), m.V, m.F); }).find("x.stl"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(MeshIo, FormatFromPath) {
  EXPECT_EQ(format_from_path("a/b.GLB"), MeshFileFormat::glb);
  EXPECT_EQ(format_from_path("b.obj"), MeshFileFormat::obj);
  EXPECT_EQ(format_from_path("b.Off"), MeshFileFormat::off);
  EXPECT_EQ(format_from_path("b.ply"), MeshFileFormat::ply);
  EXPECT_THROW(format_from_path("b.gltf"), InvalidInput);
  EXPECT_THROW(format_from_path("noext"), InvalidInput);
}

TEST(MeshIo, ReadsEveryDataMesh) {
  // Counts from the files' own headers / data/README.md; horse.obj counted with grep.
  const std::map<std::string, std::pair<int, int>> expected = {
      {"botsch-sorkine/bar.off", {6084, 12106}},   {"botsch-sorkine/cactus.off", {5261, 10518}},
      {"botsch-sorkine/cylinder.off", {4802, 9600}}, {"botsch-sorkine/plane.off", {40401, 80000}},
      {"models/bunny.off", {3485, 6966}},          {"models/cow.off", {2762, 5520}},
      {"models/hand.off", {14347, 28690}},         {"models/horse.obj", {9926, 19848}},
      {"models/knight.off", {502, 1000}},
  };
  size_t seen = 0;
  for (const auto& dir : {"botsch-sorkine", "models"})
    for (const auto& entry : std::filesystem::directory_iterator(kData + "/" + dir)) {
      const std::string ext = entry.path().extension().string();
      if (ext == ".sel" || ext == ".def" || ext == ".md") continue;
      const std::string rel = std::string(dir) + "/" + entry.path().filename().string();
      SCOPED_TRACE(rel);
      auto it = expected.find(rel);
      ASSERT_NE(it, expected.end()) << "new mesh in data/: add its counts to this test";
      const LoadedMesh r = read_mesh(entry.path().string());
      EXPECT_EQ(r.mesh.num_vertices(), it->second.first);
      EXPECT_EQ(r.mesh.num_triangles(), it->second.second);
      EXPECT_TRUE(r.identity_layout());
      EXPECT_EQ(r.input_triangles, r.mesh.F);
      EXPECT_TRUE(r.warnings.empty());
      // data/README.md: all 2-manifold, no unreferenced vertices.
      const ValidationResult v = validate_mesh(r.mesh);
      EXPECT_TRUE(v.unreferenced.empty());
      ++seen;
    }
  EXPECT_EQ(seen, expected.size());
}

TEST(MeshIo, CactusFirstAndLastValues) {
  const LoadedMesh r = read_mesh(kData + "/botsch-sorkine/cactus.off");
  ASSERT_EQ(r.mesh.num_vertices(), 5261);
  ASSERT_EQ(r.mesh.num_triangles(), 10518);
  // Compare against the text of the file itself (first vertex line, last face line).
  const std::string text = read_all(kData + "/botsch-sorkine/cactus.off");
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);  // OFF
  std::getline(in, line);  // counts
  double x, y, z;
  in >> x >> y >> z;
  EXPECT_EQ(r.mesh.V(0, 0), x);
  EXPECT_EQ(r.mesh.V(0, 1), y);
  EXPECT_EQ(r.mesh.V(0, 2), z);
  const size_t last = text.find_last_of('\n', text.size() - 2);
  std::istringstream tail(text.substr(last + 1));
  int k, a, b, c;
  tail >> k >> a >> b >> c;
  EXPECT_EQ(k, 3);
  EXPECT_EQ(r.mesh.F(10517, 0), a);
  EXPECT_EQ(r.mesh.F(10517, 1), b);
  EXPECT_EQ(r.mesh.F(10517, 2), c);
}

TEST(MeshIo, InMemoryReadEqualsFileRead) {
  for (const char* f : {"/botsch-sorkine/cactus.off", "/models/horse.obj"}) {
    const std::string path = kData + f;
    const LoadedMesh a = read_mesh(path);
    const LoadedMesh b = read_mesh_bytes(read_all(path), std::filesystem::path(path).filename().string());
    EXPECT_EQ(a.mesh.V, b.mesh.V) << f;
    EXPECT_EQ(a.mesh.F, b.mesh.F) << f;
    EXPECT_EQ(a.input_to_engine, b.input_to_engine) << f;
  }
}

// A unit square (4 positions) as two triangles that each carry their own 3 vertices with
// different UVs: 6 glTF vertices, a seam along the diagonal and at every shared corner.
tinygltf::Model seam_model() {
  const float pos[6][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0},   // triangle 0
                           {0, 0, 0}, {1, 1, 0}, {0, 1, 0}};  // triangle 1
  const float uv[6][2] = {{0, 0}, {1, 0}, {1, 1}, {0.5f, 0}, {1, 0.5f}, {0, 1}};
  const uint16_t idx[6] = {0, 1, 2, 3, 4, 5};
  tinygltf::Model model;
  model.asset.version = "2.0";
  tinygltf::Buffer buf;
  buf.data.resize(sizeof pos + sizeof uv + sizeof idx);
  std::memcpy(buf.data.data(), pos, sizeof pos);
  std::memcpy(buf.data.data() + sizeof pos, uv, sizeof uv);
  std::memcpy(buf.data.data() + sizeof pos + sizeof uv, idx, sizeof idx);
  model.buffers.push_back(buf);
  auto view = [&](size_t off, size_t len) {
    tinygltf::BufferView bv;
    bv.buffer = 0;
    bv.byteOffset = off;
    bv.byteLength = len;
    model.bufferViews.push_back(bv);
  };
  view(0, sizeof pos);
  view(sizeof pos, sizeof uv);
  view(sizeof pos + sizeof uv, sizeof idx);
  // Accessor k reads buffer view k: 6 elements each.
  auto accessor = [&](int component_type, int type) -> tinygltf::Accessor& {
    tinygltf::Accessor a;
    a.bufferView = static_cast<int>(model.accessors.size());
    a.componentType = component_type;
    a.type = type;
    a.count = 6;
    model.accessors.push_back(a);
    return model.accessors.back();
  };
  tinygltf::Accessor& positions = accessor(TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3);
  positions.minValues = {0, 0, 0};
  positions.maxValues = {1, 1, 0};
  accessor(TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2);
  accessor(TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR);
  tinygltf::Primitive p;
  p.attributes["POSITION"] = 0;
  p.attributes["TEXCOORD_0"] = 1;
  p.indices = 2;
  p.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh mesh;
  mesh.primitives.push_back(p);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  return model;
}

std::string serialise(const tinygltf::Model& model, bool binary) {
  tinygltf::TinyGLTF w;
  std::ostringstream os;
  EXPECT_TRUE(w.WriteGltfSceneToStream(&model, os, false, binary));
  return os.str();
}

TEST(MeshIo, GltfUvSeamWeldsAndMapsBack) {
  for (bool binary : {true, false}) {
    SCOPED_TRACE(binary ? "glb" : "gltf");
    const std::string bytes = serialise(seam_model(), binary);
    const LoadedMesh r = read_mesh_bytes(bytes, binary ? "seam.glb" : "seam.gltf");
    ASSERT_EQ(r.mesh.num_vertices(), 4);  // 6 glTF vertices, 4 positions
    ASSERT_EQ(r.mesh.num_triangles(), 2);
    EXPECT_FALSE(r.identity_layout());
    EXPECT_EQ(r.input_to_engine, (std::vector<int>{0, 1, 2, 0, 2, 3}));
    Triangles in_tris(2, 3), eng_tris(2, 3);
    in_tris << 0, 1, 2, 3, 4, 5;
    eng_tris << 0, 1, 2, 0, 2, 3;
    EXPECT_EQ(r.input_triangles, in_tris);
    EXPECT_EQ(r.mesh.F, eng_tris);
    ASSERT_FALSE(r.warnings.empty());
    EXPECT_NE(r.warnings.back().find("welded 6"), std::string::npos) << r.warnings.back();
    // The welded mesh is one valid surface (the unwelded one would be two triangles).
    EXPECT_NO_THROW(validate_mesh(r.mesh));

    // Deformed engine positions go back into the 6-vertex input layout.
    Vertices moved = r.mesh.V;
    moved.col(2).setConstant(0);
    moved(2, 2) = 5;  // engine vertex 2 = position (1,1,0) = input vertices 2 and 4
    const Vertices back = r.to_input_layout(moved);
    ASSERT_EQ(back.rows(), 6);
    for (int v = 0; v < 6; ++v) EXPECT_EQ(back(v, 2), (v == 2 || v == 4) ? 5.0 : 0.0) << v;
    EXPECT_EQ(back.row(5), r.mesh.V.row(3));
  }
}

TEST(MeshIo, GltfNodeTransformIsIgnoredWithWarning) {
  tinygltf::Model model = seam_model();
  model.nodes[0].translation = {10, 0, 0};
  const LoadedMesh r = read_mesh_bytes(serialise(model, true), "moved.glb");
  EXPECT_EQ(r.mesh.V.col(0).maxCoeff(), 1.0);  // mesh-local coordinates
  bool warned = false;
  for (const auto& w : r.warnings) warned |= w.find("node transforms are ignored") != std::string::npos;
  EXPECT_TRUE(warned);
}

// Issue 35.11: an input whose scene has no nodes (or whose node or material has no
// properties) uploads; its rewritten GLB must hold `{}` there, not tinygltf's `null`, so
// that it reads again (the Khronos validator checks the same file in glb_compression.mjs).
TEST(MeshIo, RewrittenGltfKeepsEmptyObjects) {
  // Written by hand: tinygltf itself would write those objects as null.
  auto doc_in = nlohmann::json::parse(serialise(seam_model(), false));
  doc_in["scenes"] = nlohmann::json::array({nlohmann::json::object()});  // no nodes
  doc_in["nodes"].push_back(nlohmann::json::object());                   // an empty node
  doc_in["materials"] = nlohmann::json::array({nlohmann::json::object()});  // all defaults
  const std::string input = doc_in.dump();
  const LoadedMesh r = read_mesh_bytes(input, "nodeless.gltf");
  const Vertices positions = r.to_input_layout(r.mesh.V);
  const std::string glb = rewrite_gltf(input, "nodeless.gltf", positions, positions);
  std::uint32_t json_length = 0;
  std::memcpy(&json_length, glb.data() + 12, 4);
  const auto doc = nlohmann::json::parse(glb.substr(20, json_length));
  for (const char* key : {"scenes", "nodes", "materials"}) {
    ASSERT_TRUE(doc.contains(key)) << key;
    for (const auto& element : doc[key]) EXPECT_TRUE(element.is_object()) << key << ": " << element;
  }
  EXPECT_EQ(doc["scenes"][0], nlohmann::json::object());
  // It uploads again, with the same vertices.
  const LoadedMesh again = read_mesh_bytes(glb, "nodeless-deformed.glb");
  EXPECT_EQ(again.mesh.V, r.mesh.V);
}

TEST(MeshIo, GltfUploadMayNotReadExternalFiles) {
  const std::string gltf = R"({"asset":{"version":"2.0"},
    "buffers":[{"uri":"/etc/hostname","byteLength":12}],
    "bufferViews":[{"buffer":0,"byteLength":12}],
    "accessors":[{"bufferView":0,"componentType":5126,"count":1,"type":"VEC3"}],
    "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]})";
  const std::string msg = error_of([&] { read_mesh_bytes(gltf, "upload.gltf"); });
  EXPECT_NE(msg.find("upload.gltf"), std::string::npos) << msg;
  EXPECT_NE(msg.find("invalid glTF"), std::string::npos) << msg;
}

TEST(MeshIo, GltfIndexOutOfRangeNamesPrimitive) {
  tinygltf::Model model = seam_model();
  uint16_t bad = 9;
  std::memcpy(model.buffers[0].data.data() + 6 * 12 + 6 * 8 + 2, &bad, 2);
  const std::string msg = error_of([&] { read_mesh_bytes(serialise(model, true), "bad.glb"); });
  EXPECT_NE(msg.find("bad.glb: mesh 0 primitive 0: index 9 out of range"), std::string::npos) << msg;
}

TEST(MeshIo, QuadsAreFanTriangulatedWithWarning) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 2 0\nf 1 2 3 4\nf 4/1/1 3/2/2 5/3/3\n";
  const LoadedMesh r = read_mesh_bytes(obj, "quad.obj");
  Triangles expected(3, 3);
  expected << 0, 1, 2, 0, 2, 3, 3, 2, 4;
  EXPECT_EQ(r.mesh.F, expected);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("1 polygon"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[0].find("triangulated"), std::string::npos) << r.warnings[0];

  const std::string off = "OFF\n# a pentagon\n5 1 0\n0 0 0\n1 0 0\n2 1 0\n1 2 0\n0 1 0\n5 0 1 2 3 4 255 0 0\n";
  const LoadedMesh o = read_mesh_bytes(off, "penta.off");
  Triangles fan(3, 3);
  fan << 0, 1, 2, 0, 2, 3, 0, 3, 4;
  EXPECT_EQ(o.mesh.F, fan);
  EXPECT_EQ(o.warnings.size(), 1u);
}

TEST(MeshIo, ObjNegativeIndicesAndComments) {
  const std::string obj = "# c\no thing\nv 0 0 0 # origin\nv 1 0 0\nvt 0 0\nvn 0 0 1\nv 0 1 0\ns off\nf -3 -2 -1\n";
  const LoadedMesh r = read_mesh_bytes(obj, "neg.obj");
  ASSERT_EQ(r.mesh.num_triangles(), 1);
  EXPECT_EQ(r.mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
}

TEST(MeshIo, NonManifoldFacesAreKeptForValidation) {
  // Three triangles on edge 0–1: a halfedge structure would drop one; the reader keeps all.
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n";
  const LoadedMesh r = read_mesh_bytes(obj, "fin.obj");
  EXPECT_EQ(r.mesh.num_triangles(), 3);
  EXPECT_THROW(validate_mesh(r.mesh), InvalidInput);
}

TEST(MeshIo, StlMergesCorners) {
  // Binary STL: two triangles of a square sharing the diagonal.
  std::string stl(80, ' ');
  auto put = [&](const void* p, size_t n) { stl.append(static_cast<const char*>(p), n); };
  uint32_t count = 2;
  put(&count, 4);
  const float tris[2][4][3] = {{{0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}},
                               {{0, 0, 1}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
  for (const auto& t : tris) {
    put(t, sizeof t);
    uint16_t attr = 0;
    put(&attr, 2);
  }
  const LoadedMesh b = read_mesh_bytes(stl, "square.stl");
  EXPECT_EQ(b.mesh.num_vertices(), 4);
  EXPECT_EQ(b.mesh.num_triangles(), 2);
  EXPECT_NO_THROW(validate_mesh(b.mesh));

  const std::string ascii =
      "solid sq\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n"
      "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid sq\n";
  const LoadedMesh a = read_mesh_bytes(ascii, "square.STL");
  EXPECT_EQ(a.mesh.num_vertices(), 4);
  EXPECT_EQ(a.mesh.num_triangles(), 2);
}

TEST(MeshIo, BinaryPly) {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\ncomment x\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
      "property list uchar uint vertex_indices\nend_header\n";
  const float v[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (const auto& p : v) {
    ply.append(reinterpret_cast<const char*>(p), 12);
    ply.push_back('\x07');
  }
  ply.push_back('\x03');
  const uint32_t f[3] = {0, 1, 2};
  ply.append(reinterpret_cast<const char*>(f), 12);
  const LoadedMesh r = read_mesh_bytes(ply, "b.ply");
  ASSERT_EQ(r.mesh.num_vertices(), 3);
  EXPECT_EQ(r.mesh.V(1, 0), 1.0);
  EXPECT_EQ(r.mesh.V(2, 1), 1.0);
  EXPECT_EQ(r.mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
  // Truncated binary data.
  const std::string msg = error_of([&] { read_mesh_bytes(ply.substr(0, ply.size() - 4), "b.ply"); });
  EXPECT_NE(msg.find("b.ply: unexpected end of binary data in face element 0"), std::string::npos) << msg;
}

TEST(MeshIo, ErrorsNameFileAndLine) {
  auto msg = [](std::string_view bytes, const std::string& name) {
    return error_of([&] { read_mesh_bytes(bytes, name); });
  };
  EXPECT_EQ(msg("OFF\n4 1 0\n0 0 0\n1 0 0\n0 1\n0 0 1\n3 0 1 2\n", "cube.off"),
            "cube.off:5: expected 3 coordinates, found 2");
  EXPECT_EQ(msg("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "t.off"),
            "t.off:6: vertex index 7 out of range (file has 3 vertices)");
  EXPECT_EQ(msg("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "short.off"),
            "short.off:6: unexpected end of file: expected 2 faces, found 1");
  EXPECT_EQ(msg("OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", "x.off"), "x.off:4: bad coordinate 'x'");
  EXPECT_EQ(msg("PLOT\n", "y.off"), "y.off:1: not an OFF file (header 'PLOT')");
  EXPECT_EQ(msg("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "two.obj"), "two.obj:4: face with 2 vertices (need at least 3)");
  EXPECT_EQ(msg("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "far.obj"), "far.obj:4: vertex index 4 out of range (file has 3 vertices)");
  EXPECT_EQ(msg("v 0 0 0\nf 0 1 2\n", "zero.obj"), "zero.obj:2: vertex index 0 (OBJ indices start at 1)");
  EXPECT_EQ(msg("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header\n0 0 zz\n",
                "a.ply"),
            "a.ply:8: bad number 'zz' for z");
  EXPECT_EQ(msg("", "empty.obj"), "empty.obj: empty file");
  EXPECT_NE(msg("solid", "m.dae").find("m.dae: unknown mesh format '.dae'"), std::string::npos);
  EXPECT_NE(msg("not json", "j.gltf").find("j.gltf: invalid glTF"), std::string::npos);
  EXPECT_NE(msg("nope", "j.glb").find("j.glb: invalid GLB"), std::string::npos);
  // A GLB on which tinygltf itself throws (std::out_of_range), found by fuzz_glb.
  const std::string thrown =
      read_all(kData + "/../tests/fuzz/corpus/fuzz_glb/regress-parser-throws.glb");
  ASSERT_FALSE(thrown.empty());
  EXPECT_NE(msg(thrown, "f.glb").find("f.glb: invalid GLB: the file is malformed"),
            std::string::npos)
      << msg(thrown, "f.glb");

  const std::string missing = error_of([] { read_mesh("/nonexistent/dir/cube.off"); });
  EXPECT_NE(missing.find("/nonexistent/dir/cube.off: cannot open file"), std::string::npos) << missing;
  const auto dir_path = std::filesystem::temp_directory_path() / ("hdeform_dir_" + std::to_string(::getpid()) + ".off");
  std::filesystem::create_directories(dir_path);
  const std::string dir = error_of([&] { read_mesh(dir_path.string()); });
  std::filesystem::remove(dir_path);
  EXPECT_NE(dir.find("is a directory"), std::string::npos) << dir;
  const std::string ext = error_of([] { read_mesh(kData + "/README.md"); });
  EXPECT_NE(ext.find("unknown mesh format '.md'"), std::string::npos) << ext;
}

TEST(MeshIo, VertexNormalsAreAreaWeightedUnitVectors) {
  // Vertex 0 is shared by a big triangle in the z = 0 plane and a small one in the x = 0 plane.
  Vertices V(5, 3);
  V << 0, 0, 0, 10, 0, 0, 0, 10, 0, 0, 0, 1, 0, -1, 0;
  Triangles F(2, 3);
  F << 0, 1, 2,  // area 50, normal +z
      0, 3, 4;   // area 0.5, normal (0,0,1)×(0,-1,0) = +x
  const Vertices N = vertex_normals(V, F);
  const Eigen::RowVector3d expected = Eigen::RowVector3d(0.5, 0, 50).normalized();
  EXPECT_NEAR((N.row(0) - expected).norm(), 0, 1e-15);
  EXPECT_NEAR((N.row(1) - Eigen::RowVector3d(0, 0, 1)).norm(), 0, 1e-15);
  EXPECT_NEAR((N.row(3) - Eigen::RowVector3d(1, 0, 0)).norm(), 0, 1e-15);

  Vertices V2(4, 3);
  V2 << 0, 0, 0, 1, 0, 0, 0, 1, 0, 7, 7, 7;  // vertex 3 unused
  Triangles F2(1, 3);
  F2 << 0, 1, 2;
  EXPECT_EQ(vertex_normals(V2, F2).row(3), Eigen::RowVector3d::Zero());
}


// ---------------------------------------------------------------------------------------
// Issue 8: bounded work and memory, limits while parsing, messages that name the format.

std::string msg_of(std::string_view bytes, const std::string& name, const ReadLimits& limits = {}) {
  return error_of([&] { read_mesh_bytes(bytes, name, limits); });
}

template <class T>
void put_be(std::string& out, T v) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (std::endian::native == std::endian::little) std::reverse(b, b + sizeof(T));
  out.append(reinterpret_cast<const char*>(b), sizeof(T));
}
template <class T>
void put_le(std::string& out, T v) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (std::endian::native == std::endian::big) std::reverse(b, b + sizeof(T));
  out.append(reinterpret_cast<const char*>(b), sizeof(T));
}

// Seconds a call takes (the reader must return or throw quickly).
double seconds_of(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    f();
  } catch (const std::exception&) {
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

const char* kTetraPlyHead =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\n";

std::string triangle_ply_data() {
  std::string d;
  for (float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put_le(d, x);
  d.push_back('\x03');
  for (int32_t i : {0, 1, 2}) put_le(d, i);
  return d;
}

TEST(MeshIoBounds, PlyElementWithoutPropertiesAndHugeCountIsSkipped) {
  // Issue 8: 0 bytes per row and 4·10⁹ rows looped for ~forever on a worker.
  for (const char* where : {"before", "after"}) {
    SCOPED_TRACE(where);
    std::string ply = kTetraPlyHead;
    const std::string junk = "element junk 4000000000\n";
    if (std::string(where) == "before") ply += junk;
    ply += "element face 1\nproperty list uchar int vertex_indices\n";
    if (std::string(where) == "after") ply += junk;
    ply += "end_header\n" + triangle_ply_data();
    LoadedMesh r;
    EXPECT_LT(seconds_of([&] { r = read_mesh_bytes(ply, "junk.ply"); }), 1.0);
    EXPECT_EQ(r.mesh.num_vertices(), 3);
    EXPECT_EQ(r.mesh.num_triangles(), 1);
  }
  // ASCII too: no line is consumed for a row without properties.
  const std::string ascii =
      "ply\nformat ascii 1.0\nelement junk 4000000000\nelement vertex 3\nproperty double x\n"
      "property double y\nproperty double z\nelement face 1\nproperty list uchar int vertex_indices\n"
      "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  LoadedMesh a;
  EXPECT_LT(seconds_of([&] { a = read_mesh_bytes(ascii, "junk.ply"); }), 1.0);
  EXPECT_EQ(a.mesh.num_triangles(), 1);
}

TEST(MeshIoBounds, PlyCountsAreCheckedAgainstTheBytesBeforeAnyAllocation) {
  // 700 million vertices of 12 bytes declared, 40 bytes present: no 16 GB reserve.
  std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex 700000000\nproperty float x\n"
                    "property float y\nproperty float z\nend_header\n";
  ply += std::string(40, '\0');
  EXPECT_EQ(msg_of(ply, "big.ply"),
            "big.ply:3: binary PLY truncated: header declares 700000000 vertex elements of at least "
            "12 bytes but 40 bytes follow the header");
  // The face element's rows come after the vertices'.
  std::string two = std::string(kTetraPlyHead) + "element face 100\nproperty list uchar int vertex_indices\nend_header\n" +
                    triangle_ply_data();
  EXPECT_EQ(msg_of(two, "f.ply"),
            "f.ply:7: binary PLY truncated: header declares 100 face elements of at least 1 byte "
            "after 36 bytes of earlier elements but 49 bytes follow the header");
  // A list length beyond the bytes left.
  std::string list = std::string(kTetraPlyHead) + "element face 1\nproperty list uint int vertex_indices\nend_header\n";
  for (float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put_le(list, x);
  put_le<uint32_t>(list, 0xFFFFFFFFu);
  EXPECT_EQ(msg_of(list, "l.ply"), "l.ply: unexpected end of binary data in face element 0 of 1");
  // A second vertex element.
  EXPECT_EQ(msg_of(std::string(kTetraPlyHead) + "element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n", "v.ply"),
            "v.ply:7: second vertex element (a PLY file has one)");
  // ASCII: a huge count reserves only what the bytes can hold and fails where the data ends.
  const std::string ascii = "ply\nformat ascii 1.0\nelement vertex 700000000\nproperty float x\n"
                            "property float y\nproperty float z\nend_header\n0 0 0\n";
  std::string m;
  EXPECT_LT(seconds_of([&] { m = msg_of(ascii, "a.ply"); }), 1.0);
  EXPECT_EQ(m, "a.ply:8: unexpected end of file: expected 700000000 vertex elements, found 1");
}

TEST(MeshIoBounds, PlyIndexThatIsNotAnIntegerIsNamedWithoutOverflow) {
  std::string ply = std::string(kTetraPlyHead) + "element face 1\nproperty list uchar double vertex_indices\nend_header\n";
  for (float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put_le(ply, x);
  ply.push_back('\x03');
  for (double v : {0.0, 1.0, 1e300}) put_le(ply, v);
  EXPECT_EQ(msg_of(ply, "d.ply"), "d.ply: face 0: vertex index 1e+300 out of range (file has 3 vertices)");
}

TEST(MeshIoBounds, OffHugeCountsReserveNothingAndFailAtTheEnd) {
  std::string m;
  EXPECT_LT(seconds_of([&] { m = msg_of("OFF\n700000000 700000000 0\n0 0 0\n", "big.off"); }), 1.0);
  EXPECT_EQ(m, "big.off:3: unexpected end of file: expected 700000000 vertices, found 1");
  EXPECT_EQ(msg_of("OFF\n2000000000 1 0\n0 0 0\n", "int.off"),
            "int.off: 2000000000 vertices: at most 715827882 are supported");
}

// Geomview binary OFF: big-endian int32 counts, float32 coordinates, faces k i… c colour….
std::string binary_off(const std::string& head, int extra_floats_per_vertex, int colour) {
  std::string off = head + "\n";
  put_be<int32_t>(off, 4);
  put_be<int32_t>(off, 4);
  put_be<int32_t>(off, 6);
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1.5f}};
  for (const auto& p : v) {
    for (float x : p) put_be(off, x);
    for (int k = 0; k < extra_floats_per_vertex; ++k) put_be(off, 0.5f);
  }
  const int32_t f[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  for (const auto& t : f) {
    put_be<int32_t>(off, 3);
    for (int32_t i : t) put_be(off, i);
    put_be<int32_t>(off, colour);
    for (int k = 0; k < colour; ++k) put_be(off, 1.0f);
  }
  return off;
}

TEST(MeshIoBounds, BinaryOffIsRead) {
  struct Case {
    const char* head;
    int extra, colour;
  };
  for (const Case& c : {Case{"OFF BINARY", 0, 0}, Case{"OFF BINARY # comment", 0, 3},
                        Case{"NOFF BINARY", 3, 4}, Case{"CNOFF BINARY", 7, 1}, Case{"STCOFF BINARY", 6, 0}}) {
    SCOPED_TRACE(c.head);
    const LoadedMesh r = read_mesh_bytes(binary_off(c.head, c.extra, c.colour), "b.off");
    ASSERT_EQ(r.mesh.num_vertices(), 4);
    ASSERT_EQ(r.mesh.num_triangles(), 4);
    EXPECT_EQ(r.mesh.V(3, 2), 1.5);
    EXPECT_EQ(r.mesh.V(1, 0), 1.0);
    EXPECT_EQ(r.mesh.F.row(2), Eigen::RowVector3i(1, 2, 3));
    EXPECT_NO_THROW(validate_mesh(r.mesh));
  }
}

TEST(MeshIoBounds, BinaryOffErrorsNameTheFaceAndByte) {
  const std::string good = binary_off("OFF BINARY", 0, 0);
  EXPECT_EQ(msg_of(good.substr(0, 40), "t.off"),
            "t.off: binary OFF truncated: header declares 4 vertices (48 bytes) and 4 faces (at least "
            "80 bytes) but 17 bytes follow the counts");
  EXPECT_EQ(msg_of(std::string("OFF BINARY\n\0\0", 13), "t.off"),
            "t.off: binary OFF truncated: 2 bytes after the header line, need 12 for the vertex, face and edge counts");
  std::string bad = good;
  bad[11 + 12 + 48 + 8 + 3] = 9;  // face 0, second index
  EXPECT_EQ(msg_of(bad, "i.off"), "i.off: binary OFF face 0 (byte 71): vertex index 9 out of range (file has 4 vertices)");
  std::string colour = good;
  colour[11 + 12 + 48 + 16 + 3] = 7;  // face 0 colour count
  EXPECT_EQ(msg_of(colour, "c.off"), "c.off: binary OFF face 0 (byte 71): colour with 7 components (expected 0 to 4)");
  std::string neg = "OFF BINARY\n";
  put_be<int32_t>(neg, -1);
  put_be<int32_t>(neg, 0);
  put_be<int32_t>(neg, 0);
  EXPECT_EQ(msg_of(neg, "n.off"), "n.off: binary OFF: negative counts (-1 vertices, 0 faces) at byte 11");
}

std::string binary_stl(uint32_t declared, int actual) {
  std::string stl(80, ' ');
  put_le(stl, declared);
  for (int t = 0; t < actual; ++t) {
    for (float x : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, static_cast<float>(t)}) put_le(stl, x);
    stl.append(2, '\0');
  }
  return stl;
}

TEST(MeshIoBounds, TruncatedBinaryStlSaysSo) {
  const std::string stl = binary_stl(1000, 4);
  ASSERT_EQ(stl.size(), 284u);
  EXPECT_EQ(msg_of(stl.substr(0, 300), "x.stl"),
            "x.stl: binary STL truncated: header declares 1000 triangles (50,084 bytes) but the file has 284 bytes");
  // A binary file whose header starts with "solid" (common) is still binary when its size fits.
  std::string solid = binary_stl(2, 2);
  solid.replace(0, 9, "solid bin");
  EXPECT_EQ(read_mesh_bytes(solid, "s.stl").mesh.num_triangles(), 2);
  // ... and truncated when it does not.
  EXPECT_EQ(msg_of(solid.substr(0, 150), "s.stl"),
            "s.stl: binary STL truncated: header declares 2 triangles (184 bytes) but the file has 150 bytes");
  EXPECT_EQ(msg_of("\x01\x02garbage", "g.stl"),
            "g.stl: not an STL file: 9 bytes, too short for a binary STL (84-byte header) and no 'solid' "
            "line for an ASCII STL");
  // Extra bytes after the declared triangles: read, with a warning.
  const LoadedMesh extra = read_mesh_bytes(binary_stl(1, 2), "e.stl");
  EXPECT_EQ(extra.mesh.num_triangles(), 1);
  ASSERT_EQ(extra.warnings.size(), 1u);
  EXPECT_EQ(extra.warnings[0], "e.stl: 50 bytes after the 1 triangle of the binary STL ignored");
  EXPECT_EQ(msg_of(binary_stl(0, 0), "z.stl"), "z.stl: no vertices found in the STL file");
}

TEST(MeshIoBounds, TruncatedAsciiStlIsAnError) {
  const std::string facet =
      "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 1 1 0\n endloop\nendfacet\n";
  const std::string whole = "solid sq\n" + facet + "endsolid sq\n";
  EXPECT_EQ(read_mesh_bytes(whole, "ok.stl").mesh.num_triangles(), 1);
  EXPECT_EQ(read_mesh_bytes("SOLID\n" + facet + "ENDSOLID\nsolid b\n" + facet + "endsolid\n", "two.stl").mesh.num_triangles(), 2);
  EXPECT_EQ(msg_of("solid sq\n" + facet, "noend.stl"),
            "noend.stl:8: ASCII STL truncated: the file ends after facet 1 (expected 'facet' or 'endsolid')");
  EXPECT_EQ(msg_of("solid sq\n" + facet.substr(0, facet.find("endfacet")), "nofacet.stl"),
            "nofacet.stl:7: ASCII STL truncated: the file ends inside facet 1 (expected 'endfacet')");
  EXPECT_EQ(msg_of("solid sq\n" + facet.substr(0, facet.find("  vertex 1 1")), "half.stl"),
            "half.stl:5: ASCII STL truncated: the file ends inside facet 1 (expected 'vertex')");
  EXPECT_EQ(msg_of("solid sq\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n", "two.stl"),
            "two.stl:6: ASCII STL: expected 'vertex', found 'endloop'");
  EXPECT_EQ(msg_of("solid sq\nfacet normal 0 0 1\nouter loop\nvertex 0 x 0\n", "x.stl"),
            "x.stl:4: ASCII STL: bad vertex coordinate 'x'");
  EXPECT_EQ(msg_of("solid sq\n", "empty.stl"),
            "empty.stl:1: ASCII STL truncated: the file ends before the first facet (expected 'facet' or 'endsolid')");
  EXPECT_EQ(msg_of(whole + "junk\n", "junk.stl"),
            "junk.stl:10: ASCII STL: expected 'solid' or the end of the file after 'endsolid', found 'junk'");
  // ASCII coordinates keep double precision.
  const LoadedMesh d = read_mesh_bytes("solid\nfacet normal 0 0 1 outer loop vertex 0.1 0 0 vertex 1 0 0 "
                                       "vertex 0 1 0 endloop endfacet endsolid", "d.stl");
  EXPECT_EQ(d.mesh.V(0, 0), 0.1);
}

TEST(MeshIoBounds, GarbageFilesNameTheFormat) {
  EXPECT_EQ(msg_of(std::string("\x7f""ELF\x02\x01\x01\0\0\0 binary", 17), "x.obj"), "x.obj:1: not an OBJ file: unknown statement '\\x7fELF\\x02\\x01\\x01\\x00\\x00\\x00'");
  EXPECT_EQ(msg_of("# just a comment\nvn 0 0 1\n", "c.obj"), "c.obj: no vertices found in the OBJ file");
  EXPECT_EQ(msg_of("OFF\n0 0 0\n", "e.off"), "e.off: no vertices found in the OFF file");
  EXPECT_EQ(msg_of("\x89PNG\r\n", "p.ply"), "p.ply:1: not a PLY file (missing 'ply' header)");
  EXPECT_EQ(msg_of("\x89PNG\r\n", "p.off"), "p.off:1: not an OFF file (header '\\x89PNG')");
  EXPECT_EQ(msg_of("{\"asset\":{\"version\":\"2.0\"}}", "n.gltf"),
            "n.gltf: no vertices found in the glTF file (no triangle primitive with a POSITION accessor of at least one element)");
}

TEST(MeshIoBounds, GltfAccessorCountCannotOverflowTheBoundsCheck) {
  // stride 12 × (count − 1) wraps to 0 in 64 bits when count = 2^62 + 1.
  const std::string gltf = R"({"asset":{"version":"2.0"},
    "buffers":[{"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAA","byteLength":12}],
    "bufferViews":[{"buffer":0,"byteLength":12}],
    "accessors":[{"bufferView":0,"componentType":5126,"count":4611686018427387905,"type":"VEC3"}],
    "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]})";
  const std::string m = msg_of(gltf, "o.gltf");
  EXPECT_NE(m.find("o.gltf: mesh 0 primitive 0 POSITION: accessor reads past the end of its bufferView"), std::string::npos) << m;
}

TEST(MeshIoBounds, GltfReusedAccessorsCannotMultiplyTheWork) {
  // An index accessor of 30 000 indices (60 KB) used by 200 primitives (a few KB of JSON)
  // would give 2 million triangles from a 70 KB file. The data read is charged per use and
  // capped at twice the file and its buffers.
  tinygltf::Model model = seam_model();
  const size_t idx_at = 6 * 12 + 6 * 8;
  model.buffers[0].data.resize(idx_at + 2 * 30000);
  for (size_t k = 0; k < 30000; ++k) {
    const uint16_t v = static_cast<uint16_t>(k % 6);
    std::memcpy(model.buffers[0].data.data() + idx_at + 2 * k, &v, 2);
  }
  model.bufferViews[2].byteLength = 2 * 30000;
  model.accessors[2].count = 30000;
  EXPECT_EQ(read_mesh_bytes(serialise(model, true), "once.glb").mesh.num_triangles(), 10000);
  const tinygltf::Primitive p = model.meshes[0].primitives[0];
  for (int i = 0; i < 200; ++i) model.meshes[0].primitives.push_back(p);
  const std::string m = msg_of(serialise(model, true), "many.glb");
  EXPECT_NE(m.find("many.glb: mesh 0 primitive 4 indices: accessors read"), std::string::npos) << m;
  EXPECT_NE(m.find("accessors overlap or are reused"), std::string::npos) << m;
}

TEST(MeshIoBounds, GlbBinChunkLongerThanTheFileIsRefused) {
  // Found by fuzz_glb (corpus/fuzz_glb/regress-bin-chunk-overflow.glb): tinygltf 2.7.0 lets
  // the BIN chunk's length reach 8 bytes past the file, and copied a buffer from there.
  std::string glb = serialise(seam_model(), true);
  uint32_t json_len = 0, bin_len = 0;
  std::memcpy(&json_len, glb.data() + 12, 4);
  std::memcpy(&bin_len, glb.data() + 20 + json_len, 4);
  ASSERT_EQ(20 + json_len + 8 + bin_len, glb.size());
  const uint32_t longer = bin_len + 8;
  std::memcpy(glb.data() + 20 + json_len, &longer, 4);
  EXPECT_EQ(msg_of(glb, "b.glb"), "b.glb: invalid GLB: the BIN chunk at byte " + std::to_string(20 + json_len) +
                                      " declares " + std::to_string(longer) + " bytes but " +
                                      std::to_string(bin_len) + " bytes follow its header");
  // The fuzzer's input itself.
  const std::string crash = read_all(kData + "/../tests/fuzz/corpus/fuzz_glb/regress-bin-chunk-overflow.glb");
  ASSERT_FALSE(crash.empty());
  EXPECT_EQ(msg_of(crash, "c.glb"), "c.glb: invalid GLB: the BIN chunk at byte 536 declares 76 bytes but 72 bytes follow its header");
}

TEST(MeshIoLimits, DeclaredCountsFailImmediately) {
  ReadLimits lim;
  lim.max_vertices = 2000000;
  std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex 5000000\nproperty float x\n"
                    "property float y\nproperty float z\nend_header\n";
  EXPECT_THROW(read_mesh_bytes(ply, "big.ply", lim), LimitExceeded);
  EXPECT_EQ(msg_of(ply, "big.ply", lim), "big.ply: 5000000 vertices exceed the server's limit of 2000000 (--max-vertices)");
  EXPECT_EQ(msg_of("OFF\n5000000 1 0\n", "big.off", lim),
            "big.off: 5000000 vertices exceed the server's limit of 2000000 (--max-vertices)");
  std::string boff = "OFF BINARY\n";
  put_be<int32_t>(boff, 5000000);
  put_be<int32_t>(boff, 0);
  put_be<int32_t>(boff, 0);
  EXPECT_EQ(msg_of(boff, "big.off", lim), "big.off: 5000000 vertices exceed the server's limit of 2000000 (--max-vertices)");
  ReadLimits tri;
  tri.max_triangles = 10;
  tri.triangles_option = "";
  EXPECT_EQ(msg_of(binary_stl(1000, 0), "big.stl", tri), "big.stl: 1000 triangles exceed the server's limit of 10");
  EXPECT_EQ(msg_of("OFF\n3 11 0\n", "f.off", tri), "f.off: 11 triangles exceed the server's limit of 10");
  // glTF: the POSITION accessor's count.
  ReadLimits five;
  five.max_vertices = 5;
  EXPECT_EQ(msg_of(serialise(seam_model(), true), "seam.glb", five),
            "seam.glb: 6 vertices exceed the server's limit of 5 (--max-vertices)");
}

TEST(MeshIoLimits, RunningCountsFailAsSoonAsTheyPassTheLimit) {
  ReadLimits lim;
  lim.max_vertices = 3;
  std::string obj;
  for (int i = 0; i < 1000; ++i) obj += "v 0 0 " + std::to_string(i) + "\n";
  EXPECT_EQ(msg_of(obj, "many.obj", lim), "many.obj: more than 3 vertices: the server's limit (--max-vertices)");
  ReadLimits tri;
  tri.max_triangles = 2;
  EXPECT_EQ(msg_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 2 0\nf 1 2 3 4 5\n", "fan.obj", tri),
            "fan.obj: more than 2 triangles: the server's limit (--max-triangles)");
  // ASCII STL vertices are counted after merging.
  const std::string facet =
      "facet normal 0 0 1 outer loop vertex 0 0 0 vertex 1 0 0 vertex 1 1 0 endloop endfacet\n";
  EXPECT_EQ(read_mesh_bytes("solid\n" + facet + facet + "endsolid\n", "m.stl", lim).mesh.num_vertices(), 3);
  // Within the limits: read as usual.
  ReadLimits roomy;
  roomy.max_vertices = 4;
  roomy.max_triangles = 4;
  const auto path = std::filesystem::temp_directory_path() / ("hdeform_limits_" + std::to_string(::getpid()) + ".off");
  {
    std::ofstream(path) << "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 1 2 3\n3 0 3 2\n";
  }
  EXPECT_EQ(read_mesh(path.string(), roomy).mesh.num_triangles(), 4);
  roomy.max_triangles = 3;
  EXPECT_THROW(read_mesh(path.string(), roomy), LimitExceeded);
  std::filesystem::remove(path);
}

TEST(MeshIoLimits, CancellationStopsAReadInProgress) {
  std::string obj;
  for (int i = 0; i < 50000; ++i) obj += "v 0 0 " + std::to_string(i) + "\n";
  std::atomic<bool> stop{true};
  ReadLimits lim;
  lim.cancel = &stop;
  EXPECT_THROW(read_mesh_bytes(obj, "c.obj", lim), ReadCancelled);
  try {
    read_mesh_bytes(obj, "c.obj", lim);
  } catch (const ReadCancelled& e) {
    EXPECT_STREQ(e.what(), "c.obj: reading cancelled");
  }
  // A callback polled every few thousand rows: cancelled on its third poll, long before the end.
  int polls = 0;
  ReadLimits cb;
  cb.should_cancel = [&polls] { return ++polls >= 3; };
  EXPECT_THROW(read_mesh_bytes(obj, "c.obj", cb), ReadCancelled);
  EXPECT_EQ(polls, 3);
  stop = false;
  EXPECT_EQ(read_mesh_bytes(obj + "f 1 2 3\n", "c.obj", lim).mesh.num_vertices(), 50000);
}

TEST(MeshIoBounds, QuotedFileContentIsEscaped) {
  // Bytes of a binary or non-UTF-8 file quoted in a message are escaped, so the message is
  // valid UTF-8 (it ends up in gRPC status messages and proto strings).
  EXPECT_EQ(msg_of("OFF\n3 1 0\n0 0 0\n1 \xff\xfe 0\n0 1 0\n3 0 1 2\n", "u.off"), "u.off:4: bad coordinate '\\xff\\xfe'");
}

TEST(MeshIo, BinaryPlyReadsBackBitIdentical) {
  const TriMesh m = awkward_tetra();
  WriteOptions o;
  o.binary_ply = true;
  for (bool with_normals : {false, true}) {
    const Vertices N = vertex_normals(m.V, m.F);
    const std::string bytes =
        write_mesh_bytes(MeshFileFormat::ply, m.V, m.F, with_normals ? &N : nullptr, o);
    EXPECT_EQ(bytes.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
    const LoadedMesh r = read_mesh_bytes(bytes, "t.ply");
    expect_bitwise_equal(r.mesh.V, m.V);
    EXPECT_EQ(r.mesh.F, m.F);
    EXPECT_TRUE(r.warnings.empty());
  }
}

TEST(MeshIo, ZUpGlbTurnsUprightInAViewerAndKeepsTheModelsCoordinates) {
  const TriMesh m = awkward_tetra();
  WriteOptions o;
  o.up_z = true;
  const std::string bytes = write_mesh_bytes(MeshFileFormat::glb, m.V, m.F, nullptr, o);
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromMemory(&model, &err, &warn,
                                          reinterpret_cast<const unsigned char*>(bytes.data()),
                                          static_cast<unsigned int>(bytes.size())))
      << err;
  // The scene's root turns +z into +y: q = (x, y, z, w) for −90° about x.
  ASSERT_EQ(model.scenes.at(0).nodes.size(), 1u);
  const auto& root = model.nodes.at(static_cast<size_t>(model.scenes[0].nodes[0]));
  ASSERT_EQ(root.rotation.size(), 4u);
  const Eigen::Quaterniond q(root.rotation[3], root.rotation[0], root.rotation[1], root.rotation[2]);
  EXPECT_TRUE((q * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitY(), 1e-15));
  EXPECT_TRUE((q * Eigen::Vector3d::UnitY()).isApprox(-Eigen::Vector3d::UnitZ(), 1e-15));
  ASSERT_EQ(root.children.size(), 1u);
  EXPECT_EQ(model.nodes.at(static_cast<size_t>(root.children[0])).mesh, 0);
  // Read back: the model's own coordinates, ids and triangles (node transforms ignored).
  const LoadedMesh r = read_mesh_bytes(bytes, "t.glb");
  EXPECT_EQ(r.mesh.V, m.V.cast<float>().cast<double>().eval());
  EXPECT_EQ(r.mesh.F, m.F);
  EXPECT_TRUE(r.identity_layout());
}

}  // namespace
}  // namespace hdeform

namespace hdeform {
namespace {

// A quad-dominant mesh (what Blender exports): a cube of quads, one pentagon cap split off a
// side, and a triangle. Read, it is fans of triangles for the solve; written with its
// polygons, every format gives the user's own faces back, in order, and reads back to the
// same triangles.
TEST(MeshIo, PolygonsAreWrittenBackAsTheFacesTheyWere) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 0.5 1.5 0.5\n"
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 4 1 5 8\n"
      "f 3 4 8 9\nf 3 9 8 7\n";  // a quad and a quad around the ninth vertex, then …
  const std::string tri_and_penta = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nv 3 3 3\n"
                                    "f 1 2 3 4 5\nf 3 6 4\n";
  for (const std::string& text : {obj, tri_and_penta}) {
    const LoadedMesh in = read_mesh_bytes(text, "poly.obj");
    ASSERT_FALSE(in.polygons.empty());
    // The faces as the user wrote them (1-based OBJ indices), for comparison.
    std::vector<std::vector<int>> faces;
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("f ", 0) != 0) continue;
      std::istringstream ids(line.substr(2));
      std::vector<int> f;
      for (int id; ids >> id;) f.push_back(id - 1);
      faces.push_back(f);
    }
    WriteOptions options;
    options.polygons = in.polygons;
    for (auto [format, binary, name] :
         {std::tuple{MeshFileFormat::obj, false, "out.obj"}, {MeshFileFormat::off, false, "out.off"},
          {MeshFileFormat::ply, false, "out.ply"}, {MeshFileFormat::ply, true, "out.ply"}}) {
      options.binary_ply = binary;
      const std::string out = write_mesh_bytes(format, in.mesh.V, in.mesh.F, nullptr, options);
      const LoadedMesh back = read_mesh_bytes(out, name);
      EXPECT_EQ(back.mesh.F, in.mesh.F) << name;  // the same fans, the same triangles
      ASSERT_EQ(back.polygons.size(), in.polygons.size()) << name;
      for (std::size_t i = 0; i < in.polygons.size(); ++i) {
        EXPECT_EQ(back.polygons[i].first_triangle, in.polygons[i].first_triangle) << name;
        EXPECT_EQ(back.polygons[i].corners, in.polygons[i].corners) << name;
      }
      if (format == MeshFileFormat::obj) {  // the face lines themselves
        std::istringstream o(out);
        std::size_t f = 0;
        for (std::string line; std::getline(o, line);) {
          if (line.rfind("f ", 0) != 0) continue;
          std::istringstream ids(line.substr(2));
          std::vector<int> got;
          for (int id; ids >> id;) got.push_back(id - 1);
          ASSERT_LT(f, faces.size());
          EXPECT_EQ(got, faces[f]) << "face " << f;
          ++f;
        }
        EXPECT_EQ(f, faces.size());
      }
    }
  }
}

TEST(MeshIo, PolygonsThatDoNotMatchTheTrianglesAreWrittenAsTriangles) {
  const LoadedMesh in = read_mesh_bytes(
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", "quad.obj");
  ASSERT_EQ(in.polygons.size(), 1u);
  Triangles other = in.mesh.F;
  other(1, 0) = 1;  // no longer a fan around corner 0
  WriteOptions options;
  options.polygons = in.polygons;
  const std::string out = write_mesh_bytes(MeshFileFormat::off, in.mesh.V, other, nullptr, options);
  EXPECT_NE(out.find("\n4 2 0\n"), std::string::npos) << out;  // 4 vertices, 2 faces
  EXPECT_EQ(read_mesh_bytes(out, "out.off").mesh.F, other);
  // Out of range, or PLY beyond 255 corners: triangles too.
  std::vector<PolygonFan> far = {{5, 4}};
  options.polygons = far;
  EXPECT_EQ(read_mesh_bytes(write_mesh_bytes(MeshFileFormat::obj, in.mesh.V, in.mesh.F, nullptr,
                                             options), "o.obj").polygons.size(), 0u);
  const int k = 300;
  std::string big;
  for (int i = 0; i < k; ++i) {
    const double a = 2 * 3.14159265358979 * i / k;
    big += "v ";  // appended piecewise: GCC 12's -Wrestrict misfires on "v " + string
    big += std::to_string(std::cos(a));
    big += ' ';
    big += std::to_string(std::sin(a));
    big += " 0\n";
  }
  big += "f";
  for (int i = 1; i <= k; ++i) {
    big += ' ';
    big += std::to_string(i);
  }
  big += "\n";
  const LoadedMesh disc = read_mesh_bytes(big, "disc.obj");
  options.polygons = disc.polygons;
  options.binary_ply = true;
  const LoadedMesh ply = read_mesh_bytes(
      write_mesh_bytes(MeshFileFormat::ply, disc.mesh.V, disc.mesh.F, nullptr, options), "d.ply");
  EXPECT_EQ(ply.mesh.F, disc.mesh.F);
  EXPECT_TRUE(ply.polygons.empty());  // 298 triangles: a uchar counts at most 255 corners
  const LoadedMesh off = read_mesh_bytes(
      write_mesh_bytes(MeshFileFormat::off, disc.mesh.V, disc.mesh.F, nullptr, options), "d.off");
  ASSERT_EQ(off.polygons.size(), 1u);  // OFF has no such limit
  EXPECT_EQ(off.polygons[0].corners, k);
}

}  // namespace
}  // namespace hdeform

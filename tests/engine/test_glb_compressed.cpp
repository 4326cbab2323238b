// Compressed GLB export (GlbCompression, mesh_io.h): read back here by a small reader of our own
// (nlohmann::json + meshoptimizer's decoders), following the two extensions' specifications,
// and compared with the mesh: positions within the stated grid error, normals within int8's,
// triangles exact; the meshopt file decodes to exactly the quantized file's bytes.
// The Khronos validator checks the same files in tests/browser/glb_compression.mjs.
#include "engine/io/mesh_io.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace hdeform {
namespace {

using json = nlohmann::json;
const std::string kData = HDEFORM_TEST_DATA;

std::uint32_t u32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

struct Glb {
  json doc;
  std::string bin;
};

Glb split(const std::string& b) {
  EXPECT_EQ(b.substr(0, 4), "glTF");
  EXPECT_EQ(u32(b, 4), 2u);
  EXPECT_EQ(u32(b, 8), b.size());
  const std::size_t json_len = u32(b, 12);
  EXPECT_EQ(b.substr(16, 4), "JSON");
  EXPECT_EQ(json_len % 4, 0u);
  Glb g{json::parse(b.substr(20, json_len)), {}};
  const std::size_t at = 20 + json_len;
  EXPECT_EQ(b.substr(at + 4, 4), std::string("BIN\0", 4));
  g.bin = b.substr(at + 8, u32(b, at));
  return g;
}

// A buffer view's bytes as a renderer gets them (decoded when EXT_meshopt_compression).
std::string view_bytes(const Glb& g, int index) {
  const json& v = g.doc.at("bufferViews").at(static_cast<std::size_t>(index));
  if (!v.contains("extensions")) {
    EXPECT_EQ(v.at("buffer"), 0);
    return g.bin.substr(v.at("byteOffset").get<std::size_t>(), v.at("byteLength").get<std::size_t>());
  }
  const json& e = v.at("extensions").at("EXT_meshopt_compression");
  const auto count = e.at("count").get<std::size_t>();
  const auto stride = e.at("byteStride").get<std::size_t>();
  EXPECT_EQ(count * stride, v.at("byteLength").get<std::size_t>());
  const std::string packed =
      g.bin.substr(e.at("byteOffset").get<std::size_t>(), e.at("byteLength").get<std::size_t>());
  const auto* src = reinterpret_cast<const unsigned char*>(packed.data());
  std::string out(count * stride, '\0');
  int rc = -1;
  if (e.at("mode") == "ATTRIBUTES")
    rc = meshopt_decodeVertexBuffer(out.data(), count, stride, src, packed.size());
  else if (e.at("mode") == "TRIANGLES")
    rc = meshopt_decodeIndexBuffer(out.data(), count, stride, src, packed.size());
  EXPECT_EQ(rc, 0) << "meshopt decode of view " << index;
  return out;
}

struct Decoded {
  Vertices V, N;
  Triangles F;
  std::vector<std::string> view_data;
};

Decoded decode(const std::string& bytes) {
  const Glb g = split(bytes);
  Decoded d;
  for (std::size_t i = 0; i < g.doc.at("bufferViews").size(); ++i)
    d.view_data.push_back(view_bytes(g, static_cast<int>(i)));
  const json& prim = g.doc.at("meshes").at(0).at("primitives").at(0);
  const json& pa = g.doc.at("accessors").at(prim.at("attributes").at("POSITION").get<std::size_t>());
  const json& na = g.doc.at("accessors").at(prim.at("attributes").at("NORMAL").get<std::size_t>());
  const json& ia = g.doc.at("accessors").at(prim.at("indices").get<std::size_t>());
  EXPECT_EQ(pa.at("componentType"), 5123);
  EXPECT_EQ(na.at("componentType"), 5120);
  EXPECT_TRUE(na.at("normalized").get<bool>());
  const json& node = g.doc.at("nodes").at(0);
  EXPECT_EQ(node.at("mesh"), 0);
  const auto t = node.at("translation").get<std::vector<double>>();
  const auto s = node.at("scale").get<std::vector<double>>();
  EXPECT_EQ(s[0], s[1]);  // uniform: normals stay right under the node transform
  EXPECT_EQ(s[0], s[2]);
  const auto n = pa.at("count").get<Eigen::Index>();
  const std::string& pv = d.view_data.at(pa.at("bufferView").get<std::size_t>());
  const std::string& nv = d.view_data.at(na.at("bufferView").get<std::size_t>());
  d.V.resize(n, 3);
  d.N.resize(n, 3);
  std::vector<int> qmin(3, 65535), qmax(3, 0);
  for (Eigen::Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      std::uint16_t q;
      std::memcpy(&q, pv.data() + 8 * i + 2 * k, 2);
      qmin[k] = std::min<int>(qmin[k], q);
      qmax[k] = std::max<int>(qmax[k], q);
      // What a renderer computes, in float32.
      d.V(i, k) = static_cast<float>(t[k]) + static_cast<float>(s[k]) * static_cast<float>(q);
      const auto c = static_cast<std::int8_t>(nv[static_cast<std::size_t>(4 * i + k)]);
      d.N(i, k) = std::max(c / 127.0, -1.0);  // glTF's normalized BYTE
    }
  EXPECT_EQ(pa.at("min").get<std::vector<int>>(), qmin);
  EXPECT_EQ(pa.at("max").get<std::vector<int>>(), qmax);
  const auto m3 = ia.at("count").get<Eigen::Index>();
  const std::string& iv = d.view_data.at(ia.at("bufferView").get<std::size_t>());
  const bool narrow = ia.at("componentType") == 5123;
  d.F.resize(m3 / 3, 3);
  for (Eigen::Index j = 0; j < m3; ++j) {
    std::uint32_t v = 0;
    std::memcpy(&v, iv.data() + (narrow ? 2 : 4) * j, narrow ? 2 : 4);
    d.F(j / 3, j % 3) = static_cast<int>(v);
  }
  return d;
}

std::vector<std::string> strings(const json& a) { return a.get<std::vector<std::string>>(); }

// `run` throws InvalidInput whose message contains `needle`.
template <class Run>
void expect_refused(Run run, const std::string& needle, const char* what) {
  try {
    run();
    ADD_FAILURE() << what;
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

// Each triangle rotated to start at its smallest id: meshopt's index codec may start a
// triangle at another corner (same winding, same triangle order), which glTF allows.
Triangles canonical(Triangles F) {
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    Eigen::Index k;
    F.row(t).minCoeff(&k);
    const Eigen::RowVector3i r = F.row(t);
    F.row(t) << r((k + 0) % 3), r((k + 1) % 3), r((k + 2) % 3);
  }
  return F;
}

void expect_matches(const TriMesh& m, const Decoded& d) {
  ASSERT_EQ(d.V.rows(), m.V.rows());
  EXPECT_EQ(canonical(d.F), canonical(m.F));
  const double extent = (m.V.colwise().maxCoeff() - m.V.colwise().minCoeff()).maxCoeff();
  // The stated bound, plus float32 rounding of a coordinate of this size.
  const double bound = extent / 131070 + 4 * std::numeric_limits<float>::epsilon() *
                                             (m.V.cwiseAbs().maxCoeff() + extent);
  EXPECT_LE((d.V - m.V).cwiseAbs().maxCoeff(), bound);
  EXPECT_GT((d.V - m.V).cwiseAbs().maxCoeff(), 0.0);  // it is quantized, not float32
  const Vertices N = vertex_normals(m.V, m.F);
  EXPECT_LE((d.N - N).cwiseAbs().maxCoeff(), 0.5 / 127 + 1e-12);
}

TEST(GlbCompressed, QuantizedCactusReadsBackWithinTheGridError) {
  const LoadedMesh r = read_mesh(kData + "/botsch-sorkine/cactus.off");
  WriteOptions o;
  o.glb_compression = GlbCompression::quantized;
  const std::string bytes = write_mesh_bytes(MeshFileFormat::glb, r.mesh.V, r.mesh.F, nullptr, o);
  const Glb g = split(bytes);
  EXPECT_EQ(strings(g.doc.at("extensionsRequired")), std::vector<std::string>{"KHR_mesh_quantization"});
  EXPECT_EQ(g.doc.at("buffers").size(), 1u);
  const Decoded d = decode(bytes);
  EXPECT_EQ(d.F, r.mesh.F);  // uncompressed: the very corners
  expect_matches(r.mesh, d);
  // 8 + 4 bytes a vertex and 2 an index (5261 vertices fit uint16), 24 and 4 in the plain GLB.
  const std::size_t n = 5261, m = 10518;
  EXPECT_EQ(g.bin.size(), n * 8 + n * 4 + (m * 6 + 2) / 4 * 4);
}

TEST(GlbCompressed, MeshoptDecodesToExactlyTheQuantizedBytes) {
  const LoadedMesh r = read_mesh(kData + "/botsch-sorkine/cactus.off");
  WriteOptions q, c;
  q.glb_compression = GlbCompression::quantized;
  c.glb_compression = GlbCompression::meshopt;
  const std::string quantized = write_mesh_bytes(MeshFileFormat::glb, r.mesh.V, r.mesh.F, nullptr, q);
  const std::string packed = write_mesh_bytes(MeshFileFormat::glb, r.mesh.V, r.mesh.F, nullptr, c);
  const Glb g = split(packed);
  EXPECT_EQ(strings(g.doc.at("extensionsRequired")),
            (std::vector<std::string>{"KHR_mesh_quantization", "EXT_meshopt_compression"}));
  // Buffer 1 is the fallback: a length, no data; every view points into it.
  ASSERT_EQ(g.doc.at("buffers").size(), 2u);
  EXPECT_TRUE(g.doc.at("buffers").at(1).at("extensions").at("EXT_meshopt_compression").at("fallback").get<bool>());
  EXPECT_FALSE(g.doc.at("buffers").at(1).contains("uri"));
  // The vertex streams are compressed; the cactus's indices (no triangle locality) would grow
  // through the codec and stay raw in buffer 0.
  const json& views = g.doc.at("bufferViews");
  for (int i : {0, 1}) {
    EXPECT_EQ(views.at(i).at("buffer"), 1);
    EXPECT_EQ(views.at(i).at("extensions").at("EXT_meshopt_compression").at("mode"), "ATTRIBUTES");
  }
  EXPECT_EQ(views.at(2).at("buffer"), 0);
  EXPECT_FALSE(views.at(2).contains("extensions"));
  const Decoded a = decode(quantized), b = decode(packed);
  EXPECT_EQ(a.view_data.at(0), b.view_data.at(0));  // positions, bit for bit
  EXPECT_EQ(a.view_data.at(1), b.view_data.at(1));  // normals
  EXPECT_EQ(canonical(a.F), canonical(b.F));        // the same triangles, in the same order
  expect_matches(r.mesh, b);
  EXPECT_LT(packed.size(), quantized.size());
}

TEST(GlbCompressed, LargeMeshesUseWideIndicesAndUpZKeepsTheMeshNode) {
  // 70,000 vertices (a strip of triangles): indices must be uint32.
  const int n = 70000;
  Vertices V(n, 3);
  for (int i = 0; i < n; ++i) V.row(i) << i * 1e-3, (i % 2) * 0.5, std::sin(i * 0.01);
  Triangles F(n - 2, 3);
  for (int t = 0; t < n - 2; ++t) {
    if (t % 2 == 0) F.row(t) << t, t + 1, t + 2;
    else F.row(t) << t + 1, t, t + 2;
  }
  WriteOptions o;
  o.glb_compression = GlbCompression::meshopt;
  o.up_z = true;
  const std::string bytes = write_mesh_bytes(MeshFileFormat::glb, V, F, nullptr, o);
  const Glb g = split(bytes);
  EXPECT_EQ(g.doc.at("accessors").at(2).at("componentType"), 5125);
  // A strip has triangle locality: its indices go through the codec too.
  EXPECT_EQ(g.doc.at("bufferViews").at(2).at("extensions").at("EXT_meshopt_compression").at("mode"),
            "TRIANGLES");
  const json& root = g.doc.at("nodes").at(g.doc.at("scenes").at(0).at("nodes").at(0).get<std::size_t>());
  EXPECT_EQ(root.at("name"), "z-up to y-up");
  const auto rot = root.at("rotation").get<std::vector<double>>();
  const Eigen::Quaterniond q(rot[3], rot[0], rot[1], rot[2]);
  EXPECT_TRUE((q * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitY(), 1e-15));
  EXPECT_EQ(root.at("children"), json::array({0}));
  TriMesh m;
  m.V = V;
  m.F = F;
  expect_matches(m, decode(bytes));
}

TEST(GlbCompressed, NonFinitePositionsAreRefusedByName) {
  Vertices V(3, 3);
  V << 0, 0, 0, 1, 0, 0, 0, std::numeric_limits<double>::quiet_NaN(), 0;
  Triangles F(1, 3);
  F << 0, 1, 2;
  WriteOptions o;
  o.glb_compression = GlbCompression::quantized;
  expect_refused([&] { write_mesh_bytes(MeshFileFormat::glb, V, F, nullptr, o); },
                 "vertex 2 has a non-finite coordinate", "a NaN position was quantized");
}

// hdeform reads float32 GLBs only: a compressed one is refused with a message that says why.
TEST(GlbCompressed, ReadingOneBackIsRefusedByName) {
  const LoadedMesh r = read_mesh(kData + "/botsch-sorkine/cactus.off");
  for (GlbCompression c : {GlbCompression::quantized, GlbCompression::meshopt}) {
    WriteOptions o;
    o.glb_compression = c;
    const std::string bytes = write_mesh_bytes(MeshFileFormat::glb, r.mesh.V, r.mesh.F, nullptr, o);
    expect_refused([&] { read_mesh_bytes(bytes, "c.glb"); }, "c.glb: requires the glTF extension ",
                   "a compressed GLB was read");
  }
}

}  // namespace
}  // namespace hdeform

// Compressed GLB: KHR_mesh_quantization, optionally through EXT_meshopt_compression
// (GlbCompression in mesh_io.h says what is stored and its error).
//
// Written with nlohmann::json rather than tinygltf: EXT_meshopt_compression's views point into
// a fallback buffer that has a byteLength and no data, which tinygltf cannot emit (it writes
// every buffer after the first as a data URI of its bytes).

#include "engine/io/mesh_writers.h"

#include "engine/io/mesh_io.h"

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace hdeform::detail {
namespace {

using json = nlohmann::json;

constexpr int kComponentByte = 5120, kComponentUnsignedShort = 5123, kComponentUnsignedInt = 5125;
constexpr int kTargetArrayBuffer = 34962, kTargetElementArrayBuffer = 34963;

// One buffer view's bytes, as a renderer sees them after any decompression.
struct Stream {
  std::string bytes;
  int stride = 0;      // bytes per element: a vertex's attribute, or one index
  std::size_t count = 0;
  bool indices = false;
};

// The positions on a uniform grid over the bounding box (4-byte stride: 3 × uint16 + padding).
struct Grid {
  std::array<double, 3> origin{};  // the box's min corner
  double step = 1;                 // extent / 65535; 1 for a point-sized box
  std::array<int, 3> qmin{}, qmax{};
};

Stream quantize_positions(const Vertices& V, Grid& grid) {
  const Eigen::Index n = V.rows();
  for (Eigen::Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(V(i, k)))
        throw InvalidInput("write_mesh: vertex " + std::to_string(i) +
                           " has a non-finite coordinate; a quantized GLB cannot hold it");
  double extent = 0;
  for (int k = 0; k < 3 && n > 0; ++k) {
    grid.origin[k] = V.col(k).minCoeff();
    extent = std::max(extent, V.col(k).maxCoeff() - grid.origin[k]);
  }
  if (extent > 0) grid.step = extent / 65535.0;
  grid.qmin = {65535, 65535, 65535};
  grid.qmax = {0, 0, 0};
  Stream s{std::string(static_cast<std::size_t>(n) * 8, '\0'), 8, static_cast<std::size_t>(n), false};
  for (Eigen::Index i = 0; i < n; ++i) {
    std::uint16_t q[4] = {0, 0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      const double t = std::round((V(i, k) - grid.origin[k]) / grid.step);
      const int v = static_cast<int>(std::clamp(t, 0.0, 65535.0));
      q[k] = static_cast<std::uint16_t>(v);
      grid.qmin[k] = std::min(grid.qmin[k], v);
      grid.qmax[k] = std::max(grid.qmax[k], v);
    }
    std::memcpy(s.bytes.data() + 8 * i, q, 8);
  }
  return s;
}

Stream quantize_normals(const Vertices& N) {
  const Eigen::Index n = N.rows();
  Stream s{std::string(static_cast<std::size_t>(n) * 4, '\0'), 4, static_cast<std::size_t>(n), false};
  for (Eigen::Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const double c = std::isfinite(N(i, k)) ? std::clamp(N(i, k), -1.0, 1.0) : 0.0;
      s.bytes[static_cast<std::size_t>(4 * i + k)] =
          static_cast<char>(static_cast<std::int8_t>(std::lround(c * 127.0)));
    }
  return s;
}

Stream index_stream(const Triangles& F, Eigen::Index vertices) {
  const bool narrow = vertices <= 65536;
  const std::size_t count = static_cast<std::size_t>(F.rows()) * 3;
  Stream s{std::string(count * (narrow ? 2 : 4), '\0'), narrow ? 2 : 4, count, true};
  for (Eigen::Index t = 0; t < F.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      const std::size_t at = static_cast<std::size_t>(3 * t + k);
      const auto v = static_cast<std::uint32_t>(F(t, k));
      if (narrow) {
        const auto v16 = static_cast<std::uint16_t>(v);
        std::memcpy(s.bytes.data() + 2 * at, &v16, 2);
      } else {
        std::memcpy(s.bytes.data() + 4 * at, &v, 4);
      }
    }
  return s;
}

// meshopt's codecs: vertex streams as "ATTRIBUTES", the index stream as "TRIANGLES" (read
// straight from F: the triangles' ids are non-negative ints, which the codec takes as unsigned).
std::string meshopt_compress(const Stream& s, const Triangles& F, std::size_t vertices) {
  std::string out;
  std::size_t size = 0;
  if (s.indices) {
    out.resize(meshopt_encodeIndexBufferBound(s.count, vertices));
    size = meshopt_encodeIndexBuffer(reinterpret_cast<unsigned char*>(out.data()), out.size(),
                                     reinterpret_cast<const unsigned int*>(F.data()), s.count);
  } else {
    out.resize(meshopt_encodeVertexBufferBound(s.count, static_cast<std::size_t>(s.stride)));
    size = meshopt_encodeVertexBuffer(reinterpret_cast<unsigned char*>(out.data()), out.size(),
                                      s.bytes.data(), s.count, static_cast<std::size_t>(s.stride));
  }
  if (size == 0) throw std::runtime_error("write_mesh: meshoptimizer failed to encode a stream");
  out.resize(size);
  return out;
}

void pad4(std::string& s, char with) { s.resize((s.size() + 3) & ~std::size_t{3}, with); }

void append_u32(std::string& out, std::uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  out.append(b, 4);
}

// The GLB container: 12-byte header, JSON chunk (space-padded), BIN chunk (zero-padded).
std::string glb_container(const json& doc, std::string bin) {
  std::string text = doc.dump();
  pad4(text, ' ');
  pad4(bin, '\0');
  const std::size_t total = 12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size());
  if (total > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error("write_mesh: the GLB would exceed 4 GiB");
  std::string out;
  out.reserve(total);
  out += "glTF";
  append_u32(out, 2);
  append_u32(out, static_cast<std::uint32_t>(total));
  append_u32(out, static_cast<std::uint32_t>(text.size()));
  out += "JSON";
  out += text;
  if (!bin.empty()) {
    append_u32(out, static_cast<std::uint32_t>(bin.size()));
    out += std::string("BIN\0", 4);
    out += bin;
  }
  return out;
}

}  // namespace

std::string write_glb_compressed(const Vertices& V, const Triangles& F, const Vertices* N,
                                 bool up_z, bool meshopt) {
  Vertices computed;
  if (!N) {
    computed = vertex_normals(V, F);
    N = &computed;
  }
  Grid grid;
  const std::array<Stream, 3> streams = {quantize_positions(V, grid), quantize_normals(*N),
                                         index_stream(F, V.rows())};

  // Buffer 0 is the GLB's BIN chunk: the streams themselves, or their compressed forms while
  // buffer 1 (the fallback, no data) gives the compressed views their decoded layout.
  std::string bin;
  std::size_t raw_offset = 0;  // in the fallback buffer
  json views = json::array();
  for (const Stream& s : streams) {
    // A stream the codec would not shrink (an index buffer without triangle locality, e.g. the
    // cactus: 65,680 bytes for 63,108) stays raw in buffer 0: views may mix, the file stays
    // the same to a reader.
    const std::string packed = meshopt ? meshopt_compress(s, F, static_cast<std::size_t>(V.rows()))
                                       : std::string();
    const bool compress = meshopt && packed.size() < s.bytes.size();
    json view = {{"buffer", compress ? 1 : 0},
                 {"byteOffset", compress ? raw_offset : bin.size()},
                 {"byteLength", s.bytes.size()},
                 {"target", s.indices ? kTargetElementArrayBuffer : kTargetArrayBuffer}};
    if (!s.indices) view["byteStride"] = s.stride;
    if (compress) {
      view["extensions"]["EXT_meshopt_compression"] = {
          {"buffer", 0},
          {"byteOffset", bin.size()},
          {"byteLength", packed.size()},
          {"byteStride", s.stride},
          {"count", s.count},
          {"mode", s.indices ? "TRIANGLES" : "ATTRIBUTES"}};
      bin += packed;
      raw_offset += (s.bytes.size() + 3) & ~std::size_t{3};
    } else {
      bin += s.bytes;
    }
    pad4(bin, '\0');
    views.push_back(std::move(view));
  }

  json extensions = {"KHR_mesh_quantization"};
  if (meshopt) extensions.push_back("EXT_meshopt_compression");
  json buffers = json::array();
  buffers.push_back({{"byteLength", bin.size()}});
  if (meshopt)
    buffers.push_back({{"byteLength", raw_offset},
                       {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}});

  const std::size_t n = static_cast<std::size_t>(V.rows());
  json position = {{"bufferView", 0},
                   {"componentType", kComponentUnsignedShort},
                   {"count", n},
                   {"type", "VEC3"}};
  if (n > 0) {
    position["min"] = grid.qmin;
    position["max"] = grid.qmax;
  }
  const json normal = {{"bufferView", 1}, {"componentType", kComponentByte},
                       {"normalized", true}, {"count", n}, {"type", "VEC3"}};
  const json index = {
      {"bufferView", 2},
      {"componentType", streams[2].stride == 2 ? kComponentUnsignedShort : kComponentUnsignedInt},
      {"count", streams[2].count},
      {"type", "SCALAR"}};
  const json accessors = json::array({position, normal, index});

  // The mesh node dequantizes: model = origin + step · q (uniform, so normals stay right).
  json nodes = json::array({{{"mesh", 0},
                             {"translation", grid.origin},
                             {"scale", {grid.step, grid.step, grid.step}}}});
  json scene_nodes = json::array({0});
  if (up_z) {
    nodes.push_back({{"name", "z-up to y-up"},
                     {"rotation", kZUpToYUp},
                     {"children", json::array({0})}});
    scene_nodes = json::array({1});
  }
  json primitive = {{"attributes", {{"POSITION", 0}, {"NORMAL", 1}}}, {"indices", 2}, {"mode", 4}};
  json mesh = {{"primitives", json::array({primitive})}};
  json scene = {{"nodes", scene_nodes}};
  json doc = {
      {"asset", {{"version", "2.0"}, {"generator", "hdeform"}}},
      {"extensionsUsed", extensions},
      {"extensionsRequired", extensions},
      {"buffers", buffers},
      {"bufferViews", views},
      {"accessors", accessors},
      {"meshes", json::array({mesh})},
      {"nodes", nodes},
      {"scenes", json::array({scene})},
      {"scene", 0}};
  return glb_container(doc, std::move(bin));
}

}  // namespace hdeform::detail

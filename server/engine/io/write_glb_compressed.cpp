// Compressed GLB: KHR_mesh_quantization, optionally through EXT_meshopt_compression
// (GlbCompression in mesh_io.h says what is stored and its error).
//
// Built with glb_builder.h like the other GLB writers. With meshopt, the compressed views
// point into a fallback buffer 1 that has a byteLength and no data (tinygltf cannot write
// such a buffer: it writes every buffer after the first as a data URI of its bytes).

#include "engine/io/mesh_writers.h"

#include "engine/io/glb_builder.h"
#include "engine/io/mesh_io.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace hdeform::detail {
namespace {

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

}  // namespace

std::string write_glb_compressed(const Vertices& V, const Triangles& F, const Vertices& N,
                                 bool up_z, bool meshopt) {
  Grid grid;
  const std::array<Stream, 3> streams = {quantize_positions(V, grid), quantize_normals(N),
                                         index_stream(F, V.rows())};

  // Buffer 0 is the GLB's BIN chunk: the streams themselves, or their compressed forms while
  // buffer 1 (the fallback, no data) gives the compressed views their decoded layout.
  GlbBuilder glb(GlbBuilder::ZeroOffset::written);
  std::size_t raw_offset = 0;  // in the fallback buffer
  std::array<int, 3> views{};
  for (std::size_t i = 0; i < streams.size(); ++i) {
    const Stream& s = streams[i];
    // A stream the codec would not shrink (an index buffer without triangle locality, e.g. the
    // cactus: 65,680 bytes for 63,108) stays raw in buffer 0: views may mix, the file stays
    // the same to a reader.
    const std::string packed = meshopt ? meshopt_compress(s, F, static_cast<std::size_t>(V.rows()))
                                       : std::string();
    const bool compress = meshopt && packed.size() < s.bytes.size();
    const int target = s.indices ? kTargetElementArrayBuffer : kTargetArrayBuffer;
    const int stride = s.indices ? 0 : s.stride;  // an index view has none
    if (!compress) {
      views[i] = glb.append_view(s.bytes, target, stride);
      continue;
    }
    views[i] = glb.add_view(raw_offset, s.bytes.size(), target, stride, 1);
    const std::size_t packed_at = glb.append(packed);
    glb.view(views[i])["extensions"]["EXT_meshopt_compression"] = {
        {"buffer", 0},
        {"byteOffset", packed_at},
        {"byteLength", packed.size()},
        {"byteStride", s.stride},
        {"count", s.count},
        {"mode", s.indices ? "TRIANGLES" : "ATTRIBUTES"}};
    raw_offset += (s.bytes.size() + 3) & ~std::size_t{3};
  }

  using json = GlbBuilder::json;
  json extensions = {"KHR_mesh_quantization"};
  if (meshopt) extensions.push_back("EXT_meshopt_compression");
  glb.doc()["extensionsUsed"] = extensions;
  glb.doc()["extensionsRequired"] = extensions;
  if (meshopt)
    glb.doc()["buffers"].push_back(
        {{"byteLength", raw_offset},
         {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}});

  const std::size_t n = static_cast<std::size_t>(V.rows());
  const int position =
      glb.add_accessor(views[0], kComponentUnsignedShort, n, "VEC3",
                       n > 0 ? json(grid.qmin) : nullptr, n > 0 ? json(grid.qmax) : nullptr);
  const int normal = glb.add_accessor(views[1], kComponentByte, n, "VEC3");
  glb.accessor(normal)["normalized"] = true;
  const int indices = glb.add_accessor(
      views[2], streams[2].stride == 2 ? kComponentUnsignedShort : kComponentUnsignedInt,
      streams[2].count, "SCALAR");
  // The mesh node dequantizes: model = origin + step · q (uniform, so normals stay right).
  glb.set_mesh(triangles({{"POSITION", position}, {"NORMAL", normal}}, indices), up_z,
               json::object(),
               {{"translation", grid.origin}, {"scale", {grid.step, grid.step, grid.step}}});
  return glb.finish("write_mesh");
}

}  // namespace hdeform::detail

// glTF/GLB reader, through tinygltf. Decision: primitives are taken as-is, in mesh-local
// coordinates; node transforms are NOT applied (a warning says so when a node carries a
// non-identity transform). The deformed positions then map straight back into the file's
// own vertex buffers. All triangle primitives (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN) of
// all meshes are used, in order meshes[i].primitives[j]; points and lines are skipped with
// a warning. The input vertex layout is the concatenation of the distinct POSITION
// accessors in first-use order (primitives sharing an accessor share its vertices).
// Vertices with bit-identical positions (−0 = +0) are welded into one engine vertex, in
// order of first occurrence: glTF splits vertices at UV/normal seams, the engine needs one
// connected surface.

#include "engine/io/mesh_readers.h"

#include <tiny_gltf.h>

#include <array>
#include <bit>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <unordered_map>

namespace hdeform::detail {
namespace {

bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;  // geometry only: never decode textures
}

bool no_file_exists(const std::string&, void*) { return false; }
std::string no_expand(const std::string& p, void*) { return p; }
bool no_read(std::vector<unsigned char>*, std::string* err, const std::string& path, void*) {
  if (err) *err += "external file '" + path + "' not allowed for an in-memory glTF (embed buffers or use GLB)\n";
  return false;
}
bool no_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing files is disabled\n";
  return false;
}

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

// Start of element 0 and the stride; validates (without overflow) that every element lies
// inside its bufferView and the view inside its buffer. `read` counts the bytes the caller
// will touch (count × element size).
const unsigned char* accessor_data(const tinygltf::Model& model, const tinygltf::Accessor& acc,
                                   const std::string& what, size_t& stride, size_t& read) {
  if (acc.sparse.isSparse) fail(what + ": sparse accessors are not supported");
  if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(model.bufferViews.size()))
    fail(what + ": accessor without a valid bufferView");
  const tinygltf::BufferView& bv = model.bufferViews[static_cast<size_t>(acc.bufferView)];
  if (bv.buffer < 0 || bv.buffer >= static_cast<int>(model.buffers.size()))
    fail(what + ": bufferView without a valid buffer");
  const tinygltf::Buffer& buf = model.buffers[static_cast<size_t>(bv.buffer)];
  const int comp = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(acc.componentType));
  const int ncomp = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(acc.type));
  if (comp <= 0 || ncomp <= 0) fail(what + ": invalid accessor componentType or type");
  const int s = acc.ByteStride(bv);
  if (s <= 0) fail(what + ": invalid byte stride");
  stride = static_cast<size_t>(s);
  const size_t elem = static_cast<size_t>(comp) * static_cast<size_t>(ncomp);
  if (bv.byteOffset > buf.data.size() || bv.byteLength > buf.data.size() - bv.byteOffset)
    fail(what + ": bufferView " + std::to_string(acc.bufferView) + " (offset " +
         std::to_string(bv.byteOffset) + ", length " + std::to_string(bv.byteLength) +
         ") lies outside its buffer of " + plural(buf.data.size(), "byte", "bytes"));
  if (acc.count > 0) {
    const size_t avail = acc.byteOffset <= bv.byteLength ? bv.byteLength - acc.byteOffset : 0;
    if (acc.byteOffset > bv.byteLength || elem > avail || (acc.count - 1) > (avail - elem) / stride)
      fail(what + ": accessor reads past the end of its bufferView (" +
           std::to_string(acc.count) + " elements of " + plural(elem, "byte", "bytes") +
           ", stride " + std::to_string(stride) + ", offset " + std::to_string(acc.byteOffset) +
           ", view length " + std::to_string(bv.byteLength) + ")");
  }
  read = acc.count * elem;  // ≤ the view's length: no overflow
  return buf.data.data() + bv.byteOffset + acc.byteOffset;
}

// tinygltf 2.7.0 (Debian 12) checks the BIN chunk's declared length against the GLB's length
// without the chunk's own 8-byte header, so a buffer could be copied up to 8 bytes past the
// end of the upload (heap overflow found by fuzz_glb). Checked here first; every other case
// is left to tinygltf, which rejects it.
void check_glb_bin_chunk(std::string_view bytes, const std::string& name) {
  if (bytes.size() < 20) return;
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const bool swap = std::endian::native != std::endian::little;
  const uint64_t length = load_raw<uint32_t>(p + 8, swap);
  const uint64_t header_and_json = 20 + static_cast<uint64_t>(load_raw<uint32_t>(p + 12, swap));
  if (length > bytes.size() || header_and_json + 8 > length) return;
  const uint64_t bin = load_raw<uint32_t>(p + header_and_json, swap);
  if (header_and_json + 8 + bin > length)
    fail(name + ": invalid GLB: the BIN chunk at byte " + std::to_string(header_and_json) +
         " declares " + plural(bin, "byte", "bytes") + " but " +
         plural(length - header_and_json - 8, "byte follows", "bytes follow") + " its header");
}

bool node_has_transform(const tinygltf::Node& n) {
  if (!n.matrix.empty()) {
    for (size_t i = 0; i < n.matrix.size(); ++i)
      if (n.matrix[i] != ((i % 5 == 0) ? 1.0 : 0.0)) return true;
  }
  if (!n.translation.empty() && (n.translation[0] != 0 || n.translation[1] != 0 || n.translation[2] != 0)) return true;
  if (!n.scale.empty() && (n.scale[0] != 1 || n.scale[1] != 1 || n.scale[2] != 1)) return true;
  if (n.rotation.size() == 4 && (n.rotation[0] != 0 || n.rotation[1] != 0 || n.rotation[2] != 0)) return true;
  return false;
}


}  // namespace

LoadedMesh read_gltf(std::string_view bytes, ReadContext& ctx, bool binary,
                     const std::string* base_dir) {
  const std::string& name = ctx.name;
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(skip_image, nullptr);
  if (!base_dir) loader.SetFsCallbacks({no_file_exists, no_expand, no_read, no_write, nullptr});
  tinygltf::Model model;
  std::string err, warn;
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) fail(name + ": file too large");
  if (binary) check_glb_bin_chunk(bytes, name);
  bool ok = false;
  try {
    ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn,
                                              reinterpret_cast<const unsigned char*>(bytes.data()),
                                              static_cast<unsigned int>(bytes.size()),
                                              base_dir ? *base_dir : std::string())
                : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(),
                                             static_cast<unsigned int>(bytes.size()),
                                             base_dir ? *base_dir : std::string());
  } catch (const InvalidInput&) {
    throw;
  } catch (const ReadCancelled&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;  // out of memory is the server's state, not the file's fault
  } catch (const std::exception& e) {
    // tinygltf throws on some malformed files (a std::vector::at past a buffer, found by
    // fuzz_glb: tests/fuzz/corpus/fuzz_glb/regress-parser-throws.glb): a bad upload, not a bug.
    fail(name + ": invalid " + (binary ? "GLB" : "glTF") + ": the file is malformed (" +
         e.what() + ")");
  }
  if (!ok) fail(name + ": invalid " + (binary ? "GLB" : "glTF") + ": " + trim(err.empty() ? warn : err));
  // Required extensions that change how geometry is stored (hdeform's own --glb-compression
  // output among them): refused by name rather than misread. Others (materials, textures)
  // leave the geometry alone and are kept by a rewrite.
  for (const std::string& e : model.extensionsRequired)
    if (e == "KHR_mesh_quantization" || e == "EXT_meshopt_compression" ||
        e == "KHR_draco_mesh_compression")
      fail(name + ": requires the glTF extension " + e +
           ", which hdeform does not read: upload a GLB with float32 positions (e.g. GetMesh "
           "without glb_compression)");

  // Work bound: accessors may share bufferViews, and primitives may share accessors, so the
  // data read could be many times the file. Every accessor use is charged; more than twice
  // the file and its buffers is refused.
  size_t budget = 2 * bytes.size();
  for (const tinygltf::Buffer& b : model.buffers) budget += 2 * b.data.size();
  size_t charged = 0;
  auto charge = [&](size_t n, const std::string& what) {
    charged += n;
    if (charged > budget)
      fail(what + ": accessors read " + grouped(charged) + " bytes so far, more than twice the " +
           "file and its buffers (" + grouped(budget / 2) + " bytes): accessors overlap or are reused");
  };
  size_t triangles = 0;

  LoadedMesh out;
  std::vector<double> input_xyz;               // input layout positions
  std::vector<int> input_tri;                  // input vertex ids
  std::unordered_map<int, int> accessor_base;  // POSITION accessor → first input vertex
  size_t skipped = 0;
  for (size_t mi = 0; mi < model.meshes.size(); ++mi) {
    const tinygltf::Mesh& mesh = model.meshes[mi];
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const std::string what = name + ": mesh " + std::to_string(mi) + " primitive " + std::to_string(pi);
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        ++skipped;
        continue;
      }
      auto it = prim.attributes.find("POSITION");
      if (it == prim.attributes.end()) fail(what + ": no POSITION attribute");
      if (it->second < 0 || it->second >= static_cast<int>(model.accessors.size()))
        fail(what + ": POSITION accessor " + std::to_string(it->second) + " does not exist");
      const tinygltf::Accessor& pacc = model.accessors[static_cast<size_t>(it->second)];
      if (pacc.type != TINYGLTF_TYPE_VEC3 || pacc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
        fail(what + ": POSITION must be a float VEC3 accessor");
      const size_t count = pacc.count;
      auto [bit, fresh] = accessor_base.try_emplace(it->second, static_cast<int>(input_xyz.size() / 3));
      const int base = bit->second;
      if (fresh) {
        size_t stride = 0, read = 0;
        const unsigned char* d = accessor_data(model, pacc, what + " POSITION", stride, read);
        charge(read, what + " POSITION");
        ctx.declare_vertices(input_xyz.size() / 3 + count);
        for (size_t v = 0; v < count; ++v) {
          ctx.tick();
          float f[3];
          std::memcpy(f, d + v * stride, sizeof f);
          for (float x : f) input_xyz.push_back(static_cast<double>(x));
        }
      }
      // Index list (or implicit 0..count-1).
      std::vector<uint32_t> idx;
      if (prim.indices >= 0) {
        if (prim.indices >= static_cast<int>(model.accessors.size()))
          fail(what + ": indices accessor " + std::to_string(prim.indices) + " does not exist");
        const tinygltf::Accessor& iacc = model.accessors[static_cast<size_t>(prim.indices)];
        if (iacc.type != TINYGLTF_TYPE_SCALAR) fail(what + ": indices must be SCALAR");
        if (iacc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
            iacc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            iacc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
          fail(what + ": indices must be unsigned byte, short or int");
        size_t stride = 0, read = 0;
        const unsigned char* d = accessor_data(model, iacc, what + " indices", stride, read);
        charge(read, what + " indices");
        idx.resize(iacc.count);
        for (size_t k = 0; k < iacc.count; ++k) {
          ctx.tick();
          const unsigned char* q = d + k * stride;
          switch (iacc.componentType) {
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: idx[k] = *q; break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: idx[k] = load_raw<uint16_t>(q, false); break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: idx[k] = load_raw<uint32_t>(q, false); break;
            default: fail(what + ": indices must be unsigned byte, short or int");
          }
          if (idx[k] >= count)
            fail(what + ": index " + std::to_string(idx[k]) + " out of range (" +
                 plural(count, "vertex", "vertices") + ")");
        }
      } else {
        charge(12 * count, what + " POSITION (as indices)");
        idx.resize(count);
        for (size_t k = 0; k < count; ++k) idx[k] = static_cast<uint32_t>(k);
      }
      const size_t prim_triangles = mode == TINYGLTF_MODE_TRIANGLES ? idx.size() / 3
                                    : idx.size() >= 3               ? idx.size() - 2
                                                                    : 0;
      triangles += prim_triangles;
      ctx.declare_triangles(triangles);
      auto push = [&](uint32_t a, uint32_t b, uint32_t c) {
        ctx.tick();
        input_tri.push_back(base + static_cast<int>(a));
        input_tri.push_back(base + static_cast<int>(b));
        input_tri.push_back(base + static_cast<int>(c));
      };
      if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (idx.size() % 3 != 0)
          out.warnings.push_back(what + ": " + std::to_string(idx.size()) +
                                 " indices is not a multiple of 3; the rest is ignored");
        for (size_t k = 0; k + 2 < idx.size(); k += 3) push(idx[k], idx[k + 1], idx[k + 2]);
      } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t k = 0; k + 2 < idx.size(); ++k) {
          if (k % 2 == 0) push(idx[k], idx[k + 1], idx[k + 2]);
          else push(idx[k + 1], idx[k], idx[k + 2]);
        }
      } else {
        for (size_t k = 1; k + 1 < idx.size(); ++k) push(idx[0], idx[k], idx[k + 1]);
      }
    }
  }
  if (skipped > 0)
    out.warnings.push_back(name + ": " + plural(skipped, "point/line primitive", "point/line primitives") +
                           " skipped");
  for (const tinygltf::Node& n : model.nodes)
    if (n.mesh >= 0 && node_has_transform(n)) {
      out.warnings.push_back(name + ": node transforms are ignored; the mesh is deformed in its own (mesh-local) coordinates");
      break;
    }

  // Weld bit-identical positions, engine ids in order of first occurrence.
  const size_t n_in = input_xyz.size() / 3;
  if (n_in == 0)
    fail(name + ": no vertices found in the " + (binary ? "GLB" : "glTF") +
         " file (no triangle primitive with a POSITION accessor of at least one element)");
  out.input_to_engine.resize(n_in);
  std::unordered_map<PosKey, int, PosKeyHash> ids;
  ids.reserve(n_in);
  std::vector<double> engine_xyz;
  engine_xyz.reserve(input_xyz.size());
  for (size_t v = 0; v < n_in; ++v) {
    ctx.tick();
    const PosKey key(input_xyz[3 * v], input_xyz[3 * v + 1], input_xyz[3 * v + 2]);
    auto [it, fresh] = ids.try_emplace(key, static_cast<int>(engine_xyz.size() / 3));
    if (fresh)
      for (int k = 0; k < 3; ++k) engine_xyz.push_back(input_xyz[3 * v + k]);
    out.input_to_engine[v] = it->second;
  }
  const Eigen::Index m = static_cast<Eigen::Index>(input_tri.size() / 3);
  out.input_triangles = Eigen::Map<const Triangles>(input_tri.data(), m, 3);
  out.mesh.V = Eigen::Map<const Vertices>(engine_xyz.data(), static_cast<Eigen::Index>(engine_xyz.size() / 3), 3);
  out.mesh.F.resize(m, 3);
  for (Eigen::Index t = 0; t < m; ++t)
    for (int k = 0; k < 3; ++k) out.mesh.F(t, k) = out.input_to_engine[static_cast<size_t>(input_tri[3 * t + k])];
  if (static_cast<size_t>(out.mesh.num_vertices()) < n_in)
    out.warnings.push_back(name + ": welded " + std::to_string(n_in) + " glTF vertices with identical positions into " +
                           std::to_string(out.mesh.num_vertices()));
  return out;
}

}  // namespace hdeform::detail

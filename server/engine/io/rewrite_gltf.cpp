#include "engine/io/rewrite_gltf.h"

#include "engine/io/glb_builder.h"
#include "engine/io/mesh_io.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <map>
#include <new>
#include <sstream>

namespace hdeform {

namespace {

bool keep_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;  // images stay as the file has them (bufferView or URI), never decoded
}

bool no_file_exists(const std::string&, void*) { return false; }
std::string no_expand(const std::string& s, void*) { return s; }
bool no_read(std::vector<unsigned char>*, std::string*, const std::string&, void*) {
  return false;
}
bool no_write(std::string*, const std::string&, const std::vector<unsigned char>&, void*) {
  return false;
}

// Appends `rows` as a tightly packed float32 VEC3 accessor; returns its index.
int append_vec3(tinygltf::Model& model, const Vertices& rows, int first, int count, bool bounds) {
  auto& data = model.buffers[0].data;
  while (data.size() % 4 != 0) data.push_back(0);
  tinygltf::BufferView bv;
  bv.buffer = 0;
  bv.byteOffset = data.size();
  bv.byteLength = static_cast<size_t>(count) * 12;
  bv.target = TINYGLTF_TARGET_ARRAY_BUFFER;
  data.resize(data.size() + bv.byteLength);
  float* out = reinterpret_cast<float*>(data.data() + bv.byteOffset);
  std::vector<double> lo(3, std::numeric_limits<double>::infinity()), hi(3, -lo[0]);
  for (int v = 0; v < count; ++v)
    for (int k = 0; k < 3; ++k) {
      const float f = static_cast<float>(rows(first + v, k));
      out[3 * v + k] = f;
      lo[static_cast<size_t>(k)] = std::min(lo[static_cast<size_t>(k)], static_cast<double>(f));
      hi[static_cast<size_t>(k)] = std::max(hi[static_cast<size_t>(k)], static_cast<double>(f));
    }
  model.bufferViews.push_back(bv);
  tinygltf::Accessor a;
  a.bufferView = static_cast<int>(model.bufferViews.size()) - 1;
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.type = TINYGLTF_TYPE_VEC3;
  a.count = static_cast<size_t>(count);
  if (bounds && count > 0) {
    a.minValues = lo;
    a.maxValues = hi;
  }
  model.accessors.push_back(a);
  return static_cast<int>(model.accessors.size()) - 1;
}

// tinygltf writes an object with no properties — a scene without nodes, a material of all
// defaults, an empty node — as `null`, which no reader accepts. Make each one `{}` again.
std::string with_empty_objects(const std::string& glb, const std::string& filename) {
  auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, glb.data() + at, 4);
    return v;
  };
  if (glb.size() < 20 || glb.compare(16, 4, "JSON") != 0 || glb.size() - 20 < u32(12))
    throw std::runtime_error(filename + ": tinygltf wrote a malformed GLB");
  const std::size_t json_end = 20 + u32(12);
  auto doc = nlohmann::json::parse(glb.begin() + 20, glb.begin() + static_cast<long>(json_end));
  bool changed = false;
  for (auto& [key, value] : doc.items()) {
    if (!value.is_array()) continue;
    for (auto& element : value) {
      if (!element.is_null()) continue;
      element = nlohmann::json::object();
      changed = true;
    }
  }
  if (!changed) return glb;
  std::string bin;
  if (glb.size() >= json_end + 8 && glb.compare(json_end + 4, 4, std::string_view("BIN\0", 4)) == 0)
    bin = glb.substr(json_end + 8, u32(json_end));
  detail::GlbBuilder out(detail::GlbBuilder::ZeroOffset::omitted, std::move(bin));
  out.doc() = std::move(doc);
  return out.finish(filename.c_str());
}

}  // namespace

std::string rewrite_gltf(std::string_view original, const std::string& filename,
                         const Vertices& positions, const Vertices& normals) {
  const bool binary = original.substr(0, 4) == "glTF";
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keep_image, nullptr);
  loader.SetFsCallbacks({no_file_exists, no_expand, no_read, no_write, nullptr});
  tinygltf::Model model;
  std::string err, warn;
  const auto* p = reinterpret_cast<const unsigned char*>(original.data());
  const auto n = static_cast<unsigned int>(original.size());
  bool ok = false;
  try {
    ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, p, n, "")
                : loader.LoadASCIIFromString(&model, &err, &warn, original.data(), n, "");
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    // read_gltf accepted these bytes, so this should not happen; if tinygltf throws anyway
    // (it does on some malformed files), the file is at fault, as in read_gltf.
    err = e.what();
  }
  if (!ok) throw InvalidInput(filename + ": cannot read it again to write its glTF: " + err);
  if (model.buffers.empty()) model.buffers.emplace_back();
  model.buffers[0].uri.clear();  // the GLB's binary chunk

  // Input vertices are numbered as read_mesh numbers them: POSITION accessors of triangle
  // primitives in mesh and primitive order, each once.
  std::map<int, std::pair<int, int>> replaced;  // POSITION accessor → (new POSITION, NORMAL)
  int next = 0;
  for (auto& mesh : model.meshes)
    for (auto& prim : mesh.primitives) {
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          mode != TINYGLTF_MODE_TRIANGLE_FAN)
        continue;
      const auto it = prim.attributes.find("POSITION");
      if (it == prim.attributes.end()) continue;
      auto r = replaced.find(it->second);
      if (r == replaced.end()) {
        const int count = static_cast<int>(model.accessors.at(static_cast<size_t>(it->second)).count);
        if (next + count > positions.rows())
          throw InvalidInput(filename + ": has more vertices than the session's mesh");
        const int pos = append_vec3(model, positions, next, count, true);
        const int nrm = append_vec3(model, normals, next, count, false);
        r = replaced.emplace(it->second, std::make_pair(pos, nrm)).first;
        next += count;
      }
      prim.attributes["POSITION"] = r->second.first;
      prim.attributes["NORMAL"] = r->second.second;
      prim.attributes.erase("TANGENT");
    }
  if (next != positions.rows())
    throw InvalidInput(filename + ": " + std::to_string(next) + " vertices, the session's mesh " +
                       std::to_string(positions.rows()));
  std::ostringstream os;
  if (!loader.WriteGltfSceneToStream(&model, os, false, true))
    throw std::runtime_error(filename + ": tinygltf failed to write the GLB");
  return with_empty_objects(os.str(), filename);
}

}  // namespace hdeform

// See glb_builder.h.

#include "engine/io/glb_builder.h"

#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace hdeform::detail {
namespace {

std::size_t round_up4(std::size_t n) { return (n + 3) & ~std::size_t{3}; }

void append_u32(std::string& out, std::uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  out.append(b, 4);
}

}  // namespace

GlbBuilder::GlbBuilder(ZeroOffset zero_offset, std::string bin)
    : zero_offset_(zero_offset), bin_(std::move(bin)) {
  bin_.resize(round_up4(bin_.size()), '\0');
  doc_["asset"] = {{"generator", "hdeform"}, {"version", "2.0"}};
  doc_["buffers"] = json::array({json::object()});
}

std::size_t GlbBuilder::grow(std::size_t length) {
  const std::size_t offset = bin_.size();
  bin_.resize(round_up4(offset + length), '\0');
  return offset;
}

std::size_t GlbBuilder::append(std::string_view bytes) {
  const std::size_t offset = grow(bytes.size());
  if (!bytes.empty()) std::memcpy(bin_.data() + offset, bytes.data(), bytes.size());
  return offset;
}

int GlbBuilder::add_view(std::size_t offset, std::size_t length, int target, int stride,
                         int buffer) {
  json v = {{"buffer", buffer}, {"byteLength", length}};
  if (offset > 0 || zero_offset_ == ZeroOffset::written) v["byteOffset"] = offset;
  if (stride > 0) v["byteStride"] = stride;
  if (target != 0) v["target"] = target;
  json& views = doc_["bufferViews"];
  views.push_back(std::move(v));
  return static_cast<int>(views.size() - 1);
}

int GlbBuilder::append_view(std::string_view bytes, int target, int stride) {
  return add_view(append(bytes), bytes.size(), target, stride);
}

int GlbBuilder::add_accessor(int view, int component, std::size_t count, const char* type,
                             json min, json max) {
  json a = {{"bufferView", view}, {"componentType", component}, {"count", count}, {"type", type}};
  if (!min.is_null()) a["min"] = std::move(min);
  if (!max.is_null()) a["max"] = std::move(max);
  json& accessors = doc_["accessors"];
  accessors.push_back(std::move(a));
  return static_cast<int>(accessors.size() - 1);
}

void GlbBuilder::set_mesh(json primitive, bool up_z, json mesh, json node) {
  mesh["primitives"] = json::array({std::move(primitive)});
  doc_["meshes"] = json::array({std::move(mesh)});
  node["mesh"] = 0;
  json nodes = json::array({std::move(node)});
  if (up_z)
    nodes.push_back({{"name", "z-up to y-up"},
                     {"rotation", kZUpToYUp},
                     {"children", json::array({0})}});
  json scene = {{"nodes", json::array({up_z ? 1 : 0})}};
  doc_["nodes"] = std::move(nodes);
  doc_["scenes"] = json::array({std::move(scene)});
  doc_["scene"] = 0;
}

std::string GlbBuilder::finish(const char* who) {
  doc_["buffers"][0]["byteLength"] = bin_.size();
  std::string text = doc_.dump();
  text.resize(round_up4(text.size()), ' ');
  const std::size_t total = 12 + 8 + text.size() + (bin_.empty() ? 0 : 8 + bin_.size());
  if (total > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error(std::string(who) + ": the GLB would exceed 4 GiB");
  std::string out;
  out.reserve(total);
  out += "glTF";
  append_u32(out, 2);
  append_u32(out, static_cast<std::uint32_t>(total));
  append_u32(out, static_cast<std::uint32_t>(text.size()));
  out += "JSON";
  out += text;
  if (!bin_.empty()) {
    append_u32(out, static_cast<std::uint32_t>(bin_.size()));
    out += std::string_view("BIN\0", 4);
    out += bin_;
  }
  return out;
}

nlohmann::json triangles(nlohmann::json attributes, int indices) {
  return {{"attributes", std::move(attributes)}, {"indices", indices}, {"mode", kModeTriangles}};
}

}  // namespace hdeform::detail

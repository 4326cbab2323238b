// Internal header of the GLB writers (write_glb, write_glb_compressed, AnimationGlb): one
// glTF document as nlohmann::json and its BIN chunk, built from the pieces every writer
// needs: bytes laid out at 4-byte boundaries, buffer views, accessors with optional bounds,
// one mesh of a TRIANGLES primitive, its node and scene (with the z-up parent node) and the
// GLB container.
//
// Object keys come out sorted (nlohmann::json keeps objects in a std::map), so a writer may
// set them in any order and the bytes depend on the values alone.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <string_view>

namespace hdeform::detail {

// glTF 2.0 enumerations: accessor.componentType, bufferView.target, primitive.mode.
inline constexpr int kComponentByte = 5120;
inline constexpr int kComponentUnsignedByte = 5121;
inline constexpr int kComponentUnsignedShort = 5123;
inline constexpr int kComponentUnsignedInt = 5125;
inline constexpr int kComponentFloat = 5126;
inline constexpr int kTargetArrayBuffer = 34962;
inline constexpr int kTargetElementArrayBuffer = 34963;
inline constexpr int kModeTriangles = 4;

// −90° about x as a glTF quaternion (x, y, z, w): (x, y, z) → (x, z, −y), z-up to y-up.
inline constexpr double kZUpToYUp[4] = {-0.70710678118654752440, 0.0, 0.0, 0.70710678118654752440};

class GlbBuilder {
 public:
  using json = nlohmann::json;

  // glTF's default byteOffset is 0, so a view at the start of its buffer may leave it out
  // (the plain and animated GLBs do) or name it (the compressed GLB, every view alike).
  // Readers see no difference; the choice only fixes a writer's bytes.
  enum class ZeroOffset { omitted, written };

  // `bin`: the start of buffer 0 (the BIN chunk) when a writer laid bytes out before it
  // built the document; views into it come from add_view. The asset is glTF 2.0 by hdeform.
  explicit GlbBuilder(ZeroOffset zero_offset, std::string bin = {});

  // `length` zero bytes at the end of the BIN chunk, which stays a multiple of 4 bytes long
  // (zero padding after them); returns their offset. data() + offset writes them in place.
  std::size_t grow(std::size_t length);
  // grow() with `bytes` copied in.
  std::size_t append(std::string_view bytes);
  char* data() { return bin_.data(); }

  // A buffer view of `length` bytes at `offset` in `buffer` (0: the BIN chunk); a target or
  // stride of 0 is left out. Returns its index; view(index) adds to its JSON (extensions).
  int add_view(std::size_t offset, std::size_t length, int target, int stride = 0,
               int buffer = 0);
  // append() and a view of those bytes.
  int append_view(std::string_view bytes, int target, int stride = 0);
  json& view(int index) { return doc_["bufferViews"][static_cast<std::size_t>(index)]; }

  // An accessor of `count` elements of `type` ("SCALAR", "VEC3") over the whole of `view`;
  // `min` and `max` are written when not null (arrays, integers for integer components).
  // Returns its index; accessor(index) adds to its JSON.
  int add_accessor(int view, int component, std::size_t count, const char* type,
                   json min = nullptr, json max = nullptr);
  json& accessor(int index) { return doc_["accessors"][static_cast<std::size_t>(index)]; }

  // The document: animations and extensions go straight in; "buffers" starts with buffer 0's
  // entry (byteLength set by finish), after which a writer may add buffers.
  json& doc() { return doc_; }

  // The document's one mesh: `primitive` as mesh.primitives[0], `node` (node 0) as the mesh's
  // node, and the scene of that node, under a parent node turning a z-up model to glTF's y-up
  // (kZUpToYUp) when up_z; the buffers keep model coordinates.
  void set_mesh(json primitive, bool up_z, json mesh = json::object(),
                json node = json::object());

  // The GLB: 12-byte header, the JSON chunk (space-padded), the BIN chunk when not empty.
  // Throws std::runtime_error naming `who` when the file would exceed 4 GiB.
  std::string finish(const char* who);

 private:
  ZeroOffset zero_offset_;
  std::string bin_;
  json doc_;
};

// A TRIANGLES primitive of `attributes` ({"POSITION": accessor, …}) and an index accessor.
nlohmann::json triangles(nlohmann::json attributes, int indices);

}  // namespace hdeform::detail

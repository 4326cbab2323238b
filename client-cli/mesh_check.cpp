#include "mesh_check.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

namespace hdeform::cli {

namespace {

float float_le(const char* p) {
  unsigned char b[4];
  std::memcpy(b, p, 4);
  const std::uint32_t u = std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 |
                          std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

std::uint32_t u32_le(const char* p) {
  unsigned char b[4];
  std::memcpy(b, p, 4);
  return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 |
         std::uint32_t(b[3]) << 24;
}

bool non_finite_token(std::string_view tok) {
  std::size_t i = 0;
  if (i < tok.size() && (tok[i] == '+' || tok[i] == '-')) ++i;
  if (i >= tok.size()) return false;
  const char c = tok[i];
  if (c != 'n' && c != 'N' && c != 'i' && c != 'I') return false;
  const std::string t(tok);
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size() && !std::isfinite(v);
}

// Counts non-finite tokens on the lines `take` accepts (text formats).
template <class Take>
std::size_t scan_text(std::string_view text, Take take) {
  std::size_t count = 0, at = 0, line_no = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(at, end - at);
    at = end + 1;
    ++line_no;
    if (!take(line, line_no)) continue;
    std::size_t p = 0;
    while (p < line.size()) {
      while (p < line.size() && (line[p] == ' ' || line[p] == '\t' || line[p] == '\r')) ++p;
      std::size_t q = p;
      while (q < line.size() && line[q] != ' ' && line[q] != '\t' && line[q] != '\r') ++q;
      if (q > p && non_finite_token(line.substr(p, q - p))) ++count;
      p = q;
    }
  }
  return count;
}

std::size_t check_glb(std::string_view b) {
  using json = nlohmann::json;
  auto bad = [](const std::string& why) { return CliError("GLB: " + why); };
  if (b.size() < 20 || b.substr(0, 4) != "glTF") throw bad("not a binary glTF");
  const std::size_t json_len = u32_le(b.data() + 12);
  if (u32_le(b.data() + 16) != 0x4E4F534Au || json_len > b.size() - 20)
    throw bad("no JSON chunk");
  std::string_view bin;
  const std::size_t bin_at = 20 + json_len;
  if (bin_at + 8 <= b.size()) {
    const std::size_t bin_len = u32_le(b.data() + bin_at);
    if (u32_le(b.data() + bin_at + 4) != 0x004E4942u || bin_len > b.size() - bin_at - 8)
      throw bad("bad BIN chunk");
    bin = b.substr(bin_at + 8, bin_len);
  }
  std::size_t count = 0;
  try {
    const json doc = json::parse(b.substr(20, json_len));
    if (!doc.contains("meshes")) return 0;
    for (const auto& mesh : doc.at("meshes"))
      for (const auto& prim : mesh.at("primitives")) {
        if (!prim.contains("attributes") || !prim.at("attributes").contains("POSITION")) continue;
        const auto& acc = doc.at("accessors").at(prim.at("attributes").at("POSITION").get<std::size_t>());
        // Integer positions (KHR_mesh_quantization) are finite by construction.
        if (acc.at("componentType").get<int>() != 5126) continue;
        if (acc.at("type").get<std::string>() != "VEC3") throw bad("POSITION is not VEC3");
        const std::size_t n = acc.at("count").get<std::size_t>();
        if (n == 0) continue;
        const auto& view = doc.at("bufferViews").at(acc.at("bufferView").get<std::size_t>());
        if (view.value("buffer", 0) != 0) throw bad("POSITION not in the GLB's own buffer");
        const std::size_t offset = view.value("byteOffset", std::size_t{0}) +
                                   acc.value("byteOffset", std::size_t{0});
        const std::size_t stride = view.value("byteStride", std::size_t{12});
        if (stride < 12 || n > (bin.size() / stride) + 1 || offset > bin.size() ||
            (n - 1) * stride + 12 > bin.size() - offset)
          throw bad("POSITION outside the buffer");
        for (std::size_t i = 0; i < n; ++i)
          for (int k = 0; k < 3; ++k)
            if (!std::isfinite(float_le(bin.data() + offset + i * stride + 4 * k))) ++count;
      }
  } catch (const json::exception& e) {
    throw bad(e.what());
  }
  return count;
}

}  // namespace

std::size_t count_non_finite_floats(std::string_view f) {
  std::size_t count = 0;
  for (std::size_t at = 0; at + 4 <= f.size(); at += 4)
    if (!std::isfinite(float_le(f.data() + at))) ++count;
  return count;
}

std::optional<std::size_t> count_non_finite_coordinates(std::string_view bytes,
                                                        std::string_view format) {
  if (format == "glb") return check_glb(bytes);
  if (format == "obj")  // vertex lines: "v x y z"
    return scan_text(bytes, [](std::string_view line, std::size_t) {
      return line.size() > 2 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t');
    });
  if (format == "off")  // every line after the header: numbers only
    return scan_text(bytes, [](std::string_view line, std::size_t n) {
      return n > 1 && !line.empty() && line[0] != '#';
    });
  if (format == "ply") {
    const std::size_t header_end = bytes.find("end_header");
    if (bytes.substr(0, 3) != "ply" || header_end == std::string_view::npos)
      throw CliError("PLY: no header");
    if (bytes.substr(0, header_end).find("format ascii") == std::string_view::npos)
      return std::nullopt;
    const std::size_t body = bytes.find('\n', header_end);
    if (body == std::string_view::npos) return 0;
    return scan_text(bytes.substr(body + 1), [](std::string_view, std::size_t) { return true; });
  }
  throw CliError("unknown mesh format '" + std::string(format) + "'");
}

}  // namespace hdeform::cli

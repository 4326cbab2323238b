// STL reader, binary and ASCII: our own parser, because OpenMesh's accepts a truncated ASCII
// STL silently and reads a truncated binary one as an empty ASCII file. Corners with
// identical positions (−0 = +0) are merged into one vertex, in order of first occurrence (as
// OpenMesh's reader does). See mesh_readers.h.
//
// Binary: 80-byte header, uint32 little-endian triangle count n, then n records of 50 bytes
// (float32 normal, 3 × float32 xyz corners, uint16 attribute). A file of exactly
// 84 + 50 n bytes is binary even when its header starts with "solid".
// ASCII: solid NAME / facet normal ni nj nk / outer loop / vertex x y z (3×) / endloop /
// endfacet ... endsolid NAME (keywords case-insensitive; several solids may follow each
// other). Coordinates are read as doubles.

#include "engine/io/mesh_readers.h"

#include <array>
#include <bit>
#include <cctype>
#include <cstdint>
#include <unordered_map>

namespace hdeform::detail {
namespace {


// Merges corners with bit-identical positions into one soup vertex.
class Welder {
 public:
  explicit Welder(Soup& s) : s_(s) {}
  int add(const double p[3]) {
    auto [it, fresh] = ids_.try_emplace(PosKey(p[0], p[1], p[2]), s_.num_vertices());
    if (fresh) s_.add_vertex(p[0], p[1], p[2]);
    return it->second;
  }

 private:
  Soup& s_;
  std::unordered_map<PosKey, int, PosKeyHash> ids_;
};

bool iequal(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i])))
      return false;
  return true;
}

Soup parse_stl_binary(std::string_view bytes, ReadContext& ctx) {
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  const bool swap = std::endian::native != std::endian::little;
  const uint32_t n = load_raw<uint32_t>(b + 80, swap);
  ctx.declare_triangles(n);
  const unsigned long long expected = 84 + 50ULL * n;
  if (bytes.size() > expected)
    ctx.warnings.push_back(ctx.name + ": " + grouped(bytes.size() - expected) +
                           " bytes after the " + plural(n, "triangle", "triangles") +
                           " of the binary STL ignored");
  Soup s(ctx);
  s.reserve(0, n);
  Welder weld(s);
  for (uint32_t t = 0; t < n; ++t) {
    const unsigned char* rec = b + 84 + 50 * static_cast<size_t>(t) + 12;  // skip the normal
    int corner[3];
    for (int c = 0; c < 3; ++c) {
      double p[3];
      for (int k = 0; k < 3; ++k) p[k] = load_raw<float>(rec + 12 * c + 4 * k, swap);
      corner[c] = weld.add(p);
    }
    s.add_polygon(corner, 3);
  }
  return s;
}

// Whitespace-separated tokens with line numbers.
class Tokens {
 public:
  explicit Tokens(std::string_view s) : s_(s) {}
  // False at the end of the text.
  bool next(std::string_view& tok) {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) {
      if (s_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ == s_.size()) return false;
    tok_line_ = line_;
    const size_t b = pos_;
    while (pos_ < s_.size() && !std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
    tok = s_.substr(b, pos_ - b);
    return true;
  }
  void skip_line() {  // the rest of the current line (a solid's name)
    while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
  }
  // The line of the last token read (at the end of the text: of the last token).
  int line() const { return tok_line_; }

 private:
  std::string_view s_;
  size_t pos_ = 0;
  int line_ = 1;
  int tok_line_ = 1;
};

Soup parse_stl_ascii(std::string_view text, ReadContext& ctx) {
  const std::string& name = ctx.name;
  Soup s(ctx);
  Welder weld(s);
  Tokens tk(text);
  std::string_view tok;
  size_t facets = 0;
  bool in_facet = false;
  auto truncated = [&](const std::string& expected) {
    fail_line(name, tk.line(),
              "ASCII STL truncated: the file ends " +
                  (in_facet ? "inside facet " + std::to_string(facets + 1)
                   : facets == 0 ? std::string("before the first facet")
                                 : "after facet " + std::to_string(facets)) +
                  " (expected " + expected + ")");
  };
  auto expect = [&](const char* kw) {
    if (!tk.next(tok)) truncated(std::string("'") + kw + "'");
    if (!iequal(tok, kw))
      fail_line(name, tk.line(), "ASCII STL: expected '" + std::string(kw) + "', found " + quoted(tok));
  };
  auto number = [&](const char* what) {
    if (!tk.next(tok)) truncated(std::string("a ") + what + " coordinate");
    double v = 0;
    const char* p = tok.data();
    const char* e = p + tok.size();
    if (p < e && *p == '+') ++p;
    auto r = std::from_chars(p, e, v);
    if (r.ec != std::errc() || r.ptr != e)
      fail_line(name, tk.line(), "ASCII STL: bad " + std::string(what) + " coordinate " + quoted(tok));
    return v;
  };
  expect("solid");
  tk.skip_line();
  for (;;) {
    if (!tk.next(tok)) truncated("'facet' or 'endsolid'");
    if (iequal(tok, "endsolid")) {
      tk.skip_line();
      if (!tk.next(tok)) break;
      if (!iequal(tok, "solid"))
        fail_line(name, tk.line(), "ASCII STL: expected 'solid' or the end of the file after 'endsolid', found " + quoted(tok));
      tk.skip_line();
      continue;
    }
    if (!iequal(tok, "facet"))
      fail_line(name, tk.line(), "ASCII STL: expected 'facet' or 'endsolid', found " + quoted(tok));
    in_facet = true;
    expect("normal");
    for (int k = 0; k < 3; ++k) number("normal");
    expect("outer");
    expect("loop");
    int corner[3];
    for (int c = 0; c < 3; ++c) {
      expect("vertex");
      double p[3];
      for (int k = 0; k < 3; ++k) p[k] = number("vertex");
      corner[c] = weld.add(p);
    }
    expect("endloop");
    expect("endfacet");
    s.add_polygon(corner, 3);
    ++facets;
    in_facet = false;
  }
  return s;
}

}  // namespace

Soup parse_stl(std::string_view bytes, ReadContext& ctx) {
  // "solid" at the start (after blanks) and text-looking bytes: ASCII; else binary.
  size_t b = 0;
  while (b < bytes.size() && b < 256 && std::isspace(static_cast<unsigned char>(bytes[b]))) ++b;
  const bool solid = bytes.size() - b >= 5 && iequal(bytes.substr(b, 5), "solid");
  bool text = solid;
  for (size_t i = 0; text && i < std::min<size_t>(bytes.size(), 1024); ++i) {
    const auto u = static_cast<unsigned char>(bytes[i]);
    if (u < 0x09 || (u > 0x0d && u < 0x20)) text = false;
  }
  if (bytes.size() >= 84) {
    const uint32_t n = load_raw<uint32_t>(reinterpret_cast<const unsigned char*>(bytes.data()) + 80,
                                          std::endian::native != std::endian::little);
    const unsigned long long expected = 84 + 50ULL * n;
    if (!text) ctx.declare_triangles(n);  // the limit first, as for every declared count
    if (bytes.size() == expected || (!text && bytes.size() > expected)) return parse_stl_binary(bytes, ctx);
    if (!text)
      fail(ctx.name + ": binary STL truncated: header declares " + plural(n, "triangle", "triangles") +
           " (" + grouped(expected) + " bytes) but the file has " + grouped(bytes.size()) + " bytes");
  }
  if (!text)
    fail(ctx.name + ": not an STL file: " + plural(bytes.size(), "byte", "bytes") +
         ", too short for a binary STL (84-byte header) and no 'solid' line for an ASCII STL");
  return parse_stl_ascii(bytes, ctx);
}

}  // namespace hdeform::detail

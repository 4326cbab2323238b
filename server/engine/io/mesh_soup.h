// Internal header of the mesh readers (namespace detail), not part of the public API: use mesh_io.h.
// The polygon soup every reader produces, error helpers, and the line/token cursor the
// text parsers (OBJ, OFF, PLY; also .sel/.def in selection.cpp) share.
#pragma once

#include "engine/io/mesh_io.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <charconv>
#include <cstddef>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace hdeform::detail {

// Throw InvalidInput(msg) / InvalidInput("NAME:LINE: msg").
[[noreturn]] void fail(const std::string& msg);
[[noreturn]] void fail_line(const std::string& name, int line, const std::string& msg);

// "Mesh.OBJ" → "obj"; "" without an extension.
std::string lower_extension(const std::string& path);
// "1 vertex", "2 vertices".
std::string plural(size_t n, const char* one, const char* many);
// 't' for error messages, cut after 40 characters; bytes outside printable ASCII are shown
// as \xNN, so a message quoting a binary or non-UTF-8 file is still valid UTF-8.
std::string quoted(std::string_view t);
// "50,084" (thousands separated by commas).
std::string grouped(unsigned long long n);

// ---------------------------------------------------------------------------------------
// One read: the file name for messages, the limits, warnings, and the cancellation poll.
class ReadContext {
 public:
  ReadContext(std::string name, const ReadLimits& limits);
  const std::string name;
  const ReadLimits& limits;
  std::vector<std::string> warnings;

  // Call once per row/line/element: polls cancellation every kPollEvery calls.
  void tick() {
    if (++ticks_ >= kPollEvery) {
      ticks_ = 0;
      poll();
    }
  }
  void poll() const;  // throws ReadCancelled
  // A count declared by a header (or known before reading): throws LimitExceeded
  // "NAME: N vertices exceed the server's limit of L (--max-vertices)".
  void declare_vertices(unsigned long long n) const;
  void declare_triangles(unsigned long long n) const;
  // The most vertices/triangles a Soup may hold (the limit, and at most what int ids allow).
  size_t vertex_cap() const { return vertex_cap_; }
  size_t triangle_cap() const { return triangle_cap_; }
  // A running count passed the cap: "NAME: more than L vertices: the server's limit (...)".
  [[noreturn]] void too_many_vertices() const;
  [[noreturn]] void too_many_triangles() const;

  static constexpr unsigned kPollEvery = 4096;

 private:
  size_t vertex_cap_;
  size_t triangle_cap_;
  unsigned ticks_ = 0;
};

// ---------------------------------------------------------------------------------------
// Polygon soup: what every reader produces before it becomes a LoadedMesh. Adding a vertex
// or a polygon checks the context's caps and polls cancellation.
struct Soup {
  explicit Soup(ReadContext& ctx) : ctx_(&ctx) {}
  std::vector<double> xyz;  // 3 per vertex
  std::vector<int> tri;     // 3 per triangle
  size_t polygons = 0;      // faces with more than 3 corners (fan-triangulated)
  std::vector<PolygonFan> fans;  // those faces, for writing them back

  int num_vertices() const { return static_cast<int>(xyz.size() / 3); }
  size_t num_triangles() const { return tri.size() / 3; }
  void add_vertex(double x, double y, double z) {
    if (xyz.size() / 3 >= ctx_->vertex_cap()) ctx_->too_many_vertices();
    ctx_->tick();
    xyz.push_back(x);
    xyz.push_back(y);
    xyz.push_back(z);
  }
  // Fan triangulation around the first corner.
  void add_polygon(const int* idx, size_t k) {
    if (k < 3) return;
    if (k - 2 > ctx_->triangle_cap() - tri.size() / 3) ctx_->too_many_triangles();
    ctx_->tick();
    if (k > 3) {
      ++polygons;
      fans.push_back({static_cast<int>(tri.size() / 3), static_cast<int>(k)});
    }
    for (size_t c = 1; c + 1 < k; ++c) {
      tri.push_back(idx[0]);
      tri.push_back(idx[c]);
      tri.push_back(idx[c + 1]);
    }
  }
  // Reserve for n more vertices / triangles: only call with counts already checked against
  // the bytes present (never a bare header count).
  void reserve(size_t vertices, size_t triangles) {
    xyz.reserve(3 * std::min(vertices, ctx_->vertex_cap()));
    tri.reserve(3 * std::min(triangles, ctx_->triangle_cap()));
  }

 private:
  ReadContext* ctx_;
};

// Identity input layout; warns when polygons were triangulated. A soup without vertices
// fails with "NAME: no vertices found in the FORMAT file" (format = e.g. "OBJ").
LoadedMesh to_loaded(Soup&& s, const ReadContext& ctx, const char* format);

// ---------------------------------------------------------------------------------------
// Line and token helpers for the text formats.
class Lines {
 public:
  explicit Lines(std::string_view s) : s_(s) {}
  bool next(std::string_view& line) {
    if (pos_ >= s_.size()) return false;
    size_t e = s_.find('\n', pos_);
    if (e == std::string_view::npos) e = s_.size();
    line = s_.substr(pos_, e - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = e + 1;
    ++lineno_;
    return true;
  }
  int lineno() const { return lineno_; }
  size_t pos() const { return pos_; }

 private:
  std::string_view s_;
  size_t pos_ = 0;
  int lineno_ = 0;
};

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }

struct Cursor {
  const char* p;
  const char* e;
  explicit Cursor(std::string_view s) : p(s.data()), e(s.data() + s.size()) {}
  void skip_ws() {
    while (p < e && is_space(*p)) ++p;
  }
  bool at_end() {
    skip_ws();
    return p == e;
  }
  std::string_view token() {
    skip_ws();
    const char* b = p;
    while (p < e && !is_space(*p)) ++p;
    return {b, static_cast<size_t>(p - b)};
  }
  std::string_view peek_token() {
    Cursor c = *this;
    return c.token();
  }
  // A whole whitespace-delimited token that is a number (a leading '+' allowed).
  template <class T>
  bool read_number(T& v) {
    skip_ws();
    const char* q = p;
    if (q < e && *q == '+') ++q;
    auto r = std::from_chars(q, e, v);
    if (r.ec != std::errc() || (r.ptr < e && !is_space(*r.ptr))) return false;
    p = r.ptr;
    return true;
  }
  bool read_double(double& v) { return read_number(v); }
  bool read_int(long long& v) { return read_number(v); }
};

// Reads 3 coordinates from `c`, or throws "NAME:LINE: expected 3 coordinates ...".
void read_xyz(Cursor& c, const std::string& name, int line, double out[3]);

// A T stored at p (unaligned), byte-swapped when `swap`.
template <class T>
T load_raw(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// A vertex position as a hash key for welding by exact position (STL, glTF): the bits of
// x, y, z, with −0 folded into +0 so the two weld.
struct PosKey {
  std::array<uint64_t, 3> b;
  PosKey(double x, double y, double z) : b{bits(x), bits(y), bits(z)} {}
  bool operator==(const PosKey&) const = default;
  static uint64_t bits(double v) { return std::bit_cast<uint64_t>(v == 0 ? 0.0 : v); }
};
struct PosKeyHash {
  size_t operator()(const PosKey& k) const {
    uint64_t h = k.b[0] * 0x9E3779B97F4A7C15ULL;
    h ^= (k.b[1] + 0x632BE59BD9B4E019ULL + (h << 6) + (h >> 2));
    h ^= (k.b[2] * 0xC2B2AE3D27D4EB4FULL + (h << 6) + (h >> 2));
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

}  // namespace hdeform::detail

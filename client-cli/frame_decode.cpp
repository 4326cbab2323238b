#include "frame_decode.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <string>

namespace hdeform::cli {

static_assert(std::endian::native == std::endian::little,
              "frame buffers are little-endian: decoding assumes a little-endian host");

namespace {

constexpr std::size_t kQuantizedVertexBytes = 8;

void expect_size(const std::string& bytes, std::size_t want, const char* what) {
  if (bytes.size() != want)
    throw FrameDecodeError(std::string("frame ") + what + ": " + std::to_string(bytes.size()) +
                           " bytes, expected " + std::to_string(want));
}

std::vector<float> float32s(const std::string& bytes) {
  std::vector<float> out(bytes.size() / sizeof(float));
  if (!out.empty()) std::memcpy(out.data(), bytes.data(), out.size() * sizeof(float));
  return out;
}

// FLOAT64 buffers rounded to the float32 this struct holds (a watcher's view).
std::vector<float> float64s(const std::string& bytes) {
  std::vector<double> wide(bytes.size() / sizeof(double));
  if (!wide.empty()) std::memcpy(wide.data(), bytes.data(), wide.size() * sizeof(double));
  return std::vector<float>(wide.begin(), wide.end());
}

void dequantize(const unsigned char* vertices, std::size_t n, const v1::Box& box,
                DecodedFrame& out) {
  const double lo[3] = {box.min().x(), box.min().y(), box.min().z()};
  const double hi[3] = {box.max().x(), box.max().y(), box.max().z()};
  double step[3];
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(lo[k]) || !std::isfinite(hi[k]) || hi[k] < lo[k])
      throw FrameDecodeError("frame position_box is not a box (min > max or not finite)");
    step[k] = (hi[k] - lo[k]) / 65535.0;
  }
  out.positions.resize(3 * n);
  out.normals.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char* v = vertices + kQuantizedVertexBytes * i;
    std::uint16_t q[3];
    std::memcpy(q, v, sizeof q);
    for (int k = 0; k < 3; ++k) out.positions[3 * i + k] = static_cast<float>(lo[k] + q[k] * step[k]);
    octahedral_decode(static_cast<std::int8_t>(v[6]), static_cast<std::int8_t>(v[7]),
                      &out.normals[3 * i]);
  }
}

std::vector<unsigned char> unpack_meshopt(const std::string& bytes, std::size_t n) {
  std::vector<unsigned char> vertices(kQuantizedVertexBytes * n);
  if (meshopt_decodeVertexBuffer(vertices.data(), n, kQuantizedVertexBytes,
                                 reinterpret_cast<const unsigned char*>(bytes.data()),
                                 bytes.size()) != 0)
    throw FrameDecodeError("frame vertices: not a meshopt vertex buffer of " + std::to_string(n) +
                           " vertices of 8 bytes");
  return vertices;
}

void decode_energies(const v1::Frame& frame, std::size_t t, DecodedFrame& out) {
  if (frame.energies().empty()) return;
  expect_size(frame.energies(), 2 * t, "energies");
  if (!std::isfinite(frame.energies_max()) || frame.energies_max() < 0)
    throw FrameDecodeError("frame energies_max must be finite and not negative");
  out.energies.resize(t);
  for (std::size_t l = 0; l < t; ++l) {
    std::uint16_t q;
    std::memcpy(&q, frame.energies().data() + 2 * l, sizeof q);
    out.energies[l] = static_cast<float>(q * (double(frame.energies_max()) / 65535.0));
  }
}

std::uint16_t unzigzag16(std::uint16_t z) {
  return static_cast<std::uint16_t>((z >> 1) ^ static_cast<std::uint16_t>(-(z & 1)));
}
std::uint8_t unzigzag8(std::uint8_t z) {
  return static_cast<std::uint8_t>((z >> 1) ^ static_cast<std::uint8_t>(-(z & 1)));
}

}  // namespace

DecodedFrame FrameStreamDecoder::decode(const v1::Frame& frame, std::size_t n, std::size_t t) {
  if (frame.encoding() != v1::FRAME_ENCODING_MESHOPT_DELTA) {
    state_.clear();  // the server sends a key frame next
    return decode_frame(frame, n, t);
  }
  DecodedFrame out;
  if (frame.superseded() || frame.vertices().empty()) {
    decode_energies(frame, t, out);
    return out;
  }
  // Taken, not kept: after a frame that fails, every delta fails until the next key frame.
  const std::vector<unsigned char> before = std::move(state_);
  state_.clear();
  std::vector<unsigned char> vertices = unpack_meshopt(frame.vertices(), n);
  if (frame.delta()) {
    if (before.size() != vertices.size())
      throw FrameDecodeError(before.empty()
                                 ? "frame is a MESHOPT_DELTA delta but no key frame came before it"
                                 : "frame is a MESHOPT_DELTA delta for another vertex count");
    for (std::size_t o = 0; o < vertices.size(); o += kQuantizedVertexBytes) {
      for (std::size_t k = 0; k < 6; k += 2) {
        std::uint16_t z, was;
        std::memcpy(&z, &vertices[o + k], 2);
        std::memcpy(&was, &before[o + k], 2);
        const auto now = static_cast<std::uint16_t>(was + unzigzag16(z));
        std::memcpy(&vertices[o + k], &now, 2);
      }
      for (std::size_t k = 6; k < 8; ++k)
        vertices[o + k] = static_cast<unsigned char>(before[o + k] + unzigzag8(vertices[o + k]));
    }
  }
  dequantize(vertices.data(), n, frame.position_box(), out);
  decode_energies(frame, t, out);
  state_ = std::move(vertices);
  return out;
}

void octahedral_decode(std::int8_t qu, std::int8_t qv, float out[3]) {
  float u = std::max(qu / 127.0f, -1.0f), v = std::max(qv / 127.0f, -1.0f);
  float z = 1.0f - std::abs(u) - std::abs(v);
  if (z < 0) {
    const float fu = (1.0f - std::abs(v)) * (u >= 0 ? 1.0f : -1.0f);
    const float fv = (1.0f - std::abs(u)) * (v >= 0 ? 1.0f : -1.0f);
    u = fu;
    v = fv;
  }
  const float len = std::sqrt(u * u + v * v + z * z);
  out[0] = u / len;
  out[1] = v / len;
  out[2] = z / len;
}

std::size_t frame_buffer_bytes(const v1::Frame& f) {
  return f.positions().size() + f.normals().size() + f.vertices().size() + f.energies().size();
}

DecodedFrame decode_frame(const v1::Frame& frame, std::size_t n, std::size_t t) {
  DecodedFrame out;
  if (frame.superseded()) return out;
  switch (frame.encoding()) {
    case v1::FRAME_ENCODING_FLOAT32:
      expect_size(frame.positions(), 12 * n, "positions");
      out.positions = float32s(frame.positions());
      if (!frame.normals().empty()) {
        expect_size(frame.normals(), 12 * n, "normals");
        out.normals = float32s(frame.normals());
      }
      if (!frame.energies().empty()) {
        expect_size(frame.energies(), 4 * t, "energies");
        out.energies = float32s(frame.energies());
      }
      return out;
    case v1::FRAME_ENCODING_FLOAT64:
      expect_size(frame.positions(), 24 * n, "positions");
      out.positions = float64s(frame.positions());
      if (!frame.normals().empty()) {
        expect_size(frame.normals(), 24 * n, "normals");
        out.normals = float64s(frame.normals());
      }
      if (!frame.energies().empty()) {
        expect_size(frame.energies(), 4 * t, "energies");
        out.energies = float32s(frame.energies());
      }
      return out;
    case v1::FRAME_ENCODING_QUANTIZED:
    case v1::FRAME_ENCODING_MESHOPT: {
      const std::string& bytes = frame.vertices();
      std::vector<unsigned char> vertices;
      const unsigned char* raw = reinterpret_cast<const unsigned char*>(bytes.data());
      if (frame.encoding() == v1::FRAME_ENCODING_QUANTIZED) {
        expect_size(bytes, kQuantizedVertexBytes * n, "vertices");
      } else {
        vertices = unpack_meshopt(bytes, n);
        raw = vertices.data();
      }
      dequantize(raw, n, frame.position_box(), out);
      decode_energies(frame, t, out);
      return out;
    }
    case v1::FRAME_ENCODING_MESHOPT_DELTA:
      throw FrameDecodeError(
          "frame encoding MESHOPT_DELTA needs the stream's previous frames (FrameStreamDecoder)");
    default:
      throw FrameDecodeError("frame encoding " + std::to_string(frame.encoding()) +
                             " is unknown to this client");
  }
}

}  // namespace hdeform::cli

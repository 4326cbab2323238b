// libFuzzer target for the client's frame decoder (client-cli/frame_decode.h): a client must
// survive whatever bytes a server (or a man in the middle) sends. Input: byte 0 picks a mode.
//   0: bytes 1–4 vertex count, 5–8 triangle count (both small), the rest a serialized Frame:
//      decode_frame returns buffers of the right sizes or throws FrameDecodeError; so does a
//      FrameStreamDecoder fed it as a key frame, then as it is, twice (MESHOPT_DELTA).
//   1: the rest is a QUANTIZED vertex buffer: meshopt-encoded then decoded through a Frame, it
//      must come back with the same quantized values (checked through the dequantized box).
#include "frame_decode.h"

#include <meshoptimizer.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace {

std::uint32_t read_u32(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

void check_sizes(const hdeform::cli::DecodedFrame& d, std::size_t n, std::size_t t) {
  if (d.positions.size() != 3 * n) __builtin_trap();
  if (!d.normals.empty() && d.normals.size() != 3 * n) __builtin_trap();
  if (!d.energies.empty() && d.energies.size() != t) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace pb = hdeform::v1;
  if (size < 1) return 0;
  if (data[0] % 2 == 0) {
    if (size < 9) return 0;
    const std::size_t n = read_u32(data + 1) % 4096, t = read_u32(data + 5) % 8192;
    pb::Frame frame;
    if (!frame.ParseFromArray(data + 9, static_cast<int>(size - 9))) return 0;
    try {
      const auto d = hdeform::cli::decode_frame(frame, n, t);
      if (!frame.superseded()) check_sizes(d, n, t);
    } catch (const hdeform::cli::FrameDecodeError&) {
    }
    // A stream: the frame as a key frame, then as it is (a MESHOPT_DELTA delta builds on the
    // key frame), then once more.
    hdeform::cli::FrameStreamDecoder stream;
    pb::Frame key = frame;
    key.set_delta(false);
    for (const pb::Frame* f : {&key, &frame, &frame}) {
      try {
        const auto d = stream.decode(*f, n, t);
        if (!f->superseded() && !(f->encoding() == pb::FRAME_ENCODING_MESHOPT_DELTA &&
                                  f->vertices().empty()))
          check_sizes(d, n, t);
      } catch (const hdeform::cli::FrameDecodeError&) {
      }
    }
    return 0;
  }
  const std::size_t n = (size - 1) / 8;
  std::string raw(reinterpret_cast<const char*>(data + 1), 8 * n);
  std::string encoded(meshopt_encodeVertexBufferBound(n, 8), '\0');
  encoded.resize(meshopt_encodeVertexBuffer(reinterpret_cast<unsigned char*>(encoded.data()),
                                            encoded.size(), raw.data(), n, 8));
  pb::Frame frame;
  frame.set_encoding(pb::FRAME_ENCODING_MESHOPT);
  frame.set_vertices(encoded);
  auto* box = frame.mutable_position_box();
  box->mutable_max()->set_x(65535);  // q decodes to itself
  box->mutable_max()->set_y(65535);
  box->mutable_max()->set_z(65535);
  const auto d = hdeform::cli::decode_frame(frame, n, 0);  // must not throw
  check_sizes(d, n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      std::uint16_t q;
      std::memcpy(&q, raw.data() + 8 * i + 2 * k, 2);
      if (d.positions[3 * i + k] != static_cast<float>(q)) __builtin_trap();
    }
  return 0;
}

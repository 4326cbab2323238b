// Client side of the frame encodings (proto FrameEncoding): a Frame's buffers back to float32
// arrays, whatever encoding the server used. Used by `hdeform watch`; the service tests check
// it against the server's encoder (tests/service/test_frame_encoding.cpp).
#pragma once

#include "hdeform/v1/deform.pb.h"

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace hdeform::cli {

// A frame whose buffers do not match its encoding or the session's sizes.
struct FrameDecodeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct DecodedFrame {
  std::vector<float> positions;  // 3 per vertex, base-GLB order (model units)
  std::vector<float> normals;    // 3 per vertex (unit), empty if the frame has none
  std::vector<float> energies;   // 1 per triangle, empty if the frame has none
};

// `vertex_count` / `triangle_count`: the session's (Session.vertex_count, .triangle_count).
// Throws FrameDecodeError naming the buffer and the size it expected. MESHOPT_DELTA frames
// need the stream's previous frames: FrameStreamDecoder.
DecodedFrame decode_frame(const v1::Frame& frame, std::size_t vertex_count,
                          std::size_t triangle_count);

// The frames of one stream, in order, in any encoding: keeps the quantized vertices of the
// last MESHOPT_DELTA frame for the deltas that follow. After a frame that fails to decode,
// every delta fails until the next key frame (watch anew).
class FrameStreamDecoder {
 public:
  DecodedFrame decode(const v1::Frame& frame, std::size_t vertex_count, std::size_t triangle_count);

 private:
  std::vector<unsigned char> state_;  // 8 bytes per vertex: the last frame, quantized
};

// One int8 octahedral pair back to a unit vector (deform.proto's formula).
void octahedral_decode(std::int8_t qu, std::int8_t qv, float out[3]);

// Bytes of buffer payload a frame carries (positions, normals, vertices, energies).
std::size_t frame_buffer_bytes(const v1::Frame& frame);

}  // namespace hdeform::cli

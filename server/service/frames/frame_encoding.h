// Frame buffer encodings (proto FrameEncoding): FLOAT32 as Session::update makes frames,
// QUANTIZED (8 bytes per vertex: 3 × uint16 position in the frame's box, 2 × int8
// octahedral normal; uint16 energies) and MESHOPT (the quantized vertices through
// meshoptimizer's vertex codec); MESHOPT_DELTA's per-stream state is frame_delta.h. The
// formats are specified in deform.proto; clients decode them with client-cli/frame_decode.h
// (C++) or the viewer's decoders.
#pragma once

#include "hdeform/v1/deform.pb.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace hdeform::service {

inline constexpr std::size_t kQuantizedVertexBytes = 8;

// Fails with INVALID_ARGUMENT naming `where` when `format` asks for an encoding this server does not
// know (a newer client's enum value), or for MESHOPT_DELTA where frames may be dropped or
// reordered (`in_order_stream` false: Deform coalesces its frames, UpdateHandles has no stream).
void check_frame_format(const v1::FrameFormat& format, const char* where,
                        bool in_order_stream = false);

// The encoding `frame` (a FLOAT32 frame) goes out in for a client that asked for `format`.
v1::FrameEncoding encoding_for(const v1::Frame& frame, const v1::FrameFormat& format);

// `frame` (FLOAT32, as Session::update makes it) for a client that asked for `format`: the
// same pointer when nothing changes, else a new frame with every non-buffer field copied
// and the buffers encoded. `omit_buffers`: no buffers at all (UpdateHandlesRequest).
std::shared_ptr<const v1::Frame> encode_frame(std::shared_ptr<const v1::Frame> frame,
                                              const v1::FrameFormat& format,
                                              bool omit_buffers = false);
// The same into `out` (cleared first); false, and `out` untouched, when `frame` goes out as
// it is.
bool encode_frame_to(const v1::Frame& frame, const v1::FrameFormat& format, bool omit_buffers,
                     v1::Frame* out);

// Every field of `in` but its buffers (positions, normals, energies, vertices,
// position_box, energies_max, delta), and encoding FLOAT32.
void copy_frame_header(const v1::Frame& in, v1::Frame* out);

// The QUANTIZED vertex buffer (8 bytes per vertex) of float32 xyz positions and normals
// (`normals` empty: the normal bytes are 0), and the box it spans. Preconditions: positions
// finite; both spans 3 floats per vertex.
std::string quantize_vertices(std::span<const float> positions, std::span<const float> normals,
                              v1::Box* box);

// The bounding box of xyz positions (3 floats per vertex); all zero when there are none.
v1::Box bounding_box(std::span<const float> positions);

// The QUANTIZED vertex bytes of `positions` and `normals` (empty: normal bytes 0) on the grid
// `box` into `out` (8 bytes per vertex, every vertex written). False when a position lies
// outside the box (it is then clamped to it) or is NaN.
bool quantize_onto(std::span<const float> positions, std::span<const float> normals,
                   const v1::Box& box, unsigned char* out);

// The two int8 octahedral components of a unit vector (any non-zero vector: it is
// normalized by the L1 norm first).
void octahedral_encode(const float n[3], std::int8_t out[2]);

// QUANTIZED energies: uint16 per triangle (rounded to nearest) and the scale energies_max.
std::string quantize_energies(std::span<const float> energies, float* energies_max);

// `frame`'s FLOAT32 energies, if any, as QUANTIZED energies and energies_max of `out`.
void set_quantized_energies(const v1::Frame& frame, v1::Frame* out);

// meshoptimizer's vertex codec over `vertices` (vertex_size bytes each, a multiple of 4).
std::string meshopt_encode(std::string_view vertices, std::size_t vertex_size);

}  // namespace hdeform::service

// FRAME_ENCODING_MESHOPT_DELTA for one stream (deform.proto, FrameEncoding): each frame is the
// difference to the previous one on a key frame's fixed grid, which meshopt's vertex codec
// packs far tighter than absolute positions while a drag moves the mesh a little per frame.
#pragma once

#include "hdeform/v1/deform.pb.h"

#include <cstdint>
#include <string>

namespace hdeform::service {

// Not thread-safe: one per stream, used in the stream's write order (from any thread: its
// scratch buffers are per thread). Holds 8 bytes per vertex.
class FrameDeltaEncoder {
 public:
  // The grid a key frame sets: the frame's bounding box grown by this fraction of its largest
  // side on each side of every axis, so that the frames of a drag stay on it.
  static constexpr double kGridMargin = 0.125;

  // `frame` (FLOAT32, as Session::update makes it) into `out` (cleared first): every non-buffer
  // field copied, encoding MESHOPT_DELTA, and a key frame or a delta to the frame of the
  // previous call. A frame without positions (superseded) goes out without buffers and
  // changes nothing.
  void encode(const v1::Frame& frame, v1::Frame* out);

  // The stream sent something else since (a FLOAT32 exact frame): the next frame is a key frame.
  void reset() { has_reference_ = false; }

  std::uint64_t key_frames() const { return key_frames_; }
  std::uint64_t delta_frames() const { return delta_frames_; }

 private:
  bool has_reference_ = false, reference_has_normals_ = false;
  v1::Box grid_;
  std::string reference_;  // the last frame encoded, quantized: 8 bytes per vertex
  std::uint64_t key_frames_ = 0, delta_frames_ = 0;
};

}  // namespace hdeform::service

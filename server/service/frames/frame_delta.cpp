#include "service/frames/frame_delta.h"

#include "service/frames/frame_encoding.h"

#include <algorithm>
#include <cstring>
#include <span>

namespace hdeform::service {

namespace {

std::span<const float> floats(const std::string& bytes) {
  return {reinterpret_cast<const float*>(bytes.data()), bytes.size() / sizeof(float)};
}

// Zigzag: small differences of either sign become small unsigned numbers, whose high bits
// meshopt's codec then sends as nearly nothing.
std::uint16_t zigzag16(std::uint16_t now, std::uint16_t before) {
  const auto d = static_cast<std::int16_t>(static_cast<std::uint16_t>(now - before));
  return static_cast<std::uint16_t>((static_cast<std::uint16_t>(d) << 1) ^ (d >> 15));
}
std::uint8_t zigzag8(std::uint8_t now, std::uint8_t before) {
  const auto d = static_cast<std::int8_t>(static_cast<std::uint8_t>(now - before));
  return static_cast<std::uint8_t>((static_cast<std::uint8_t>(d) << 1) ^ (d >> 7));
}

// `box` grown by `margin` × its largest side on each side of every axis.
v1::Box grown(const v1::Box& box, double margin) {
  const double side = std::max({box.max().x() - box.min().x(), box.max().y() - box.min().y(),
                                box.max().z() - box.min().z()});
  const auto m = static_cast<float>(margin * side);
  v1::Box out;
  out.mutable_min()->set_x(box.min().x() - m);
  out.mutable_min()->set_y(box.min().y() - m);
  out.mutable_min()->set_z(box.min().z() - m);
  out.mutable_max()->set_x(box.max().x() + m);
  out.mutable_max()->set_y(box.max().y() + m);
  out.mutable_max()->set_z(box.max().z() + m);
  return out;
}

}  // namespace

void FrameDeltaEncoder::encode(const v1::Frame& frame, v1::Frame* out) {
  out->Clear();
  copy_frame_header(frame, out);
  out->set_encoding(v1::FRAME_ENCODING_MESHOPT_DELTA);
  set_quantized_energies(frame, out);
  const auto p = floats(frame.positions());
  const auto nrm = floats(frame.normals());
  if (p.empty()) return;  // superseded: nothing to send, nothing the client's state changes by
  const std::size_t n = p.size() / 3;
  const bool has_normals = nrm.size() == p.size();
  // Scratch per thread, not per watcher: a watcher keeps only its reference (8 bytes a vertex).
  thread_local std::string current, deltas;
  current.resize(kQuantizedVertexBytes * n);
  auto* now = reinterpret_cast<unsigned char*>(current.data());
  bool key = !has_reference_ || reference_.size() != current.size() ||
             reference_has_normals_ != has_normals || !quantize_onto(p, nrm, grid_, now);
  if (key) {
    grid_ = grown(bounding_box(p), kGridMargin);
    quantize_onto(p, nrm, grid_, now);  // inside: the grid holds the box with room to spare
    out->set_vertices(meshopt_encode(current, kQuantizedVertexBytes));
    ++key_frames_;
  } else {
    deltas.resize(current.size());
    const auto* before = reinterpret_cast<const unsigned char*>(reference_.data());
    auto* d = reinterpret_cast<unsigned char*>(deltas.data());
#pragma omp parallel for schedule(static) if (n >= 16384)  // smaller: waking the team costs more
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t o = kQuantizedVertexBytes * i;
      for (int k = 0; k < 3; ++k) {
        std::uint16_t a, b;
        std::memcpy(&a, now + o + 2 * k, 2);
        std::memcpy(&b, before + o + 2 * k, 2);
        const std::uint16_t z = zigzag16(a, b);
        std::memcpy(d + o + 2 * k, &z, 2);
      }
      d[o + 6] = zigzag8(now[o + 6], before[o + 6]);
      d[o + 7] = zigzag8(now[o + 7], before[o + 7]);
    }
    out->set_vertices(meshopt_encode(deltas, kQuantizedVertexBytes));
    out->set_delta(true);
    ++delta_frames_;
  }
  *out->mutable_position_box() = grid_;
  std::swap(reference_, current);  // the old reference is this thread's next scratch
  reference_has_normals_ = has_normals;
  has_reference_ = true;
}

}  // namespace hdeform::service

#include "frame_encoding.h"

#include "errors.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

namespace hdeform::service {

static_assert(std::endian::native == std::endian::little,
              "frame buffers are written as native integers: little-endian hosts only");

namespace {

std::span<const float> floats(const std::string& bytes) {
  return {reinterpret_cast<const float*>(bytes.data()), bytes.size() / sizeof(float)};
}

std::uint16_t to_u16(float t) {  // t in [0, 1] (clamped): nearest of 65536 levels
  return static_cast<std::uint16_t>(std::lrintf(std::clamp(t, 0.0f, 1.0f) * 65535.0f));
}

}  // namespace

void check_frame_format(const v1::FrameFormat& format, const char* where, bool in_order_stream) {
  if (!v1::FrameEncoding_IsValid(format.encoding()))
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(where) + ": unknown frame encoding " + std::to_string(format.encoding()) +
             " (this server knows FLOAT32 = 0, QUANTIZED = 1, MESHOPT = 2, MESHOPT_DELTA = 3)");
  if (format.encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA && !in_order_stream)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(where) +
             ": frame encoding MESHOPT_DELTA needs a stream that carries every frame it encodes "
             "(WatchSession); use MESHOPT here");
}

v1::FrameEncoding encoding_for(const v1::Frame& frame, const v1::FrameFormat& format) {
  if (format.exact_as_float32() && frame.exact()) return v1::FRAME_ENCODING_FLOAT32;
  return format.encoding();
}

void copy_frame_header(const v1::Frame& in, v1::Frame* out) {
  out->set_session(in.session());
  out->set_sequence(in.sequence());
  out->set_version(in.version());
  if (in.has_measures()) *out->mutable_measures() = in.measures();
  if (in.has_beta()) *out->mutable_beta() = in.beta();
  out->set_solve_ms(in.solve_ms());
  out->set_exact(in.exact());
  out->set_superseded(in.superseded());
  out->set_client_id(in.client_id());
  *out->mutable_transforms() = in.transforms();
  out->set_encoding(v1::FRAME_ENCODING_FLOAT32);
}

void octahedral_encode(const float n[3], std::int8_t out[2]) {
  // Float math and lrintf (one instruction each): this runs for every vertex of every frame.
  const float l1 = std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]);
  const float inv = l1 > 0 ? 1.0f / l1 : 0.0f;
  float u = n[0] * inv, v = n[1] * inv;
  if (n[2] < 0) {  // fold the lower hemisphere over the diagonals
    const float fu = (1 - std::abs(v)) * (u >= 0 ? 1.0f : -1.0f);
    const float fv = (1 - std::abs(u)) * (v >= 0 ? 1.0f : -1.0f);
    u = fu;
    v = fv;
  }
  out[0] = static_cast<std::int8_t>(std::lrintf(std::clamp(u, -1.0f, 1.0f) * 127.0f));
  out[1] = static_cast<std::int8_t>(std::lrintf(std::clamp(v, -1.0f, 1.0f) * 127.0f));
}

v1::Box bounding_box(std::span<const float> p) {
  const std::size_t n = p.size() / 3;
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  if (n > 0) {
    for (int k = 0; k < 3; ++k) lo[k] = hi[k] = p[k];
    for (std::size_t i = 1; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], p[3 * i + k]);
        hi[k] = std::max(hi[k], p[3 * i + k]);
      }
  }
  v1::Box box;
  box.mutable_min()->set_x(lo[0]);
  box.mutable_min()->set_y(lo[1]);
  box.mutable_min()->set_z(lo[2]);
  box.mutable_max()->set_x(hi[0]);
  box.mutable_max()->set_y(hi[1]);
  box.mutable_max()->set_z(hi[2]);
  return box;
}

bool quantize_onto(std::span<const float> p, std::span<const float> nrm, const v1::Box& box,
                   unsigned char* out) {
  const double lo[3] = {box.min().x(), box.min().y(), box.min().z()};
  const double hi[3] = {box.max().x(), box.max().y(), box.max().z()};
  double scale[3];  // q = (x − lo) · 65535 / extent, in double: float would lose the last bits
  for (int k = 0; k < 3; ++k) {
    const double extent = hi[k] - lo[k];
    scale[k] = extent > 0 ? 65535.0 / extent : 0.0;  // a flat axis: every q is 0, decoded as min
  }
  const std::size_t n = p.size() / 3;
  const bool has_normals = nrm.size() == p.size();
  bool inside = true;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint16_t q[3];
    for (int k = 0; k < 3; ++k) {
      const double x = p[3 * i + k];
      const double t = (x - lo[k]) * scale[k];
      // Outside: rounds below 0 or above 65535, or off a flat axis. NaN fails both tests.
      if (!(t >= -0.5 && t < 65535.5) || (scale[k] == 0 && x != lo[k])) inside = false;
      q[k] = static_cast<std::uint16_t>(std::clamp(std::lrint(t), 0L, 65535L));
    }
    unsigned char* v = out + kQuantizedVertexBytes * i;
    std::memcpy(v, q, sizeof q);
    if (has_normals)
      octahedral_encode(&nrm[3 * i], reinterpret_cast<std::int8_t*>(v + 6));
    else
      v[6] = v[7] = 0;
  }
  return inside;
}

std::string quantize_vertices(std::span<const float> p, std::span<const float> nrm,
                              v1::Box* box) {
  *box = bounding_box(p);
  std::string out(kQuantizedVertexBytes * (p.size() / 3), '\0');
  quantize_onto(p, nrm, *box, reinterpret_cast<unsigned char*>(out.data()));  // inside by construction
  return out;
}

std::string quantize_energies(std::span<const float> e, float* energies_max) {
  float top = 0;
  for (float x : e)
    if (std::isfinite(x)) top = std::max(top, x);
  *energies_max = top;
  std::string out(sizeof(std::uint16_t) * e.size(), '\0');
  auto* q = reinterpret_cast<std::uint16_t*>(out.data());
  const float inv = top > 0 ? 1.0f / top : 0.0f;
  for (std::size_t l = 0; l < e.size(); ++l)
    q[l] = std::isfinite(e[l]) ? to_u16(e[l] * inv) : std::uint16_t{65535};
  return out;
}

void set_quantized_energies(const v1::Frame& frame, v1::Frame* out) {
  if (frame.energies().empty()) return;
  float top = 0;
  out->set_energies(quantize_energies(floats(frame.energies()), &top));
  out->set_energies_max(top);
}

std::string meshopt_encode(std::string_view vertices, std::size_t vertex_size) {
  const std::size_t count = vertices.size() / vertex_size;
  std::string out(meshopt_encodeVertexBufferBound(count, vertex_size), '\0');
  const std::size_t size =
      meshopt_encodeVertexBuffer(reinterpret_cast<unsigned char*>(out.data()), out.size(),
                                 vertices.data(), count, vertex_size);
  out.resize(size);
  return out;
}

bool encode_frame_to(const v1::Frame& frame, const v1::FrameFormat& format, bool omit_buffers,
                     v1::Frame* out) {
  const v1::FrameEncoding encoding = encoding_for(frame, format);
  if (!omit_buffers && encoding == v1::FRAME_ENCODING_FLOAT32) return false;
  out->Clear();
  copy_frame_header(frame, out);
  if (omit_buffers || frame.superseded()) return true;
  out->set_encoding(encoding);
  std::string vertices = quantize_vertices(floats(frame.positions()), floats(frame.normals()),
                                           out->mutable_position_box());
  if (encoding == v1::FRAME_ENCODING_MESHOPT || encoding == v1::FRAME_ENCODING_MESHOPT_DELTA)
    vertices = meshopt_encode(vertices, kQuantizedVertexBytes);
  out->set_vertices(std::move(vertices));
  set_quantized_energies(frame, out);
  return true;
}

std::shared_ptr<const v1::Frame> encode_frame(std::shared_ptr<const v1::Frame> frame,
                                              const v1::FrameFormat& format, bool omit_buffers) {
  auto out = std::make_shared<v1::Frame>();
  if (!encode_frame_to(*frame, format, omit_buffers, out.get())) return frame;
  return out;
}

}  // namespace hdeform::service

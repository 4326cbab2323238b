#include "service/frames/frame_encoding.h"

#include "engine/simd/cpu_features.h"
#include "service/frames/quantize_kernel.h"
#include "service/infra/service_error.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

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
             " (this server knows FLOAT32 = 0, QUANTIZED = 1, MESHOPT = 2, MESHOPT_DELTA = 3, "
             "FLOAT64 = 4)");
  if (format.encoding() == v1::FRAME_ENCODING_MESHOPT_DELTA && !in_order_stream)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(where) +
             ": frame encoding MESHOPT_DELTA needs a stream that carries every frame it encodes "
             "(WatchSession); use MESHOPT here");
  if (format.encoding() == v1::FRAME_ENCODING_FLOAT64 && in_order_stream)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(where) +
             ": frame encoding FLOAT64 is for a client's own frames (UpdateHandles, Deform); "
             "watchers share float32 frames: use FLOAT32 here");
}

v1::FrameEncoding encoding_for(const v1::Frame& frame, const v1::FrameFormat& format) {
  if (format.encoding() == v1::FRAME_ENCODING_FLOAT64) return v1::FRAME_ENCODING_FLOAT64;
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

namespace {

// Per vertex of every frame: float math and lrintf (one instruction each without errno,
// CMakeLists.txt), inlined into detail::quantize_range's loop.
inline void octahedral(const float n[3], std::int8_t out[2]) {
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

}  // namespace

void octahedral_encode(const float n[3], std::int8_t out[2]) { octahedral(n, out); }

v1::Box bounding_box(std::span<const float> p) {
  const std::size_t n = p.size() / 3;
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  if (n > 0) {
    for (int k = 0; k < 3; ++k) lo[k] = hi[k] = p[k];
    std::size_t done = 1;
#ifdef HDEFORM_HAVE_AVX2_KERNELS
    if (kernel_isa() == Isa::avx2) done += detail::box_range_avx2(p.data(), 1, n, lo, hi);
#endif
    detail::box_range(p.data(), done, n, lo, hi);
    // min and max are exact, so any order of the loop gives the same box but for the sign of
    // a zero: + 0 makes it +0.
    for (int k = 0; k < 3; ++k) {
      lo[k] += 0.0f;
      hi[k] += 0.0f;
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

namespace detail {

void box_range(const float* p, std::size_t begin, std::size_t end, float lo[3], float hi[3]) {
  for (std::size_t i = begin; i < end; ++i)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[3 * i + k]);
      hi[k] = std::max(hi[k], p[3 * i + k]);
    }
}

void max_finite_range(const float* e, std::size_t begin, std::size_t end, float* top) {
  for (std::size_t l = begin; l < end; ++l)
    if (std::isfinite(e[l])) *top = std::max(*top, e[l]);
}

void quantize_energy_range(const float* e, std::size_t begin, std::size_t end, float inv,
                           std::uint16_t* q) {
  for (std::size_t l = begin; l < end; ++l)
    q[l] = std::isfinite(e[l]) ? to_u16(e[l] * inv) : std::uint16_t{65535};
}

bool quantize_range(const float* p, const float* nrm, std::size_t begin, std::size_t end,
                    const QuantizeGrid& grid, unsigned char* out) {
  bool inside = true;
  for (std::size_t i = begin; i < end; ++i) {
    std::uint16_t q[3];
    for (int k = 0; k < 3; ++k) {
      const double x = p[3 * i + k];
      const double t = (x - grid.lo[k]) * grid.scale[k];
      // Outside: rounds below 0 or above 65535, or off a flat axis. NaN fails both tests.
      if (!(t >= -0.5 && t < 65535.5) || (grid.scale[k] == 0 && x != grid.lo[k])) inside = false;
      // Clamped before rounding (NaN to 0), as the AVX2 build's max and min do.
      q[k] = static_cast<std::uint16_t>(std::lrint(t > 0 ? std::min(t, 65535.0) : 0.0));
    }
    unsigned char* v = out + kQuantizedVertexBytes * i;
    std::memcpy(v, q, sizeof q);
    if (nrm)
      octahedral(&nrm[3 * i], reinterpret_cast<std::int8_t*>(v + 6));
    else
      v[6] = v[7] = 0;
  }
  return inside;
}

}  // namespace detail

bool quantize_onto(std::span<const float> p, std::span<const float> nrm, const v1::Box& box,
                   unsigned char* out) {
  detail::QuantizeGrid grid{{box.min().x(), box.min().y(), box.min().z()}, {}};
  const double hi[3] = {box.max().x(), box.max().y(), box.max().z()};
  for (int k = 0; k < 3; ++k) {
    const double extent = hi[k] - grid.lo[k];
    grid.scale[k] = extent > 0 ? 65535.0 / extent : 0.0;
  }
  const std::size_t n = p.size() / 3;
  const float* normals = nrm.size() == p.size() ? nrm.data() : nullptr;
  bool inside = true;
#ifdef HDEFORM_HAVE_AVX2_KERNELS
  if (kernel_isa() == Isa::avx2) {  // one thread: waking a team costs more than the loop
    const std::size_t done = detail::quantize_range_avx2(p.data(), normals, 0, n, grid, out, &inside);
    return detail::quantize_range(p.data(), normals, done, n, grid, out) && inside;
  }
#endif
  constexpr std::size_t kChunk = 8192;  // the generic loop on the team, from 2 chunks up
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) if (chunks >= 2) reduction(&& : inside)
  for (std::size_t c = 0; c < chunks; ++c)
    inside = detail::quantize_range(p.data(), normals, c * kChunk, std::min(n, (c + 1) * kChunk),
                                    grid, out) && inside;
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
  [[maybe_unused]] const bool avx2 = kernel_isa() == Isa::avx2;
  float top = 0;
  std::size_t done = 0;
#ifdef HDEFORM_HAVE_AVX2_KERNELS
  if (avx2) done = detail::max_finite_range_avx2(e.data(), 0, e.size(), &top);
#endif
  detail::max_finite_range(e.data(), done, e.size(), &top);
  *energies_max = top;
  std::string out(sizeof(std::uint16_t) * e.size(), '\0');
  auto* q = reinterpret_cast<std::uint16_t*>(out.data());
  const float inv = top > 0 ? 1.0f / top : 0.0f;
  done = 0;
#ifdef HDEFORM_HAVE_AVX2_KERNELS
  if (avx2) done = detail::quantize_energy_range_avx2(e.data(), 0, e.size(), inv, q);
#endif
  detail::quantize_energy_range(e.data(), done, e.size(), inv, q);
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
  // The codec writes into a buffer per thread sized to its bound (1.2 MB at 100K, about
  // 2.5 times what it writes): a fresh zero-filled string per frame cost a memset and
  // fresh pages.
  thread_local std::vector<unsigned char> scratch;
  scratch.resize(meshopt_encodeVertexBufferBound(count, vertex_size));
  const std::size_t size = meshopt_encodeVertexBuffer(scratch.data(), scratch.size(),
                                                      vertices.data(), count, vertex_size);
  return std::string(reinterpret_cast<const char*>(scratch.data()), size);
}

bool encode_frame_to(const v1::Frame& frame, const v1::FrameFormat& format, bool omit_buffers,
                     v1::Frame* out) {
  const v1::FrameEncoding encoding = encoding_for(frame, format);
  // FLOAT64 buffers are made by the session (Session::Update::float64); the frame's own
  // `encoding` says which it carries.
  if (!omit_buffers &&
      (encoding == v1::FRAME_ENCODING_FLOAT32 || encoding == v1::FRAME_ENCODING_FLOAT64))
    return false;
  out->Clear();
  copy_frame_header(frame, out);
  if (omit_buffers || frame.superseded()) return true;
  out->set_encoding(encoding);
  const auto p = floats(frame.positions());
  if (encoding == v1::FRAME_ENCODING_QUANTIZED) {
    out->set_vertices(quantize_vertices(p, floats(frame.normals()), out->mutable_position_box()));
  } else {  // MESHOPT (MESHOPT_DELTA's watchers have their own encoder: frame_delta.h)
    thread_local std::vector<unsigned char> quantized;  // scratch, as in meshopt_encode
    quantized.resize(kQuantizedVertexBytes * (p.size() / 3));
    *out->mutable_position_box() = bounding_box(p);
    quantize_onto(p, floats(frame.normals()), out->position_box(), quantized.data());
    out->set_vertices(meshopt_encode(
        {reinterpret_cast<const char*>(quantized.data()), quantized.size()}, kQuantizedVertexBytes));
  }
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

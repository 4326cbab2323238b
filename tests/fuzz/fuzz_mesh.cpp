// libFuzzer target for one mesh reader: read_mesh_bytes(data, HDEFORM_FUZZ_FILENAME), the
// upload path of the service (no file system access). A reader may only throw InvalidInput
// (or LimitExceeded, one of them); anything else — another exception, a sanitizer report,
// a timeout or an allocation beyond -rss_limit_mb — is a bug. A mesh that is read must be
// consistent: every index in range, the input layout as long as its map. The input's size
// picks the limits, so the limit and cancellation paths are fuzzed too: size % 4 == 1 →
// at most 40 vertices and 60 triangles; == 2 → cancelled at the second poll (ReadCancelled
// is then allowed); == 3 → the upload's opt-in repair runs on what was read (its tolerance
// from the first byte), which must keep the same invariants and be idempotent.
#include "engine/io/mesh_io.h"
#include "engine/io/repair_loaded.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

#ifndef HDEFORM_FUZZ_FILENAME
#error "define HDEFORM_FUZZ_FILENAME (e.g. \"fuzz.obj\"): the extension picks the reader"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  hdeform::ReadLimits limits;
  int polls = 0;
  if (size % 4 == 1) {
    limits.max_vertices = 40;
    limits.max_triangles = 60;
  } else if (size % 4 == 2) {
    limits.should_cancel = [&polls] { return ++polls >= 2; };
  }
  try {
    hdeform::LoadedMesh m = hdeform::read_mesh_bytes(bytes, HDEFORM_FUZZ_FILENAME, limits);
    if (size % 4 == 3) {
      const double tolerance = (data[0] % 3) * 1e-3;
      hdeform::repair_loaded_mesh(m, {tolerance});
      if (hdeform::repair_mesh(m.mesh, {tolerance}).report.changed()) __builtin_trap();
      for (const int v : m.repair_to_input)
        if (v < 0) __builtin_trap();
    }
    if (limits.max_vertices > 0 && static_cast<std::size_t>(m.input_to_engine.size()) > limits.max_vertices)
      __builtin_trap();
    if (limits.max_triangles > 0 && static_cast<std::size_t>(m.input_triangles.rows()) > limits.max_triangles)
      __builtin_trap();
    const Eigen::Index n = m.mesh.V.rows();
    for (Eigen::Index t = 0; t < m.mesh.F.rows(); ++t)
      for (int k = 0; k < 3; ++k)
        if (m.mesh.F(t, k) < 0 || m.mesh.F(t, k) >= n) __builtin_trap();
    const auto n_in = static_cast<Eigen::Index>(m.input_to_engine.size());
    for (const int e : m.input_to_engine)
      if (e < 0 || e >= n) __builtin_trap();
    for (Eigen::Index t = 0; t < m.input_triangles.rows(); ++t)
      for (int k = 0; k < 3; ++k)
        if (m.input_triangles(t, k) < 0 || m.input_triangles(t, k) >= n_in) __builtin_trap();
    if (m.to_input_layout(m.mesh.V).rows() != n_in) __builtin_trap();
  } catch (const hdeform::InvalidInput&) {
  } catch (const hdeform::ReadCancelled&) {
    if (!limits.should_cancel) __builtin_trap();
  }
  return 0;
}

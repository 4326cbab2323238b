// libFuzzer target for parse_def: only InvalidInput may be thrown; a result is a finite
// affine 4×4 matrix.
#include "engine/io/selection.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const Eigen::Matrix4d M = hdeform::parse_def(text, "fuzz.def");
    if (!M.allFinite()) __builtin_trap();
  } catch (const hdeform::InvalidInput&) {
  }
  return 0;
}

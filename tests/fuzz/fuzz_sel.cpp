// libFuzzer target for parse_sel: the first two bytes (little-endian) are the mesh's vertex
// count (0–65535), the rest is the .sel file. Only InvalidInput may be thrown; a result
// has exactly that many labels, each 0, 1 or 2.
#include "engine/io/selection.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const int nv = data[0] | (data[1] << 8);
  const std::string_view text(reinterpret_cast<const char*>(data) + 2, size - 2);
  try {
    const std::vector<int> labels = hdeform::parse_sel(text, nv, "fuzz.sel");
    if (static_cast<int>(labels.size()) != nv) __builtin_trap();
    for (const int l : labels)
      if (l < 0 || l > 2) __builtin_trap();
  } catch (const hdeform::InvalidInput&) {
  }
  return 0;
}

// Rerunning the report leaves unchanged files alone: same bytes are not rewritten, and a PNG
// whose pixels are the same is kept as it is even if an encoder (another stb version) would
// compress it differently. So `scripts/reproduce.sh` leaves git clean when nothing changed.
#pragma once

#include <string>

namespace hdeform::report {

// Writes `bytes` to `path` unless the file already holds exactly them. True when written.
bool write_if_changed(const std::string& path, const std::string& bytes);

// Writes an 8-bit RGB image (w×h, tightly packed) as PNG unless `path` is a PNG with the
// same pixels. True when written.
bool write_png_if_changed(const std::string& path, int w, int h, const unsigned char* rgb);

}  // namespace hdeform::report

#include "write_if_changed.h"

#include <stb/stb_image.h>
#include <stb/stb_image_write.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace hdeform::report {

namespace {

bool read_all(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  out.assign(std::istreambuf_iterator<char>(in), {});
  return true;
}

void write_all(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace

bool write_if_changed(const std::string& path, const std::string& bytes) {
  std::string old;
  if (read_all(path, old) && old == bytes) return false;
  write_all(path, bytes);
  return true;
}

bool write_png_if_changed(const std::string& path, int w, int h, const unsigned char* rgb) {
  std::string old;
  if (read_all(path, old)) {
    int ow = 0, oh = 0, channels = 0;
    unsigned char* pixels =
        stbi_load_from_memory(reinterpret_cast<const unsigned char*>(old.data()),
                              static_cast<int>(old.size()), &ow, &oh, &channels, 3);
    const bool same = pixels && ow == w && oh == h &&
                      std::memcmp(pixels, rgb, static_cast<std::size_t>(w) * h * 3) == 0;
    stbi_image_free(pixels);
    if (same) return false;
  }
  std::string png;
  auto sink = [](void* ctx, void* data, int size) {
    static_cast<std::string*>(ctx)->append(static_cast<const char*>(data),
                                           static_cast<std::size_t>(size));
  };
  if (!stbi_write_png_to_func(sink, &png, w, h, 3, rgb, w * 3))
    throw std::runtime_error("cannot encode " + path);
  write_all(path, png);
  return true;
}

}  // namespace hdeform::report

#pragma once
// 8-bit RGBA images produced by the preview renderer, and writing them as PNG.
#include <cstdint>
#include <filesystem>
#include <vector>

namespace snow::render {

/// RGBA8 pixels, sRGB-encoded, rows top to bottom, 4 bytes per pixel.
struct ImageRGBA8 {
  int width = 0;                // pixels
  int height = 0;               // pixels
  std::vector<uint8_t> pixels;  // width * height * 4

  /// Pointer to the 4 bytes of pixel (x, y), y = 0 at the top. No bounds check.
  const uint8_t* at(int x, int y) const {
    return pixels.data() + (static_cast<size_t>(y) * static_cast<size_t>(width) + x) * 4;
  }
};

/// Writes `image` as an 8-bit RGBA PNG (stb_image_write), atomically: the
/// file appears complete or not at all. Throws IOError naming `path` on
/// failure and InputError if the pixel count does not match the size.
void write_png(const ImageRGBA8& image, const std::filesystem::path& path);

}  // namespace snow::render

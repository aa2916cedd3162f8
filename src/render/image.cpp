// PNG output of preview images through the stb_image_write implementation
// in Debian's libstb (so no STB_IMAGE_WRITE_IMPLEMENTATION here).
#include "render/image.h"

#include <stb_image_write.h>

#include <string>

#include "core/error.h"
#include "core/fs.h"

namespace snow::render {

void write_png(const ImageRGBA8& image, const std::filesystem::path& path) {
  const size_t expected = static_cast<size_t>(std::max(image.width, 0)) *
                          static_cast<size_t>(std::max(image.height, 0)) * 4;
  if (image.width < 1 || image.height < 1 || image.pixels.size() != expected) {
    throw InputError("cannot write " + path.string() + ": image " + std::to_string(image.width) +
                     "x" + std::to_string(image.height) + " has " +
                     std::to_string(image.pixels.size()) + " bytes, expected " +
                     std::to_string(expected));
  }
  write_file_atomically(path, [&](const std::filesystem::path& tmp) {
    if (!stbi_write_png(tmp.c_str(), image.width, image.height, 4, image.pixels.data(),
                        image.width * 4)) {
      throw IOError("could not write PNG " + path.string());
    }
  });
}

}  // namespace snow::render

#pragma once
// Reading the single-channel float EXR images of the --maps output in tests
// (mesh/write_maps.h), with the format's expectations checked.
#include <gtest/gtest.h>
#include <tinyexr.h>

#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/fs.h"

namespace snow::test {

/// The "Y" channel of the EXR at `path`, rows one after another; its size
/// in *width x *height. Expects one 32-bit float channel named "Y".
inline std::vector<float> read_exr(const std::filesystem::path& path, int* width, int* height) {
  const std::vector<uint8_t> bytes = snow::read_file_bytes(path);
  EXRVersion version;
  EXPECT_EQ(ParseEXRVersionFromMemory(&version, bytes.data(), bytes.size()), TINYEXR_SUCCESS);
  EXRHeader header;
  InitEXRHeader(&header);
  const char* err = nullptr;
  EXPECT_EQ(ParseEXRHeaderFromMemory(&header, &version, bytes.data(), bytes.size(), &err),
            TINYEXR_SUCCESS);
  EXPECT_EQ(header.num_channels, 1);
  EXPECT_STREQ(header.channels[0].name, "Y");
  EXPECT_EQ(header.pixel_types[0], TINYEXR_PIXELTYPE_FLOAT);
  EXRImage image;
  InitEXRImage(&image);
  EXPECT_EQ(LoadEXRImageFromMemory(&image, &header, bytes.data(), bytes.size(), &err),
            TINYEXR_SUCCESS);
  *width = image.width;
  *height = image.height;
  const float* plane = reinterpret_cast<const float*>(image.images[0]);
  std::vector<float> out(plane, plane + size_t(image.width) * size_t(image.height));
  FreeEXRImage(&image);
  FreeEXRHeader(&header);
  return out;
}

}  // namespace snow::test

#pragma once
// The input's glTF as the loader read it, kept for writers that copy the
// input (the combined writer, mesh/export.h): with it nothing reads or
// parses the input's JSON a second time.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace snow {

/// What load_scene keeps of the file when LoadSettings::keep_source is set
/// (Scene::source). The JSON passed the loader's document checks: nested at
/// most kMaxJsonDepth levels (scene/input_policy.h), at most
/// LoadLimits::max_json_bytes, a JSON object, glTF 2.x. Elements the scene
/// does not use are as the file has them (unchecked).
struct SourceGltf {
  std::filesystem::path path;  // the scene file as named to load_scene
  nlohmann::json json;         // its JSON (a .glb's JSON chunk), parsed once
  // A .glb's BIN chunk, where its bytes lie in the file (bytes from the
  // file's start; the chunk's length, not buffer 0's byteLength).
  bool has_bin = false;
  uint64_t bin_offset = 0;
  uint64_t bin_length = 0;
  // The file's size (bytes) and modification time as the loader read it:
  // a write that copies the BIN chunk later checks that they still hold.
  uint64_t file_size = 0;
  std::filesystem::file_time_type modified{};
};

/// The bytes of a data: URI (RFC 2397): base64 (RFC 4648; whitespace
/// ignored, the URL-safe alphabet accepted) when its header ends in
/// ";base64", else percent-encoded text. The media type (the header up to
/// ';', maybe empty) in *mime. nullopt, with the reason in *why, for a
/// malformed one (no ',', bad base64 or escape). The loader decodes its
/// buffers and images with it.
std::optional<std::vector<uint8_t>> decode_data_uri(const std::string& uri, std::string* mime,
                                                    std::string* why);

}  // namespace snow

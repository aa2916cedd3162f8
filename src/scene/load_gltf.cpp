// glTF 2.0 loader following the Khronos glTF 2.0 specification: GLB container
// (section 4.4), buffers/bufferViews/accessors with byteStride and sparse
// storage (3.6), meshes and primitive topologies (3.7.2), the node hierarchy
// (3.5), materials (3.9.2) and textures (3.8); extensions
// KHR_mesh_quantization, KHR_texture_transform, KHR_draco_mesh_compression
// and EXT_mesh_gpu_instancing.
//
// The JSON is parsed with nlohmann::json and every value is validated here:
// the file is untrusted. Sizes are checked with 64-bit arithmetic before any
// allocation, so a declared count of 1e9 over a 48-byte buffer fails at once.
#include "scene/load_gltf.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>

#include <stb_image.h>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#ifdef SNOW_HAVE_DRACO
#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#endif

#include "core/default_init.h"
#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"
#include "core/parallel.h"

namespace snow {
namespace {

namespace fs = std::filesystem;

/// Bytes read from a file or a data: URI. Sized without writing zeros
/// first: the read or the decoding writes every byte (the 1M-triangle
/// terrain's 84 MB GLB at 128 texels: whole run 441-467 -> 425-436 ms).
using Bytes = std::vector<uint8_t, DefaultInitAllocator<uint8_t>>;

using json = nlohmann::json;

constexpr int kByte = 5120;
constexpr int kUnsignedByte = 5121;
constexpr int kShort = 5122;
constexpr int kUnsignedShort = 5123;
constexpr int kInt = 5124;
constexpr int kUnsignedInt = 5125;
constexpr int kFloat = 5126;

constexpr uint32_t kGlbMagic = 0x46546C67;   // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"
constexpr uint64_t kMaxAccessorCount = 1ull << 32;
constexpr size_t kMaxPathNames = 24;  // node paths deeper than this are elided

const char* const kModeNames[] = {"POINTS",    "LINES",          "LINE_LOOP",   "LINE_STRIP",
                                  "TRIANGLES", "TRIANGLE_STRIP", "TRIANGLE_FAN"};

/// Length of the valid UTF-8 sequence at text[i], or 0 if it is invalid.
size_t utf8_sequence(std::string_view text, size_t i) {
  const auto c = static_cast<unsigned char>(text[i]);
  size_t n = 0;
  uint32_t cp = 0;
  if (c < 0x80) return 1;
  if ((c & 0xE0) == 0xC0)
    n = 2, cp = c & 0x1F;
  else if ((c & 0xF0) == 0xE0)
    n = 3, cp = c & 0x0F;
  else if ((c & 0xF8) == 0xF0)
    n = 4, cp = c & 0x07;
  else
    return 0;
  if (i + n > text.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    const auto d = static_cast<unsigned char>(text[i + k]);
    if ((d & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (d & 0x3F);
  }
  static const uint32_t kMin[5] = {0, 0, 0x80, 0x800, 0x10000};
  if (cp < kMin[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

/// Makes text from the file safe for a one-line message: control characters
/// become spaces, invalid UTF-8 bytes '?', and long text is cut with "...".
std::string one_line(std::string_view text, size_t max_chars = 120) {
  std::string out;
  out.reserve(std::min(text.size(), max_chars) + 3);
  for (size_t i = 0; i < text.size();) {
    if (out.size() >= max_chars) return out + "...";
    const size_t n = utf8_sequence(text, i);
    if (n == 0) {
      out += '?';
      ++i;
    } else if (n == 1) {
      const auto u = static_cast<unsigned char>(text[i]);
      out += (u < 0x20 || u == 0x7F) ? ' ' : text[i];
      ++i;
    } else {
      out.append(text.data() + i, n);
      i += n;
    }
  }
  return out;
}

int component_size(int component_type) {
  switch (component_type) {
    case kByte:
    case kUnsignedByte:
      return 1;
    case kShort:
    case kUnsignedShort:
      return 2;
    case kInt:
    case kUnsignedInt:
    case kFloat:
      return 4;
    default:
      return 0;
  }
}

int type_components(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  if (type == "MAT2") return 4;
  if (type == "MAT3") return 9;
  if (type == "MAT4") return 16;
  return 0;
}

/// Converts `count` elements of `components` values of type T into floats.
template <typename T>
void convert_elements(const uint8_t* src, uint64_t stride, uint64_t count, int components,
                      bool normalized, float* out) {
  if (std::is_same<T, float>::value && stride == sizeof(float) * size_t(components)) {
    std::memcpy(out, src, count * stride);
    return;
  }
  for (uint64_t i = 0; i < count; ++i) {
    const uint8_t* element = src + i * stride;
    for (int c = 0; c < components; ++c) {
      T value;
      std::memcpy(&value, element + c * sizeof(T), sizeof(T));
      float f = static_cast<float>(value);
      if (normalized && !std::is_same<T, float>::value) {
        // glTF 2.0 section 3.11 (normalized integers).
        if (std::is_same<T, int8_t>::value) f = std::max(f / 127.0f, -1.0f);
        if (std::is_same<T, uint8_t>::value) f = f / 255.0f;
        if (std::is_same<T, int16_t>::value) f = std::max(f / 32767.0f, -1.0f);
        if (std::is_same<T, uint16_t>::value) f = f / 65535.0f;
      }
      out[i * size_t(components) + size_t(c)] = f;
    }
  }
}

void convert_any(int component_type, const uint8_t* src, uint64_t stride, uint64_t count,
                 int components, bool normalized, float* out) {
  switch (component_type) {
    case kByte:
      return convert_elements<int8_t>(src, stride, count, components, normalized, out);
    case kUnsignedByte:
      return convert_elements<uint8_t>(src, stride, count, components, normalized, out);
    case kShort:
      return convert_elements<int16_t>(src, stride, count, components, normalized, out);
    case kUnsignedShort:
      return convert_elements<uint16_t>(src, stride, count, components, normalized, out);
    case kInt:
      return convert_elements<int32_t>(src, stride, count, components, false, out);
    case kUnsignedInt:
      return convert_elements<uint32_t>(src, stride, count, components, false, out);
    default:
      return convert_elements<float>(src, stride, count, components, false, out);
  }
}

uint32_t read_uint(const uint8_t* p, int component_type) {
  switch (component_type) {
    case kUnsignedByte:
      return *p;
    case kUnsignedShort: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    default: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

uint32_t read_u32_le(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

/// Strict base64 (RFC 4648); whitespace is ignored. False on bad input.
bool base64_decode(std::string_view in, Bytes& out) {
  static const std::array<int8_t, 256> table = [] {
    std::array<int8_t, 256> t{};
    t.fill(-1);
    const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (int i = 0; i < 64; ++i)
      t[static_cast<unsigned char>(alphabet[i])] = static_cast<int8_t>(i);
    t['-'] = 62;  // URL-safe variants
    t['_'] = 63;
    return t;
  }();
  out.clear();
  out.reserve(in.size() / 4 * 3 + 3);
  uint32_t bits = 0;
  int nbits = 0;
  size_t i = 0;
  for (; i < in.size(); ++i) {
    const auto c = static_cast<unsigned char>(in[i]);
    if (c == '=') break;
    if (c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
    const int v = table[c];
    if (v < 0) return false;
    bits = (bits << 6) | uint32_t(v);
    nbits += 6;
    if (nbits >= 8) {
      nbits -= 8;
      out.push_back(static_cast<uint8_t>((bits >> nbits) & 0xFF));
    }
  }
  for (; i < in.size(); ++i) {
    if (in[i] != '=' && in[i] != '\n' && in[i] != '\r') return false;
  }
  return nbits < 6;
}

/// Decodes %XX escapes; false on a malformed escape or a NUL byte.
bool percent_decode(std::string_view in, std::string& out) {
  out.clear();
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] == '%') {
      if (i + 2 >= in.size()) return false;
      auto hex = [](char c) {
        if (c >= '0' && c <= '9') return c - '0';
        if (c >= 'a' && c <= 'f') return c - 'a' + 10;
        if (c >= 'A' && c <= 'F') return c - 'A' + 10;
        return -1;
      };
      const int hi = hex(in[i + 1]);
      const int lo = hex(in[i + 2]);
      if (hi < 0 || lo < 0 || (hi == 0 && lo == 0)) return false;
      out += static_cast<char>(hi * 16 + lo);
      i += 2;
    } else {
      if (in[i] == '\0') return false;
      out += in[i];
    }
  }
  return true;
}

}  // namespace

std::optional<fs::path> resolve_relative_uri(const fs::path& folder, const std::string& uri,
                                             std::string* why) {
  std::string decoded;
  const auto refuse = [&](const char* reason) -> std::optional<fs::path> {
    if (why) *why = reason;
    return std::nullopt;
  };
  if (!percent_decode(uri, decoded)) return refuse("is malformed");
  std::replace(decoded.begin(), decoded.end(), '\\', '/');
  // A scheme ("http:", "file:", "data:", "C:") is not a relative path.
  const size_t colon = decoded.find(':');
  const size_t slash = decoded.find('/');
  if (colon != std::string::npos && (slash == std::string::npos || colon < slash))
    return refuse("is not a relative file path (refused)");
  if (decoded.empty()) return refuse("is empty");
  const fs::path relative(decoded);
  if (relative.is_absolute() || relative.has_root_path())
    return refuse("is an absolute path (refused)");
  for (const auto& part : relative) {
    if (part == "..") return refuse("leaves the scene's folder (refused)");
  }
  return folder / relative;
}

namespace {

bool starts_with_ci(std::string_view s, std::string_view prefix) {
  if (s.size() < prefix.size()) return false;
  for (size_t i = 0; i < prefix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(s[i])) != prefix[i]) return false;
  }
  return true;
}

bool finite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

/// Extensions that do not change the geometry, or that the loader handles.
bool extension_known(const std::string& name) {
  static const char* const kKnown[] = {"KHR_mesh_quantization",
                                       "KHR_texture_transform",
                                       "KHR_draco_mesh_compression",
                                       "EXT_mesh_gpu_instancing",
                                       "KHR_lights_punctual",
                                       "KHR_texture_basisu",
                                       "EXT_texture_webp",
                                       "EXT_texture_avif",
                                       "MSFT_texture_dds",
                                       "KHR_xmp",
                                       "KHR_xmp_json_ld",
                                       "KHR_animation_pointer",
                                       "EXT_meshopt_compression",
                                       "KHR_meshopt_compression",
                                       "EXT_lights_image_based",
                                       "MSFT_lod",
                                       "KHR_materials_variants",
                                       "KHR_audio",
                                       "KHR_node_visibility"};
  for (const char* known : kKnown)
    if (name == known) return true;
  return name.rfind("KHR_materials_", 0) == 0;
}

/// Extensions a file may require and still load correctly here.
bool extension_supported_when_required(const std::string& name) {
  if (name == "EXT_meshopt_compression" || name == "KHR_meshopt_compression") return false;
  if (name == "KHR_node_visibility" || name == "MSFT_lod") return false;
  if (name == "KHR_draco_mesh_compression") return gltf_draco_supported();
  return extension_known(name);
}

// ---------------------------------------------------------------------------

// Vertices or triangles per task of the loops that put a primitive's
// triangles into the scene.
constexpr size_t kLoadChunk = size_t(1) << 15;

struct BufferSlot {
  bool loaded = false;
  Bytes owned;
  const uint8_t* data = nullptr;
  uint64_t size = 0;  // declared byteLength (the data holds at least this)
};

struct ViewRange {
  const uint8_t* data = nullptr;
  uint64_t length = 0;
  uint64_t stride = 0;  // 0 when the view has no byteStride
};

struct AccessorInfo {
  int index = -1;
  uint64_t count = 0;
  int components = 0;
  int component_type = 0;
  bool normalized = false;
  const uint8_t* data = nullptr;  // first element; null: all zeros (+ sparse)
  uint64_t stride = 0;
  uint64_t sparse_count = 0;
  const uint8_t* sparse_indices = nullptr;
  int sparse_index_type = 0;
  const uint8_t* sparse_values = nullptr;
};

/// Texture coordinate set and KHR_texture_transform of a baseColorTexture.
struct UvMapping {
  int set = 0;
  bool transform = false;
  glm::dmat3 matrix{1.0};
};

/// One primitive decoded in mesh space; shared by all instances of its mesh.
struct PrimitiveGeometry {
  bool skip = false;
  int material = -1;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;   // empty or one per position
  std::vector<glm::vec2> uvs;       // empty or one per position
  std::vector<uint32_t> triangles;  // three vertex indices per triangle
};

/// A (node, mesh) pair found by the traversal, with its world matrix.
struct Instance {
  int node = -1;
  int mesh = -1;
  uint32_t path = 0;  // index into node_paths_
  glm::dmat4 world{1.0};
};

class GltfLoader {
 public:
  GltfLoader(const fs::path& path, const LoadSettings& settings)
      : path_(path), settings_(settings), label_(path.string()) {
    folder_ = path.parent_path();
    if (folder_.empty()) folder_ = ".";
  }

  Scene load() {
    read_document();
    check_extensions();
    read_materials();
    std::vector<Instance> instances = traverse();
    build_geometry(instances);
    if (scene_.triangle_count() == 0) {
      if (scene_.stats.triangles_read > 0)
        fail("the scene has no triangles left after dropping " +
             std::to_string(scene_.stats.degenerate_dropped) + " degenerate ones");
      fail("the scene has no triangles");
    }
    if (settings_.load_images) load_images();
    return std::move(scene_);
  }

 private:
  // --- errors and warnings -------------------------------------------------

  [[noreturn]] void fail(const std::string& message) const {
    throw InputError(label_ + ": " + message);
  }

  [[noreturn]] void fail_triangle_limit() const {
    fail("the scene has more triangles than the limit of " +
         std::to_string(settings_.limits.max_triangles) + " (LoadLimits::max_triangles)");
  }

  void warn(const std::string& message) {
    scene_.warnings.push_back(message);
    log_warn(message);
  }

  // --- JSON access with validation -----------------------------------------

  const json* member(const json& object, const char* key) const {
    if (!object.is_object()) return nullptr;
    auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
  }

  /// Top-level array `key` (empty when absent).
  const json& top_array(const char* key) const {
    static const json empty = json::array();
    const json* value = member(doc_, key);
    if (!value) return empty;
    if (!value->is_array()) fail(std::string("'") + key + "' must be an array");
    return *value;
  }

  const json& element(const json& array, uint64_t index, const std::string& what) const {
    const json& value = array[size_t(index)];
    if (!value.is_object()) fail(what + " must be a JSON object");
    return value;
  }

  uint64_t as_uint(const json& value, const std::string& what) const {
    if (value.is_number_unsigned()) return value.get<uint64_t>();
    if (value.is_number_integer() && value.get<int64_t>() >= 0) return value.get<uint64_t>();
    if (value.is_number_float()) {
      const double d = value.get<double>();
      if (d >= 0 && d <= 9007199254740992.0 && std::floor(d) == d) return static_cast<uint64_t>(d);
    }
    fail(what + " must be a non-negative integer, not " +
         one_line(value.dump(-1, ' ', false, json::error_handler_t::replace), 40));
  }

  uint64_t opt_uint(const json& object, const char* key, uint64_t fallback,
                    const std::string& what) const {
    const json* value = member(object, key);
    return value ? as_uint(*value, what + " '" + key + "'") : fallback;
  }

  /// Optional index into an array of `size` things; -1 when absent.
  int64_t opt_index(const json& object, const char* key, size_t size, const std::string& what,
                    const char* things) const {
    const json* value = member(object, key);
    if (!value) return -1;
    const uint64_t index = as_uint(*value, what + " '" + key + "'");
    if (index >= size)
      fail(what + " '" + key + "' = " + std::to_string(index) + " is out of range (" +
           std::to_string(size) + " " + things + ")");
    return int64_t(index);
  }

  double as_number(const json& value, const std::string& what) const {
    if (!value.is_number()) fail(what + " must be a number");
    const double d = value.get<double>();
    if (!std::isfinite(d)) fail(what + " is not finite");
    return d;
  }

  /// Fixed-size array of finite numbers.
  template <size_t N>
  std::array<double, N> numbers(const json& value, const std::string& what) const {
    if (!value.is_array() || value.size() != N)
      fail(what + " must be an array of " + std::to_string(N) + " numbers");
    std::array<double, N> out{};
    for (size_t i = 0; i < N; ++i) {
      if (!value[i].is_number())
        fail(what + " must be an array of " + std::to_string(N) + " numbers");
      out[i] = value[i].get<double>();
      if (!std::isfinite(out[i])) fail(what + " has a non-finite value (NaN or infinite)");
    }
    return out;
  }

  std::string opt_string(const json& object, const char* key) const {
    const json* value = member(object, key);
    return value && value->is_string() ? value->get<std::string>() : std::string();
  }

  std::string mesh_label(int mesh) const {
    const std::string name = opt_string(meshes()[size_t(mesh)], "name");
    return name.empty() ? "mesh " + std::to_string(mesh)
                        : "mesh " + std::to_string(mesh) + " ('" + one_line(name, 60) + "')";
  }

  std::string node_label(int node) const {
    const std::string name = opt_string(nodes()[size_t(node)], "name");
    return name.empty() ? "node " + std::to_string(node)
                        : "node " + std::to_string(node) + " ('" + one_line(name, 60) + "')";
  }

  const json& nodes() const { return top_array("nodes"); }
  const json& meshes() const { return top_array("meshes"); }

  // --- files and URIs --------------------------------------------------------

  Bytes read_file(const fs::path& file, const std::string& what, bool missing_ok,
                  bool* missing) const {
    std::error_code ec;
    const auto status = fs::status(file, ec);
    if (ec || !fs::exists(status)) {
      if (missing) *missing = true;
      if (missing_ok) return {};
      fail(what + ": file '" + one_line(file.string()) + "' does not exist");
    }
    if (!fs::is_regular_file(status))
      fail(what + ": '" + one_line(file.string()) + "' is not a file");
    const uint64_t size = fs::file_size(file, ec);
    if (ec) fail(what + ": cannot read '" + one_line(file.string()) + "'");
    if (size > settings_.limits.max_file_bytes)
      fail(what + ": '" + one_line(file.string()) + "' is " + std::to_string(size) +
           " bytes, over the limit of " + std::to_string(settings_.limits.max_file_bytes) +
           " (LoadLimits::max_file_bytes)");
    Bytes bytes(size);
    std::ifstream in(file, std::ios::binary);
    if (!in || !in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size)))
      fail(what + ": cannot read '" + one_line(file.string()) + "'");
    return bytes;
  }

  /// Resolves a relative URI inside the scene's folder; refuses anything else.
  fs::path resolve_uri(const std::string& uri, const std::string& what) const {
    std::string why;
    std::optional<fs::path> file = resolve_relative_uri(folder_, uri, &why);
    if (!file) fail(what + ": uri '" + one_line(uri) + "' " + why);
    return *file;
  }

  /// Bytes of a data: URI.
  Bytes decode_data_uri(const std::string& uri, const std::string& what, std::string* mime) const {
    const size_t comma = uri.find(',');
    if (comma == std::string::npos) fail(what + ": malformed data uri (no ',')");
    const std::string header = uri.substr(5, comma - 5);
    if (mime) *mime = header.substr(0, header.find(';'));
    const std::string_view payload(uri.data() + comma + 1, uri.size() - comma - 1);
    Bytes bytes;
    if (header.size() >= 7 && header.compare(header.size() - 7, 7, ";base64") == 0) {
      if (!base64_decode(payload, bytes)) fail(what + ": data uri is not valid base64");
    } else {
      std::string raw;
      if (!percent_decode(payload, raw)) fail(what + ": malformed data uri");
      bytes.assign(raw.begin(), raw.end());
    }
    if (bytes.size() > settings_.limits.max_file_bytes)
      fail(what + ": data uri is over the limit of " +
           std::to_string(settings_.limits.max_file_bytes) + " bytes (LoadLimits::max_file_bytes)");
    return bytes;
  }

  // --- document ------------------------------------------------------------

  void read_document() {
    {
      std::error_code ec;
      if (!fs::exists(path_, ec)) throw IOError(label_ + ": file does not exist");
      if (fs::is_directory(path_, ec)) throw IOError(label_ + ": is a folder, not a glTF file");
      std::ifstream probe(path_, std::ios::binary);
      if (!probe) throw IOError(label_ + ": cannot open file");
    }
    file_ = read_file(path_, "scene file", false, nullptr);
    const std::string extension = lower_extension(path_);
    const bool glb_magic = file_.size() >= 4 && read_u32_le(file_.data()) == kGlbMagic;
    const uint8_t* json_begin = file_.data();
    uint64_t json_size = file_.size();
    if (glb_magic) {
      parse_glb_container(json_begin, json_size);
    } else if (extension == ".glb") {
      if (file_.size() < 12)
        fail("truncated GLB: " + std::to_string(file_.size()) + " bytes, header needs 12");
      fail("not a GLB file: bad magic (the first 4 bytes are not 'glTF')");
    }
    if (json_size > settings_.limits.max_json_bytes)
      fail("JSON is " + std::to_string(json_size) + " bytes, over the limit of " +
           std::to_string(settings_.limits.max_json_bytes) + " (LoadLimits::max_json_bytes)");
    try {
      doc_ = json::parse(json_begin, json_begin + json_size);
    } catch (const json::exception& e) {
      std::string message = e.what();
      const size_t bracket = message.find("] ");
      if (message.rfind("[json.exception", 0) == 0 && bracket != std::string::npos)
        message = message.substr(bracket + 2);
      fail("broken JSON: " + one_line(message, 200));
    }
    if (!doc_.is_object()) fail("broken JSON: the top level is not an object");
    const json* asset = member(doc_, "asset");
    const std::string version = asset ? opt_string(*asset, "version") : std::string();
    if (version.empty()) {
      warn("'asset.version' is missing; reading the file as glTF 2.0");
    } else if (version[0] != '2') {
      fail("glTF version " + one_line(version, 20) + " is not supported (only 2.x)");
    }
  }

  void parse_glb_container(const uint8_t*& json_begin, uint64_t& json_size) {
    const uint64_t file_size = file_.size();
    if (file_size < 12)
      fail("truncated GLB: " + std::to_string(file_size) + " bytes, header needs 12");
    const uint32_t version = read_u32_le(file_.data() + 4);
    const uint32_t length = read_u32_le(file_.data() + 8);
    if (version != 2) fail("GLB version " + std::to_string(version) + " is not supported (only 2)");
    if (length > file_size)
      fail("truncated GLB: header declares " + std::to_string(length) + " bytes, the file has " +
           std::to_string(file_size));
    if (length < 20)
      fail("truncated GLB: declared length " + std::to_string(length) +
           " leaves no room for the JSON chunk");
    uint64_t offset = 12;
    int chunk = 0;
    bool have_json = false;
    while (offset < length) {
      if (length - offset < 8)
        fail("truncated GLB: chunk " + std::to_string(chunk) + " header at byte " +
             std::to_string(offset) + " is cut off");
      const uint32_t chunk_length = read_u32_le(file_.data() + offset);
      const uint32_t chunk_type = read_u32_le(file_.data() + offset + 4);
      const uint64_t data_offset = offset + 8;
      if (chunk_length > length - data_offset)
        fail("truncated GLB: chunk " + std::to_string(chunk) + " declares " +
             std::to_string(chunk_length) + " bytes, only " + std::to_string(length - data_offset) +
             " remain");
      if (chunk == 0) {
        if (chunk_type != kChunkJson) fail("bad GLB: the first chunk is not JSON");
        json_begin = file_.data() + data_offset;
        json_size = chunk_length;
        have_json = true;
      } else if (chunk_type == kChunkBin && !has_glb_bin_) {
        glb_bin_ = file_.data() + data_offset;
        glb_bin_size_ = chunk_length;
        has_glb_bin_ = true;
      } else if (chunk_type == kChunkJson || chunk_type == kChunkBin) {
        fail("bad GLB: chunk " + std::to_string(chunk) + " is a second " +
             (chunk_type == kChunkJson ? "JSON" : "BIN") + " chunk");
      }
      // Chunks are 4-byte aligned; tolerate writers that forgot the padding.
      offset = data_offset + chunk_length;
      if (offset % 4 != 0 && offset + (4 - offset % 4) <= length) offset += 4 - offset % 4;
      ++chunk;
    }
    if (!have_json) fail("bad GLB: no JSON chunk");
    is_glb_ = true;
  }

  void check_extensions() {
    for (const json& name : top_array("extensionsRequired")) {
      if (!name.is_string()) fail("'extensionsRequired' must hold strings");
      const std::string ext = name.get<std::string>();
      if (extension_supported_when_required(ext)) continue;
      if (ext == "EXT_meshopt_compression" || ext == "KHR_meshopt_compression")
        fail("requires extension " + ext +
             " (meshopt-compressed buffers), which snowmodel cannot decode; decompress the "
             "file first (e.g. gltfpack -noq or gltf-transform copy)");
      if (ext == "KHR_draco_mesh_compression")
        fail("requires extension KHR_draco_mesh_compression, but this build has no Draco decoder");
      fail("requires extension '" + one_line(ext, 60) + "', which snowmodel does not support");
    }
    for (const json& name : top_array("extensionsUsed")) {
      if (!name.is_string()) fail("'extensionsUsed' must hold strings");
      const std::string ext = name.get<std::string>();
      if (!extension_known(ext)) warn("ignoring unknown extension '" + one_line(ext, 60) + "'");
    }
  }

  // --- buffers, views, accessors --------------------------------------------

  const BufferSlot& buffer(uint64_t index) {
    const json& buffers = top_array("buffers");
    if (slots_.size() != buffers.size()) slots_.resize(buffers.size());
    BufferSlot& slot = slots_[size_t(index)];
    if (slot.loaded) return slot;
    const std::string what = "buffer " + std::to_string(index);
    const json& object = element(buffers, index, what);
    const json* length_value = member(object, "byteLength");
    if (!length_value) fail(what + " has no 'byteLength'");
    slot.size = as_uint(*length_value, what + " 'byteLength'");
    const json* uri_value = member(object, "uri");
    if (!uri_value) {
      if (!is_glb_ || index != 0) {
        const json* extensions = member(object, "extensions");
        if (extensions && (member(*extensions, "EXT_meshopt_compression") ||
                           member(*extensions, "KHR_meshopt_compression")))
          fail(what +
               " is an EXT_meshopt_compression fallback without data; meshopt-compressed "
               "files are not supported");
        fail(what + " has no 'uri'");
      }
      if (!has_glb_bin_) fail(what + " refers to the GLB BIN chunk, but the file has none");
      if (glb_bin_size_ < slot.size)
        fail(what + ": GLB BIN chunk holds " + std::to_string(glb_bin_size_) +
             " bytes, but byteLength is " + std::to_string(slot.size));
      slot.data = glb_bin_;
    } else {
      if (!uri_value->is_string()) fail(what + " 'uri' must be a string");
      const std::string uri = uri_value->get<std::string>();
      if (starts_with_ci(uri, "data:")) {
        slot.owned = decode_data_uri(uri, what, nullptr);
      } else {
        const fs::path file = resolve_uri(uri, what);
        slot.owned = read_file(file, what + " ('" + one_line(uri, 60) + "')", false, nullptr);
      }
      if (slot.owned.size() < slot.size)
        fail(what + " ('" + one_line(starts_with_ci(uri, "data:") ? "data uri" : uri, 60) +
             "') holds " + std::to_string(slot.owned.size()) + " bytes, but byteLength is " +
             std::to_string(slot.size));
      slot.data = slot.owned.data();
    }
    slot.loaded = true;
    return slot;
  }

  ViewRange view(uint64_t index, const std::string& user) {
    const json& views = top_array("bufferViews");
    if (index >= views.size())
      fail(user + ": bufferView " + std::to_string(index) + " is out of range (" +
           std::to_string(views.size()) + " bufferViews)");
    const std::string what = "bufferView " + std::to_string(index);
    const json& object = element(views, index, what);
    const json* buffer_value = member(object, "buffer");
    if (!buffer_value) fail(what + " has no 'buffer'");
    const uint64_t buffer_index = as_uint(*buffer_value, what + " 'buffer'");
    const size_t buffer_count = top_array("buffers").size();
    if (buffer_index >= buffer_count)
      fail(what + " 'buffer' = " + std::to_string(buffer_index) + " is out of range (" +
           std::to_string(buffer_count) + " buffers)");
    const uint64_t offset = opt_uint(object, "byteOffset", 0, what);
    const json* length_value = member(object, "byteLength");
    if (!length_value) fail(what + " has no 'byteLength'");
    const uint64_t length = as_uint(*length_value, what + " 'byteLength'");
    const uint64_t stride = opt_uint(object, "byteStride", 0, what);
    if (member(object, "byteStride") && (stride < 1 || stride > 252))
      fail(what + " 'byteStride' = " + std::to_string(stride) + " is outside 4..252");
    const BufferSlot& slot = buffer(buffer_index);
    if (offset > slot.size || length > slot.size - offset)
      fail(what + " (offset " + std::to_string(offset) + ", length " + std::to_string(length) +
           ") is out of range of buffer " + std::to_string(buffer_index) + " (" +
           std::to_string(slot.size) + " bytes)");
    return ViewRange{slot.data + offset, length, stride};
  }

  AccessorInfo accessor_info(uint64_t index, const std::string& role) {
    const json& accessors = top_array("accessors");
    if (index >= accessors.size())
      fail(role + ": accessor " + std::to_string(index) + " is out of range (" +
           std::to_string(accessors.size()) + " accessors)");
    const std::string what = "accessor " + std::to_string(index) + " (" + role + ")";
    const json& object = element(accessors, index, what);
    AccessorInfo info;
    info.index = int(index);
    const json* type_value = member(object, "componentType");
    if (!type_value) fail(what + " has no 'componentType'");
    info.component_type =
        int(std::min<uint64_t>(as_uint(*type_value, what + " 'componentType'"), 1 << 20));
    const int csize = component_size(info.component_type);
    if (csize == 0)
      fail(what + " has unknown componentType " + std::to_string(info.component_type));
    info.components = type_components(opt_string(object, "type"));
    if (info.components == 0) fail(what + " has a missing or unknown 'type'");
    const json* normalized = member(object, "normalized");
    info.normalized = normalized && normalized->is_boolean() && normalized->get<bool>();
    const json* count_value = member(object, "count");
    if (!count_value) fail(what + " has no 'count'");
    info.count = as_uint(*count_value, what + " 'count'");
    if (info.count > kMaxAccessorCount)
      fail(what + " declares count " + std::to_string(info.count) + ", over 2^32");
    const uint64_t element_size = uint64_t(csize) * uint64_t(info.components);
    const int64_t view_index =
        opt_index(object, "bufferView", top_array("bufferViews").size(), what, "bufferViews");
    if (view_index >= 0) {
      const ViewRange range = view(uint64_t(view_index), what);
      const uint64_t offset = opt_uint(object, "byteOffset", 0, what);
      info.stride = range.stride ? range.stride : element_size;
      if (info.stride < element_size)
        fail(what + ": bufferView " + std::to_string(view_index) + " byteStride " +
             std::to_string(info.stride) + " is smaller than an element (" +
             std::to_string(element_size) + " bytes)");
      if (info.count > 0) {
        const uint64_t needed = (info.count - 1) * info.stride + element_size;
        if (offset > range.length || needed > range.length - offset)
          fail(what + ": " + std::to_string(info.count) + " elements of " +
               std::to_string(element_size) + " bytes need " + std::to_string(needed) +
               " bytes from offset " + std::to_string(offset) + ", but bufferView " +
               std::to_string(view_index) + " holds " + std::to_string(range.length));
      }
      info.data = range.data + offset;
    }
    if (info.count > max_elements())
      fail(what + " declares count " + std::to_string(info.count) + ", over the limit of " +
           std::to_string(max_elements()) + " elements (from LoadLimits::max_triangles)");
    if (const json* sparse = member(object, "sparse")) {
      const std::string swhat = what + " sparse";
      const json* scount = member(*sparse, "count");
      if (!scount) fail(swhat + " has no 'count'");
      info.sparse_count = as_uint(*scount, swhat + " 'count'");
      if (info.sparse_count > info.count)
        fail(swhat + " 'count' " + std::to_string(info.sparse_count) +
             " exceeds the accessor count " + std::to_string(info.count));
      const json* indices = member(*sparse, "indices");
      const json* values = member(*sparse, "values");
      if (!indices || !indices->is_object() || !values || !values->is_object())
        fail(swhat + " needs 'indices' and 'values' objects");
      const json* itype = member(*indices, "componentType");
      if (!itype) fail(swhat + " indices have no 'componentType'");
      info.sparse_index_type =
          int(std::min<uint64_t>(as_uint(*itype, swhat + " indices 'componentType'"), 1 << 20));
      if (info.sparse_index_type != kUnsignedByte && info.sparse_index_type != kUnsignedShort &&
          info.sparse_index_type != kUnsignedInt)
        fail(swhat + " indices have componentType " + std::to_string(info.sparse_index_type) +
             " (must be an unsigned integer type)");
      const size_t view_count = top_array("bufferViews").size();
      const int64_t iview =
          opt_index(*indices, "bufferView", view_count, swhat + " indices", "bufferViews");
      const int64_t vview =
          opt_index(*values, "bufferView", view_count, swhat + " values", "bufferViews");
      if (iview < 0 || vview < 0) fail(swhat + " indices and values need a 'bufferView'");
      const ViewRange irange = view(uint64_t(iview), swhat);
      const ViewRange vrange = view(uint64_t(vview), swhat);
      const uint64_t ioffset = opt_uint(*indices, "byteOffset", 0, swhat + " indices");
      const uint64_t voffset = opt_uint(*values, "byteOffset", 0, swhat + " values");
      const uint64_t ineeded = info.sparse_count * uint64_t(component_size(info.sparse_index_type));
      const uint64_t vneeded = info.sparse_count * element_size;
      if (ioffset > irange.length || ineeded > irange.length - ioffset)
        fail(swhat + " indices need " + std::to_string(ineeded) + " bytes from offset " +
             std::to_string(ioffset) + ", but bufferView " + std::to_string(iview) + " holds " +
             std::to_string(irange.length));
      if (voffset > vrange.length || vneeded > vrange.length - voffset)
        fail(swhat + " values need " + std::to_string(vneeded) + " bytes from offset " +
             std::to_string(voffset) + ", but bufferView " + std::to_string(vview) + " holds " +
             std::to_string(vrange.length));
      info.sparse_indices = irange.data + ioffset;
      info.sparse_values = vrange.data + voffset;
    }
    return info;
  }

  uint64_t max_elements() const { return settings_.limits.max_triangles * 3 + 2; }

  /// Decodes an attribute accessor to floats (normalization and sparse applied).
  std::vector<float> decode_floats(const AccessorInfo& info, const std::string& role) {
    const std::string what = "accessor " + std::to_string(info.index) + " (" + role + ")";
    std::vector<float> out(size_t(info.count) * size_t(info.components), 0.0f);
    if (info.data)
      convert_any(info.component_type, info.data, info.stride, info.count, info.components,
                  info.normalized, out.data());
    const uint64_t element_size =
        uint64_t(component_size(info.component_type)) * uint64_t(info.components);
    const int isize = component_size(info.sparse_index_type);
    for (uint64_t k = 0; k < info.sparse_count; ++k) {
      const uint32_t target =
          read_uint(info.sparse_indices + k * uint64_t(isize), info.sparse_index_type);
      if (target >= info.count)
        fail(what + " sparse index " + std::to_string(target) + " is out of range (count " +
             std::to_string(info.count) + ")");
      convert_any(info.component_type, info.sparse_values + k * element_size, element_size, 1,
                  info.components, info.normalized,
                  out.data() + size_t(target) * size_t(info.components));
    }
    return out;
  }

  /// Reads a vertex attribute (POSITION, NORMAL, TEXCOORD_n) with type checks.
  std::vector<float> read_attribute(uint64_t accessor, int components, const std::string& role,
                                    AccessorInfo* info_out) {
    const AccessorInfo info = accessor_info(accessor, role);
    const std::string what = "accessor " + std::to_string(accessor) + " (" + role + ")";
    if (info.components != components) fail(what + " must be VEC" + std::to_string(components));
    if (info.component_type == kInt || info.component_type == kUnsignedInt)
      fail(what + " has componentType " + std::to_string(info.component_type) +
           ", not allowed for vertex attributes");
    if (info_out) *info_out = info;
    std::vector<float> values = decode_floats(info, role);
    for (size_t i = 0; i < values.size(); ++i) {
      if (!std::isfinite(values[i]))
        fail(what + " element " + std::to_string(i / size_t(components)) +
             " is not finite (NaN or infinite)");
    }
    return values;
  }

  std::vector<uint32_t> read_indices(uint64_t accessor, const std::string& role) {
    const AccessorInfo info = accessor_info(accessor, role);
    const std::string what = "accessor " + std::to_string(accessor) + " (" + role + ")";
    if (info.components != 1) fail(what + " must be SCALAR");
    if (info.component_type != kUnsignedByte && info.component_type != kUnsignedShort &&
        info.component_type != kUnsignedInt)
      fail(what + " has componentType " + std::to_string(info.component_type) +
           " (indices must be unsigned byte, short or int)");
    std::vector<uint32_t> out(size_t(info.count), 0u);
    if (info.data) {
      const int csize = component_size(info.component_type);
      if (info.stride == uint64_t(csize) && info.component_type == kUnsignedInt) {
        std::memcpy(out.data(), info.data, size_t(info.count) * 4);
      } else if (info.component_type == kUnsignedShort) {
        for (uint64_t i = 0; i < info.count; ++i) {
          uint16_t v;
          std::memcpy(&v, info.data + i * info.stride, 2);
          out[size_t(i)] = v;
        }
      } else {
        for (uint64_t i = 0; i < info.count; ++i)
          out[size_t(i)] = read_uint(info.data + i * info.stride, info.component_type);
      }
    }
    const int isize = component_size(info.sparse_index_type);
    for (uint64_t k = 0; k < info.sparse_count; ++k) {
      const uint32_t target =
          read_uint(info.sparse_indices + k * uint64_t(isize), info.sparse_index_type);
      if (target >= info.count)
        fail(what + " sparse index " + std::to_string(target) + " is out of range (count " +
             std::to_string(info.count) + ")");
      out[target] =
          read_uint(info.sparse_values + k * uint64_t(component_size(info.component_type)),
                    info.component_type);
    }
    return out;
  }

  // --- materials ---------------------------------------------------------------

  void read_materials() {
    const json& materials = top_array("materials");
    const size_t texture_count = top_array("textures").size();
    scene_.materials.resize(materials.size());
    uv_mappings_.resize(materials.size());
    material_images_.assign(materials.size(), -1);
    for (size_t m = 0; m < materials.size(); ++m) {
      const std::string what = "material " + std::to_string(m);
      const json& object = element(materials, m, what);
      Material& material = scene_.materials[m];
      material.name = opt_string(object, "name");
      const json* pbr = member(object, "pbrMetallicRoughness");
      if (!pbr) continue;
      if (const json* factor = member(*pbr, "baseColorFactor")) {
        const auto f = numbers<4>(*factor, what + " baseColorFactor");
        material.base_color = glm::vec4(f[0], f[1], f[2], f[3]);
      }
      const json* texture_info = member(*pbr, "baseColorTexture");
      if (!texture_info) continue;
      const int64_t texture =
          opt_index(*texture_info, "index", texture_count, what + " baseColorTexture", "textures");
      if (texture < 0) fail(what + " baseColorTexture has no 'index'");
      UvMapping& mapping = uv_mappings_[m];
      mapping.set = int(std::min<uint64_t>(
          opt_uint(*texture_info, "texCoord", 0, what + " baseColorTexture"), 1000));
      const json* extensions = member(*texture_info, "extensions");
      const json* transform = extensions ? member(*extensions, "KHR_texture_transform") : nullptr;
      if (transform && transform->is_object()) {
        const std::string twhat = what + " KHR_texture_transform";
        std::array<double, 2> offset{0, 0}, scale{1, 1};
        double rotation = 0;
        if (const json* v = member(*transform, "offset"))
          offset = numbers<2>(*v, twhat + " offset");
        if (const json* v = member(*transform, "scale")) scale = numbers<2>(*v, twhat + " scale");
        if (const json* v = member(*transform, "rotation"))
          rotation = as_number(*v, twhat + " rotation");
        if (member(*transform, "texCoord"))
          mapping.set = int(std::min<uint64_t>(opt_uint(*transform, "texCoord", 0, twhat), 1000));
        const double c = std::cos(rotation), s = std::sin(rotation);
        // KHR_texture_transform: uv' = T * R * S * uv (column-major below).
        mapping.matrix = glm::dmat3(c * scale[0], -s * scale[0], 0,  //
                                    s * scale[1], c * scale[1], 0,   //
                                    offset[0], offset[1], 1);
        mapping.transform = true;
      }
      material_images_[m] = texture_source(uint64_t(texture));
    }
  }

  /// Image index of a texture, or -1 (with a warning) if it only has sources
  /// in formats stb cannot decode.
  int texture_source(uint64_t texture) {
    const std::string what = "texture " + std::to_string(texture);
    const json& object = element(top_array("textures"), texture, what);
    const size_t image_count = top_array("images").size();
    const int64_t source = opt_index(object, "source", image_count, what, "images");
    if (source >= 0) return int(source);
    if (const json* extensions = member(object, "extensions")) {
      for (auto it = extensions->begin(); it != extensions->end(); ++it) {
        if (member(it.value(), "source")) {
          if (settings_.load_images)
            warn(what + ": only a " + one_line(it.key(), 40) +
                 " image is given, which snowmodel cannot decode; base color texture ignored");
          return -1;
        }
      }
    }
    return -1;
  }

  // --- node hierarchy ------------------------------------------------------------

  glm::dmat4 local_matrix(uint64_t node, const json& object) const {
    const std::string what = node_label(int(node));
    if (const json* matrix = member(object, "matrix")) {
      const auto m = numbers<16>(*matrix, what + " 'matrix'");
      glm::dmat4 out;
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) out[c][r] = m[size_t(c * 4 + r)];
      return out;
    }
    glm::dmat4 out(1.0);
    if (const json* t = member(object, "translation")) {
      const auto v = numbers<3>(*t, what + " 'translation'");
      out[3] = glm::dvec4(v[0], v[1], v[2], 1.0);
    }
    if (const json* r = member(object, "rotation")) {
      const auto q = numbers<4>(*r, what + " 'rotation'");
      glm::dquat quat(q[3], q[0], q[1], q[2]);  // glTF stores x, y, z, w
      const double length = glm::length(quat);
      if (!(length > 1e-12)) fail(what + " 'rotation' is a zero quaternion");
      out = out * glm::dmat4(glm::mat4_cast(quat / length));
    }
    if (const json* s = member(object, "scale")) {
      const auto v = numbers<3>(*s, what + " 'scale'");
      out = out * glm::dmat4(glm::dvec4(v[0], 0, 0, 0), glm::dvec4(0, v[1], 0, 0),
                             glm::dvec4(0, 0, v[2], 0), glm::dvec4(0, 0, 0, 1));
    }
    return out;
  }

  std::string node_name(int node) const {
    std::string name = opt_string(nodes()[size_t(node)], "name");
    return name.empty() ? "node" + std::to_string(node) : name;
  }

  std::string path_string(const std::vector<int>& path) const {
    std::string out;
    const size_t n = path.size();
    for (size_t i = 0; i < n; ++i) {
      if (n > kMaxPathNames && i == 4) {
        out += "/...(" + std::to_string(n - kMaxPathNames) + " levels)";
        i = n - (kMaxPathNames - 4) - 1;
        continue;
      }
      out += "/" + node_name(path[i]);
    }
    return out;
  }

  /// Roots of the scene to load, validated.
  std::vector<int> scene_roots(const std::vector<uint32_t>& parents) {
    const json& scenes = top_array("scenes");
    const size_t node_count = nodes().size();
    std::vector<int> roots;
    int64_t scene_index = opt_index(doc_, "scene", scenes.size(), "top-level", "scenes");
    if (scene_index < 0 && !scenes.empty()) scene_index = 0;
    if (scene_index < 0) {
      for (size_t n = 0; n < node_count; ++n)
        if (parents[n] == 0) roots.push_back(int(n));
      return roots;
    }
    const std::string what = "scene " + std::to_string(scene_index);
    const json& object = element(scenes, uint64_t(scene_index), what);
    const json* list = member(object, "nodes");
    if (!list) return roots;
    if (!list->is_array()) fail(what + " 'nodes' must be an array");
    for (const json& value : *list) {
      const uint64_t n = as_uint(value, what + " node");
      if (n >= node_count)
        fail(what + " lists node " + std::to_string(n) + ", out of range (" +
             std::to_string(node_count) + " nodes)");
      if (parents[n] != 0)
        warn(what + " lists " + node_label(int(n)) +
             ", which is a child of another node; its ancestors' transforms are not applied");
      roots.push_back(int(n));
    }
    return roots;
  }

  /// Iterative depth-first traversal: world matrices of every mesh node.
  std::vector<Instance> traverse() {
    const json& node_array = nodes();
    const size_t node_count = node_array.size();
    const size_t mesh_count = meshes().size();
    // Validate children and find parents (glTF node graphs are strict trees).
    std::vector<uint32_t> parents(node_count, 0);
    for (size_t n = 0; n < node_count; ++n) {
      const json& object = element(node_array, n, "node " + std::to_string(n));
      const json* children = member(object, "children");
      if (!children) continue;
      if (!children->is_array()) fail(node_label(int(n)) + " 'children' must be an array");
      for (const json& child : *children) {
        const uint64_t c = as_uint(child, node_label(int(n)) + " child");
        if (c >= node_count)
          fail(node_label(int(n)) + " has child " + std::to_string(c) + ", out of range (" +
               std::to_string(node_count) + " nodes)");
        if (c == n) fail("node cycle: " + node_label(int(n)) + " is its own child");
        if (++parents[c] > 1)
          fail(node_label(int(c)) + " is a child of more than one node (glTF needs a tree)");
      }
    }
    const std::vector<int> roots = scene_roots(parents);

    struct Entry {
      int node;
      bool exit;
      glm::dmat4 parent;
    };
    std::vector<Entry> stack;
    std::vector<uint8_t> state(node_count, 0);  // 0 new, 1 on the current path, 2 done
    std::vector<int> path;
    std::vector<Instance> instances;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it)
      stack.push_back({*it, false, glm::dmat4(1.0)});
    while (!stack.empty()) {
      const Entry entry = stack.back();
      stack.pop_back();
      const int n = entry.node;
      if (entry.exit) {
        state[size_t(n)] = 2;
        path.pop_back();
        continue;
      }
      if (state[size_t(n)] == 1) fail("node cycle through " + node_label(n));
      if (state[size_t(n)] == 2)
        fail(node_label(n) + " is reached twice in the scene (repeated root or shared child)");
      state[size_t(n)] = 1;
      path.push_back(n);
      ++scene_.stats.nodes;
      const json& object = node_array[size_t(n)];
      const glm::dmat4 world = entry.parent * local_matrix(uint64_t(n), object);
      if (!finite(world)) fail(node_label(n) + ": world transform is not finite");
      stack.push_back({n, true, glm::dmat4(1.0)});
      const int64_t mesh = opt_index(object, "mesh", mesh_count, node_label(n), "meshes");
      if (mesh >= 0) add_instances(n, int(mesh), world, object, path, instances);
      if (const json* children = member(object, "children")) {
        for (auto c = children->rbegin(); c != children->rend(); ++c)
          stack.push_back({int(c->get<uint64_t>()), false, world});
      }
    }
    return instances;
  }

  void add_instances(int node, int mesh, const glm::dmat4& world, const json& object,
                     const std::vector<int>& path, std::vector<Instance>& instances) {
    const uint32_t path_id = uint32_t(node_paths_.size());
    node_paths_.push_back(path_string(path));
    if (member(object, "skin"))
      warn(node_label(node) + ": skin ignored, " + mesh_label(mesh) +
           " placed in its bind pose by the node transform");
    const json* extensions = member(object, "extensions");
    const json* gpu = extensions ? member(*extensions, "EXT_mesh_gpu_instancing") : nullptr;
    const json* attributes = gpu ? member(*gpu, "attributes") : nullptr;
    if (!attributes || !attributes->is_object()) {
      instances.push_back({node, mesh, path_id, world});
      return;
    }
    // EXT_mesh_gpu_instancing: one instance per element of the TRS accessors.
    const std::string what = node_label(node) + " EXT_mesh_gpu_instancing";
    const size_t accessor_count = top_array("accessors").size();
    std::vector<float> t, r, s;
    uint64_t count = 0;
    bool have_count = false;
    auto read = [&](const char* name, int components, std::vector<float>& out) {
      const int64_t a = opt_index(*attributes, name, accessor_count, what, "accessors");
      if (a < 0) return;
      out = read_attribute(uint64_t(a), components, what + " " + name, nullptr);
      const uint64_t n = out.size() / size_t(components);
      if (have_count && n != count) fail(what + ": attribute counts differ");
      count = n;
      have_count = true;
    };
    read("TRANSLATION", 3, t);
    read("ROTATION", 4, r);
    read("SCALE", 3, s);
    if (!have_count) {
      instances.push_back({node, mesh, path_id, world});
      return;
    }
    if (count > settings_.limits.max_triangles)
      fail(what + ": " + std::to_string(count) + " instances exceed LoadLimits::max_triangles");
    for (uint64_t i = 0; i < count; ++i) {
      glm::dmat4 local(1.0);
      if (!t.empty()) local[3] = glm::dvec4(t[3 * i], t[3 * i + 1], t[3 * i + 2], 1.0);
      if (!r.empty()) {
        glm::dquat q(r[4 * i + 3], r[4 * i], r[4 * i + 1], r[4 * i + 2]);
        const double length = glm::length(q);
        if (!(length > 1e-12))
          fail(what + ": instance " + std::to_string(i) + " has a zero rotation");
        local = local * glm::dmat4(glm::mat4_cast(q / length));
      }
      if (!s.empty())
        local = local * glm::dmat4(glm::dvec4(s[3 * i], 0, 0, 0), glm::dvec4(0, s[3 * i + 1], 0, 0),
                                   glm::dvec4(0, 0, s[3 * i + 2], 0), glm::dvec4(0, 0, 0, 1));
      const glm::dmat4 instance_world = world * local;
      if (!finite(instance_world))
        fail(what + ": instance " + std::to_string(i) + " transform is not finite");
      instances.push_back({node, mesh, path_id, instance_world});
    }
  }

  // --- geometry --------------------------------------------------------------

  const json& primitives_of(int mesh) const {
    const std::string what = mesh_label(mesh);
    const json& object = element(meshes(), uint64_t(mesh), what);
    const json* primitives = member(object, "primitives");
    if (!primitives || !primitives->is_array()) fail(what + " has no 'primitives' array");
    return *primitives;
  }

  /// Triangles the mesh's primitives will produce, from validated declared
  /// counts (no decoding). Used to check the limit and reserve memory early.
  uint64_t estimate_triangles(int mesh) {
    uint64_t total = 0;
    const json& primitives = primitives_of(mesh);
    const size_t accessor_count = top_array("accessors").size();
    for (size_t p = 0; p < primitives.size(); ++p) {
      const json& prim = primitives[p];
      const std::string what = mesh_label(mesh) + " primitive " + std::to_string(p);
      const uint64_t mode = opt_uint(prim, "mode", 4, what);
      if (mode < 4 || mode > 6) continue;  // reported when decoded
      const json* attributes = member(prim, "attributes");
      int64_t source = opt_index(prim, "indices", accessor_count, what, "accessors");
      std::string role = what + " indices";
      if (source < 0 && attributes) {
        source = opt_index(*attributes, "POSITION", accessor_count, what, "accessors");
        role = what + " POSITION";
      }
      if (source < 0) continue;
      const uint64_t n = accessor_info(uint64_t(source), role).count;
      total += mode == 4 ? n / 3 : (n >= 3 ? n - 2 : 0);
    }
    return total;
  }

  PrimitiveGeometry decode_primitive(int mesh, uint64_t p, const json& prim) {
    PrimitiveGeometry geometry;
    const std::string mesh_text = mesh_label(mesh);
    const std::string what = mesh_text + " primitive " + std::to_string(p);
    if (!prim.is_object()) fail(what + " must be a JSON object");
    const uint64_t mode = opt_uint(prim, "mode", 4, what);
    if (mode > 6) fail(what + " has unknown mode " + std::to_string(mode));
    const std::string mesh_name = opt_string(meshes()[size_t(mesh)], "name");
    const std::string short_mesh =
        mesh_name.empty() ? std::to_string(mesh) : "'" + one_line(mesh_name, 60) + "'";
    if (mode < 4) {
      warn("ignoring primitive " + std::to_string(p) + " of mesh " + short_mesh + " (" +
           kModeNames[mode] + ")");
      ++scene_.stats.primitives_skipped;
      geometry.skip = true;
      return geometry;
    }
    geometry.material =
        int(opt_index(prim, "material", scene_.materials.size(), what, "materials"));
    const json* attributes = member(prim, "attributes");
    if (!attributes || !attributes->is_object()) fail(what + " has no 'attributes' object");
    const int uv_set = geometry.material >= 0 ? uv_mappings_[size_t(geometry.material)].set : 0;
    const std::string uv_name = "TEXCOORD_" + std::to_string(uv_set);

    const json* extensions = member(prim, "extensions");
    const json* draco = extensions ? member(*extensions, "KHR_draco_mesh_compression") : nullptr;
    if (draco && gltf_draco_supported()) {
      decode_draco(*draco, what, uv_name, geometry);
    } else {
      const size_t accessor_count = top_array("accessors").size();
      const int64_t position =
          opt_index(*attributes, "POSITION", accessor_count, what, "accessors");
      if (position < 0) {
        warn("ignoring primitive " + std::to_string(p) + " of mesh " + short_mesh +
             " (no POSITION)");
        ++scene_.stats.primitives_skipped;
        geometry.skip = true;
        return geometry;
      }
      AccessorInfo position_info;
      {
        const json* view = member(top_array("accessors")[size_t(position)], "bufferView");
        if (draco && !view)
          fail(what +
               " is compressed with KHR_draco_mesh_compression, but this build has no Draco "
               "decoder");
        if (!draco && !view && !member(top_array("accessors")[size_t(position)], "sparse"))
          warn(what + ": POSITION accessor " + std::to_string(position) +
               " has no data (all zeros)");
      }
      std::vector<float> values =
          read_attribute(uint64_t(position), 3, what + " POSITION", &position_info);
      const size_t vertex_count = values.size() / 3;
      geometry.positions.resize(vertex_count);
      std::memcpy(geometry.positions.data(), values.data(), values.size() * sizeof(float));
      const int64_t normal =
          settings_.shading ? opt_index(*attributes, "NORMAL", accessor_count, what, "accessors")
                            : -1;
      if (normal >= 0) {
        values = read_attribute(uint64_t(normal), 3, what + " NORMAL", nullptr);
        if (values.size() / 3 != vertex_count) {
          warn(what + ": NORMAL count differs from POSITION count; using flat normals");
        } else {
          geometry.normals.resize(vertex_count);
          std::memcpy(geometry.normals.data(), values.data(), values.size() * sizeof(float));
        }
      }
      const int64_t uv = settings_.shading ? opt_index(*attributes, uv_name.c_str(), accessor_count,
                                                       what, "accessors")
                                           : -1;
      if (uv >= 0) {
        values = read_attribute(uint64_t(uv), 2, what + " " + uv_name, nullptr);
        if (values.size() / 2 != vertex_count) {
          warn(what + ": " + uv_name + " count differs from POSITION count; ignored");
        } else {
          geometry.uvs.resize(vertex_count);
          std::memcpy(geometry.uvs.data(), values.data(), values.size() * sizeof(float));
        }
      }
      std::vector<uint32_t> indices;
      const int64_t index_accessor = opt_index(prim, "indices", accessor_count, what, "accessors");
      if (index_accessor >= 0) {
        indices = read_indices(uint64_t(index_accessor), what + " indices");
        for (size_t i = 0; i < indices.size(); ++i) {
          if (indices[i] >= vertex_count)
            fail(what + ": index " + std::to_string(indices[i]) + " (element " + std::to_string(i) +
                 " of accessor " + std::to_string(index_accessor) + ") is out of range (" +
                 std::to_string(vertex_count) + " vertices)");
        }
      } else {
        indices.resize(vertex_count);
        for (size_t i = 0; i < vertex_count; ++i) indices[i] = uint32_t(i);
      }
      expand_topology(int(mode), indices, what, geometry.triangles);
    }
    compact_vertices(geometry);
    if (!geometry.uvs.empty() && geometry.material >= 0) {
      const UvMapping& mapping = uv_mappings_[size_t(geometry.material)];
      if (mapping.transform) {
        for (glm::vec2& uv : geometry.uvs) uv = glm::vec2(mapping.matrix * glm::dvec3(uv, 1.0));
      }
    }
    return geometry;
  }

  /// Drops vertices no triangle uses (primitives often index a small part of
  /// a vertex array shared with others), so instances transform only these.
  static void compact_vertices(PrimitiveGeometry& g) {
    const size_t vertex_count = g.positions.size();
    if (g.triangles.size() >= vertex_count * 2) {
      // Usually every vertex is used: check before building a remap.
      std::vector<uint8_t> used(vertex_count, 0);
      for (uint32_t i : g.triangles) used[i] = 1;
      if (std::find(used.begin(), used.end(), 0) == used.end()) return;
    }
    std::vector<uint32_t> remap(vertex_count, UINT32_MAX);
    uint32_t next = 0;
    for (uint32_t& i : g.triangles) {
      if (remap[i] == UINT32_MAX) remap[i] = next++;
      i = remap[i];
    }
    auto gather = [&](auto& values) {
      if (values.empty()) return;
      std::remove_reference_t<decltype(values)> out(next);
      for (size_t v = 0; v < vertex_count; ++v)
        if (remap[v] != UINT32_MAX) out[remap[v]] = values[v];
      values = std::move(out);
    };
    gather(g.positions);
    gather(g.normals);
    gather(g.uvs);
  }

  /// TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN index lists to a triangle list
  /// (glTF 2.0 section 3.7.2.1 gives the vertex order of each triangle).
  void expand_topology(int mode, std::vector<uint32_t>& indices, const std::string& what,
                       std::vector<uint32_t>& triangles) {
    const size_t n = indices.size();
    if (mode == 4) {
      if (n % 3 != 0)
        warn(what + ": index count " + std::to_string(n) + " is not a multiple of 3; the last " +
             std::to_string(n % 3) + " ignored");
      indices.resize(n - n % 3);
      triangles = std::move(indices);
      return;
    }
    if (n < 3) return;
    triangles.resize((n - 2) * 3);
    for (size_t i = 0; i + 2 < n; ++i) {
      uint32_t* out = triangles.data() + 3 * i;
      if (mode == 5) {  // strip: {v_i, v_{i+1+i%2}, v_{i+2-i%2}}
        out[0] = indices[i];
        out[1] = indices[i + 1 + i % 2];
        out[2] = indices[i + 2 - i % 2];
      } else {  // fan: {v_{i+1}, v_{i+2}, v_0}
        out[0] = indices[i + 1];
        out[1] = indices[i + 2];
        out[2] = indices[0];
      }
    }
  }

  void decode_draco(const json& extension, const std::string& what, const std::string& uv_name,
                    PrimitiveGeometry& geometry) {
#ifdef SNOW_HAVE_DRACO
    const std::string dwhat = what + " KHR_draco_mesh_compression";
    const int64_t view_index =
        opt_index(extension, "bufferView", top_array("bufferViews").size(), dwhat, "bufferViews");
    if (view_index < 0) fail(dwhat + " has no 'bufferView'");
    const json* attributes = member(extension, "attributes");
    if (!attributes || !attributes->is_object()) fail(dwhat + " has no 'attributes' object");
    const ViewRange range = view(uint64_t(view_index), dwhat);
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(range.data), size_t(range.length));
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok())
      fail(dwhat + ": Draco decoding failed: " + one_line(decoded.status().error_msg_string()));
    const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    const uint64_t points = mesh->num_points();
    const uint64_t faces = mesh->num_faces();
    if (faces > settings_.limits.max_triangles || points > max_elements())
      fail(dwhat + ": " + std::to_string(faces) + " faces exceed LoadLimits::max_triangles");
    auto read = [&](const char* name, int components, std::vector<float>& out) -> bool {
      const json* id = member(*attributes, name);
      if (!id) return false;
      const draco::PointAttribute* attribute = mesh->GetAttributeByUniqueId(
          uint32_t(std::min<uint64_t>(as_uint(*id, dwhat + " " + name), UINT32_MAX)));
      if (!attribute) fail(dwhat + ": " + name + " refers to a missing Draco attribute");
      if (attribute->num_components() < components)
        fail(dwhat + ": " + name + " has " + std::to_string(int(attribute->num_components())) +
             " components");
      out.resize(size_t(points) * size_t(components));
      for (uint64_t i = 0; i < points; ++i) {
        const draco::AttributeValueIndex value =
            attribute->mapped_index(draco::PointIndex(uint32_t(i)));
        if (value.value() >= attribute->size() ||
            !attribute->ConvertValue<float>(value, int8_t(components),
                                            out.data() + i * size_t(components)))
          fail(dwhat + ": " + name + " value of point " + std::to_string(i) + " is unreadable");
      }
      for (float v : out)
        if (!std::isfinite(v)) fail(dwhat + ": " + name + " has a non-finite value");
      return true;
    };
    std::vector<float> values;
    if (!read("POSITION", 3, values)) fail(dwhat + " has no POSITION attribute");
    geometry.positions.resize(size_t(points));
    std::memcpy(geometry.positions.data(), values.data(), values.size() * sizeof(float));
    if (settings_.shading && read("NORMAL", 3, values)) {
      geometry.normals.resize(size_t(points));
      std::memcpy(geometry.normals.data(), values.data(), values.size() * sizeof(float));
    }
    if (settings_.shading && read(uv_name.c_str(), 2, values)) {
      geometry.uvs.resize(size_t(points));
      std::memcpy(geometry.uvs.data(), values.data(), values.size() * sizeof(float));
    }
    geometry.triangles.resize(size_t(faces) * 3);
    for (uint64_t f = 0; f < faces; ++f) {
      const draco::Mesh::Face& face = mesh->face(draco::FaceIndex(uint32_t(f)));
      for (int k = 0; k < 3; ++k) {
        const uint32_t index = face[k].value();
        if (index >= points)
          fail(dwhat + ": face " + std::to_string(f) + " has an out-of-range point");
        geometry.triangles[size_t(f) * 3 + size_t(k)] = index;
      }
    }
#else
    (void)extension;
    (void)uv_name;
    (void)geometry;
    fail(what +
         " is compressed with KHR_draco_mesh_compression, but this build has no Draco decoder");
#endif
  }

  const PrimitiveGeometry& geometry(int mesh, size_t p) {
    auto& slot = geometry_cache_[mesh];
    if (slot.empty()) {
      const json& primitives = primitives_of(mesh);
      slot.resize(primitives.size());
    }
    if (!slot[p])
      slot[p] =
          std::make_unique<PrimitiveGeometry>(decode_primitive(mesh, p, primitives_of(mesh)[p]));
    return *slot[p];
  }

  void build_geometry(const std::vector<Instance>& instances) {
    // Check the triangle limit and reserve memory from declared counts.
    std::unordered_map<int, uint64_t> estimate;
    std::unordered_map<int, uint32_t> uses;
    uint64_t total = 0;
    for (const Instance& instance : instances) {
      auto it = estimate.find(instance.mesh);
      if (it == estimate.end())
        it = estimate.emplace(instance.mesh, estimate_triangles(instance.mesh)).first;
      total += it->second;
      ++uses[instance.mesh];
      if (total > settings_.limits.max_triangles) fail_triangle_limit();
    }
    scene_.positions.reserve(size_t(total) * 3);
    if (settings_.shading) scene_.normals.reserve(size_t(total) * 3);
    Progress progress("load", double(instances.size()));
    std::vector<glm::vec3> world_positions, world_normals;
    for (size_t i = 0; i < instances.size(); ++i) {
      const Instance& instance = instances[i];
      ++scene_.stats.instances;
      const size_t primitive_count = primitives_of(instance.mesh).size();
      for (size_t p = 0; p < primitive_count; ++p) {
        const PrimitiveGeometry& g = geometry(instance.mesh, p);
        if (!g.skip) append(instance, int(p), g, world_positions, world_normals);
      }
      if (--uses[instance.mesh] == 0) geometry_cache_.erase(instance.mesh);
      progress.update(double(i + 1));
    }
  }

  void append(const Instance& instance, int primitive, const PrimitiveGeometry& g,
              std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn) {
    const uint64_t triangle_count = g.triangles.size() / 3;
    if (scene_.stats.triangles_read + triangle_count > settings_.limits.max_triangles)
      fail_triangle_limit();
    scene_.stats.triangles_read += triangle_count;
    const glm::dmat4& world = instance.world;
    const glm::dmat3 linear(world);
    const double det = glm::determinant(linear);
    const bool flip = det < 0;
    // det * inverse-transpose = columns (c1 x c2, c2 x c0, c0 x c1); the sign
    // of det keeps normals pointing the same way for mirrored instances.
    const double sign = det < 0 ? -1.0 : 1.0;
    const glm::mat3 normal_matrix(glm::dmat3(glm::cross(linear[1], linear[2]),
                                             glm::cross(linear[2], linear[0]),
                                             glm::cross(linear[0], linear[1])) *
                                  sign);
    // Vertices, then triangles, in chunks on all cores; each chunk writes its
    // own elements, and what it finds (the first vertex not finite, its kept
    // triangles, their bounds) is combined in chunk order, so the scene is
    // the same on any number of cores.
    const size_t vertex_count = g.positions.size();
    const size_t vertex_chunks = (vertex_count + kLoadChunk - 1) / kLoadChunk;
    wp.resize(vertex_count);
    std::vector<size_t> not_finite(vertex_chunks, SIZE_MAX);  // per chunk, the first
    const bool has_normals = !g.normals.empty();
    if (has_normals) wn.resize(vertex_count);
    parallel_for_ranges(vertex_count, kLoadChunk, [&](size_t begin, size_t end) {
      for (size_t v = begin; v < end; ++v) {
        const glm::dvec3 p = glm::dvec3(world * glm::dvec4(glm::dvec3(g.positions[v]), 1.0));
        wp[v] = glm::vec3(p);
        if (!std::isfinite(wp[v].x) || !std::isfinite(wp[v].y) || !std::isfinite(wp[v].z)) {
          not_finite[begin / kLoadChunk] = std::min(not_finite[begin / kLoadChunk], v);
        }
        if (!has_normals) continue;
        const glm::vec3 n = normal_matrix * g.normals[v];
        const float length = glm::length(n);
        wn[v] = length > 1e-30f && std::isfinite(length) ? n / length : glm::vec3(0.0f);
      }
    });
    for (const size_t v : not_finite) {
      if (v == SIZE_MAX) continue;
      fail(node_label(instance.node) + ": vertex " + std::to_string(v) + " of " +
           mesh_label(instance.mesh) + " is not finite in world space");
    }
    const bool has_uvs = !g.uvs.empty();
    if (has_uvs && scene_.uvs.empty() && !scene_.positions.empty())
      scene_.uvs.resize(scene_.positions.size(), glm::vec2(0.0f));
    const bool write_uvs = has_uvs || !scene_.uvs.empty();
    if (write_uvs && scene_.uvs.capacity() < scene_.positions.capacity())
      scene_.uvs.reserve(scene_.positions.capacity());

    SceneObject object;
    object.node = instance.node;
    object.mesh = instance.mesh;
    object.primitive = primitive;
    object.material = g.material;
    object.first_triangle = uint32_t(scene_.triangle_count());
    // Triangle t's corners as wound in world space, or false where it is
    // degenerate: a repeated index, or zero area (the height is below 1e-7
    // of the longest edge).
    const auto indices = [&](uint64_t t, uint32_t(&v)[3]) {
      v[0] = g.triangles[3 * t];
      v[1] = g.triangles[3 * t + 1];
      v[2] = g.triangles[3 * t + 2];
      if (flip) std::swap(v[1], v[2]);
    };
    const auto corners = [&](uint64_t t, uint32_t(&v)[3]) {
      indices(t, v);
      if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) return false;
      const glm::vec3 pa = wp[v[0]], pb = wp[v[1]], pc = wp[v[2]];
      const glm::dvec3 e0 = glm::dvec3(pb - pa), e1 = glm::dvec3(pc - pa), e2 = glm::dvec3(pc - pb);
      const glm::dvec3 cross = glm::cross(e0, e1);
      const double area2 = glm::dot(cross, cross);
      const double longest2 = std::max({glm::dot(e0, e0), glm::dot(e1, e1), glm::dot(e2, e2)});
      return area2 > 1e-14 * longest2 * longest2;
    };
    const size_t chunks = size_t((triangle_count + kLoadChunk - 1) / kLoadChunk);
    std::vector<size_t> chunk_kept(chunks + 1, 0);  // then each chunk's first output triangle
    std::vector<uint8_t> keep(triangle_count);      // corners() of each, worked out once
    parallel_for(chunks, [&](size_t c) {
      uint32_t v[3];
      for (uint64_t t = c * kLoadChunk;
           t < std::min<uint64_t>(triangle_count, (c + 1) * kLoadChunk); ++t) {
        keep[t] = corners(t, v);
        chunk_kept[c + 1] += keep[t];
      }
    });
    for (size_t c = 0; c < chunks; ++c) chunk_kept[c + 1] += chunk_kept[c];
    const uint64_t kept = chunk_kept[chunks];
    scene_.stats.degenerate_dropped += triangle_count - kept;
    const size_t out = scene_.positions.size();
    scene_.positions.resize(out + 3 * kept);
    if (settings_.shading) {
      scene_.normals.resize(out + 3 * kept);
      if (write_uvs) scene_.uvs.resize(out + 3 * kept);
    }
    std::vector<Bounds> chunk_bounds(chunks);
    parallel_for(chunks, [&](size_t c) {
      size_t at = out + 3 * chunk_kept[c];
      uint32_t v[3];
      for (uint64_t t = c * kLoadChunk;
           t < std::min<uint64_t>(triangle_count, (c + 1) * kLoadChunk); ++t) {
        if (!keep[t]) continue;
        indices(t, v);
        glm::vec3 face(0.0f);
        if (settings_.shading) {
          const glm::dvec3 cross =
              glm::cross(glm::dvec3(wp[v[1]] - wp[v[0]]), glm::dvec3(wp[v[2]] - wp[v[0]]));
          face = glm::vec3(cross / std::sqrt(glm::dot(cross, cross)));
        }
        for (const uint32_t corner : v) {
          scene_.positions[at] = wp[corner];
          chunk_bounds[c].extend(wp[corner]);
          if (settings_.shading) {
            glm::vec3 n = face;
            if (has_normals &&
                (wn[corner].x != 0.0f || wn[corner].y != 0.0f || wn[corner].z != 0.0f)) {
              n = wn[corner];
            }
            scene_.normals[at] = n;
            if (write_uvs) scene_.uvs[at] = has_uvs ? g.uvs[corner] : glm::vec2(0.0f);
          }
          ++at;
        }
      }
    });
    for (const Bounds& b : chunk_bounds) {
      if (b.empty()) continue;
      scene_.bounds.extend(b.min);
      scene_.bounds.extend(b.max);
    }
    if (kept == 0) return;
    if (scene_.triangle_count() > UINT32_MAX) fail("the scene has more than 2^32 triangles");
    object.triangle_count = uint32_t(kept);
    const std::string node_name = opt_string(nodes()[size_t(instance.node)], "name");
    const std::string mesh_name = opt_string(meshes()[size_t(instance.mesh)], "name");
    object.name = !node_name.empty()   ? node_name
                  : !mesh_name.empty() ? mesh_name
                                       : "mesh" + std::to_string(instance.mesh) + ".prim" +
                                             std::to_string(primitive);
    object.node_path = node_paths_[instance.path];
    scene_.objects.push_back(std::move(object));
  }

  // --- images ------------------------------------------------------------------

  void load_images() {
    std::vector<uint8_t> used(scene_.materials.size(), 0);
    for (const SceneObject& object : scene_.objects)
      if (object.material >= 0) used[size_t(object.material)] = 1;
    std::unordered_map<int, int> decoded;  // glTF image -> Scene::images index (-1: failed)
    for (size_t m = 0; m < scene_.materials.size(); ++m) {
      const int image = material_images_[m];
      if (!used[m] || image < 0) continue;
      auto it = decoded.find(image);
      if (it == decoded.end()) it = decoded.emplace(image, decode_image(image)).first;
      scene_.materials[m].base_color_image = it->second;
    }
  }

  int decode_image(int index) {
    const std::string what = "image " + std::to_string(index);
    const json& object = element(top_array("images"), uint64_t(index), what);
    const std::string name = opt_string(object, "name");
    std::string mime = opt_string(object, "mimeType");
    Bytes owned;
    const uint8_t* data = nullptr;
    uint64_t size = 0;
    std::string label = what;
    if (const json* uri_value = member(object, "uri")) {
      if (!uri_value->is_string()) fail(what + " 'uri' must be a string");
      const std::string uri = uri_value->get<std::string>();
      if (starts_with_ci(uri, "data:")) {
        owned = decode_data_uri(uri, what, &mime);
      } else {
        label = what + " ('" + one_line(uri, 60) + "')";
        const fs::path file = resolve_uri(uri, what);
        bool missing = false;
        owned = read_file(file, label, true, &missing);
        if (missing) {
          warn(label + ": file not found; base color texture ignored");
          return -1;
        }
      }
      data = owned.data();
      size = owned.size();
    } else {
      const int64_t view_index =
          opt_index(object, "bufferView", top_array("bufferViews").size(), what, "bufferViews");
      if (view_index < 0) fail(what + " has neither 'uri' nor 'bufferView'");
      const ViewRange range = view(uint64_t(view_index), what);
      data = range.data;
      size = range.length;
    }
    if (size == 0 || size > uint64_t(INT32_MAX)) {
      warn(label + ": empty or oversized image; base color texture ignored");
      return -1;
    }
    int width = 0, height = 0, channels = 0;
    if (!stbi_info_from_memory(data, int(size), &width, &height, &channels)) {
      warn(label + ": cannot decode " + (mime.empty() ? std::string("image") : one_line(mime, 40)) +
           " (" + one_line(stbi_failure_reason() ? stbi_failure_reason() : "unknown format", 60) +
           "); base color texture ignored");
      return -1;
    }
    if (width <= 0 || height <= 0 ||
        uint64_t(width) * uint64_t(height) > settings_.limits.max_image_pixels) {
      warn(label + ": " + std::to_string(width) + "x" + std::to_string(height) +
           " pixels, over LoadLimits::max_image_pixels; base color texture ignored");
      return -1;
    }
    stbi_uc* pixels = stbi_load_from_memory(data, int(size), &width, &height, &channels, 4);
    if (!pixels) {
      warn(label + ": decoding failed (" +
           one_line(stbi_failure_reason() ? stbi_failure_reason() : "?", 60) +
           "); base color texture ignored");
      return -1;
    }
    Image image;
    image.name = name;
    image.width = width;
    image.height = height;
    image.rgba.assign(pixels, pixels + size_t(width) * size_t(height) * 4);
    stbi_image_free(pixels);
    scene_.images.push_back(std::move(image));
    return int(scene_.images.size() - 1);
  }

  // --- state -------------------------------------------------------------------

  fs::path path_;
  fs::path folder_;
  LoadSettings settings_;
  std::string label_;
  Bytes file_;
  bool is_glb_ = false;
  bool has_glb_bin_ = false;
  const uint8_t* glb_bin_ = nullptr;
  uint64_t glb_bin_size_ = 0;
  json doc_;
  std::vector<BufferSlot> slots_;
  std::vector<UvMapping> uv_mappings_;
  std::vector<int> material_images_;
  std::vector<std::string> node_paths_;
  std::unordered_map<int, std::vector<std::unique_ptr<PrimitiveGeometry>>> geometry_cache_;
  Scene scene_;
};

}  // namespace

uint64_t gltf_input_bytes(const std::filesystem::path& path) {
  const auto extension_is = [](const std::filesystem::path& p, const char* ext) {
    return lower_extension(p) == ext;
  };
  std::error_code error;
  uintmax_t bytes = std::filesystem::file_size(path, error);
  if (error) return 0;
  if (extension_is(path, ".gltf")) {
    const std::filesystem::path folder =
        path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
    // Never throws: a folder that cannot be listed, or changes meanwhile,
    // counts what was seen.
    for (std::filesystem::directory_iterator it(folder, error), end; !error && it != end;
         it.increment(error)) {
      std::error_code size_error;
      if (!extension_is(it->path(), ".bin")) continue;
      const uintmax_t size = it->file_size(size_error);
      if (!size_error) bytes += size;
    }
  }
  return uint64_t(bytes);
}

bool gltf_draco_supported() {
#ifdef SNOW_HAVE_DRACO
  return true;
#else
  return false;
#endif
}

Scene load_scene(const std::filesystem::path& path, const LoadSettings& settings) {
  try {
    GltfLoader loader(path, settings);
    return loader.load();
  } catch (const std::bad_alloc&) {
    throw InputError(path.string() +
                     ": out of memory while loading (scene too large for this machine)");
  } catch (const std::length_error&) {
    throw InputError(path.string() +
                     ": out of memory while loading (scene too large for this machine)");
  }
}

// --- summaries ---------------------------------------------------------------

namespace {

json vec_json(const glm::vec3& v) { return json::array({v.x, v.y, v.z}); }

std::string format_vec(const glm::vec3& v) {
  char text[96];
  std::snprintf(text, sizeof(text), "(%.4g, %.4g, %.4g)", double(v.x), double(v.y), double(v.z));
  return text;
}

}  // namespace

std::string scene_summary_json(const Scene& scene) {
  json out;
  out["triangles"] = scene.triangle_count();
  out["stats"] = {{"triangles_read", scene.stats.triangles_read},
                  {"degenerate_dropped", scene.stats.degenerate_dropped},
                  {"primitives_skipped", scene.stats.primitives_skipped},
                  {"nodes", scene.stats.nodes},
                  {"instances", scene.stats.instances}};
  if (scene.bounds.empty()) {
    out["bounds"] = nullptr;
  } else {
    out["bounds"] = {{"unit", "m"},
                     {"up", "+Y"},
                     {"min", vec_json(scene.bounds.min)},
                     {"max", vec_json(scene.bounds.max)},
                     {"size", vec_json(scene.bounds.size())}};
  }
  json objects = json::array();
  for (const SceneObject& o : scene.objects) {
    objects.push_back({{"name", o.name},
                       {"node_path", o.node_path},
                       {"node", o.node},
                       {"mesh", o.mesh},
                       {"primitive", o.primitive},
                       {"material", o.material},
                       {"first_triangle", o.first_triangle},
                       {"triangles", o.triangle_count}});
  }
  out["objects"] = std::move(objects);
  json materials = json::array();
  for (const Material& m : scene.materials) {
    materials.push_back(
        {{"name", m.name},
         {"base_color", {m.base_color.r, m.base_color.g, m.base_color.b, m.base_color.a}},
         {"base_color_image", m.base_color_image}});
  }
  out["materials"] = std::move(materials);
  json images = json::array();
  for (const Image& image : scene.images)
    images.push_back({{"name", image.name}, {"width", image.width}, {"height", image.height}});
  out["images"] = std::move(images);
  out["has_uvs"] = !scene.uvs.empty();
  out["warnings"] = scene.warnings;
  // Names come from the file and may hold invalid UTF-8: replace, never throw.
  return out.dump(2, ' ', false, json::error_handler_t::replace);
}

std::string scene_summary_text(const Scene& scene) {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof(line),
                "triangles: %zu (read %llu, degenerate dropped %llu)\n"
                "objects: %zu   materials: %zu   images: %zu   nodes: %llu   instances: %llu   "
                "primitives skipped: %llu\n",
                scene.triangle_count(), static_cast<unsigned long long>(scene.stats.triangles_read),
                static_cast<unsigned long long>(scene.stats.degenerate_dropped),
                scene.objects.size(), scene.materials.size(), scene.images.size(),
                static_cast<unsigned long long>(scene.stats.nodes),
                static_cast<unsigned long long>(scene.stats.instances),
                static_cast<unsigned long long>(scene.stats.primitives_skipped));
  out += line;
  if (scene.bounds.empty()) {
    out += "bounds: empty\n";
  } else {
    const glm::vec3 size = scene.bounds.size();
    std::snprintf(line, sizeof(line),
                  "bounds (m, +Y up): min %s max %s, size %.4g x %.4g x %.4g m\n",
                  format_vec(scene.bounds.min).c_str(), format_vec(scene.bounds.max).c_str(),
                  double(size.x), double(size.y), double(size.z));
    out += line;
  }
  out += "objects:\n";
  constexpr size_t kMaxListed = 50;
  for (size_t i = 0; i < scene.objects.size() && i < kMaxListed; ++i) {
    const SceneObject& o = scene.objects[i];
    std::string material = "-";
    if (o.material >= 0 && size_t(o.material) < scene.materials.size()) {
      const std::string& name = scene.materials[size_t(o.material)].name;
      material = std::to_string(o.material) + (name.empty() ? "" : " '" + one_line(name, 40) + "'");
    }
    std::snprintf(line, sizeof(line), "  %4zu  %9u tris  mesh %d prim %d  material %s  %s\n", i,
                  o.triangle_count, o.mesh, o.primitive, material.c_str(),
                  one_line(o.node_path, 200).c_str());
    out += line;
  }
  if (scene.objects.size() > kMaxListed)
    out += "  ... and " + std::to_string(scene.objects.size() - kMaxListed) + " more\n";
  if (!scene.warnings.empty()) {
    out += "warnings: " + std::to_string(scene.warnings.size()) + "\n";
    for (const std::string& w : scene.warnings) out += "  - " + one_line(w, 300) + "\n";
  }
  if (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

}  // namespace snow

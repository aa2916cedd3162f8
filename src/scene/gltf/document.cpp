// Part of the glTF loader (see scene/gltf/internal.h): the file and its JSON.
// The GLB container (glTF 2.0 section 4.4), buffers and bufferViews (3.6),
// URIs relative to the scene's folder, data: URIs (RFC 2397) with base64
// (RFC 4648), and the JSON accessors that validate every value.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <system_error>

#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"
#include "scene/gltf/internal.h"
#include "scene/input_policy.h"

namespace snow {
namespace gltf {
namespace {

namespace fs = std::filesystem;

constexpr uint32_t kGlbMagic = 0x46546C67;   // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"

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

uint32_t read_u32_le(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

/// Strict base64 (RFC 4648); whitespace is ignored. False on bad input.
template <class Out>
bool base64_decode(std::string_view in, Out& out) {
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

/// The bytes of the data: URI `uri` (which starts with "data:") into `out`,
/// its media type in *mime; null, else what is wrong with it.
template <class Out>
const char* data_uri_bytes(const std::string& uri, Out& out, std::string* mime) {
  const size_t comma = uri.find(',');
  if (comma == std::string::npos) return "malformed data uri (no ',')";
  const std::string header = uri.substr(5, comma - 5);
  if (mime) *mime = header.substr(0, header.find(';'));
  const std::string_view payload(uri.data() + comma + 1, uri.size() - comma - 1);
  if (header.size() >= 7 && header.compare(header.size() - 7, 7, ";base64") == 0) {
    if (!base64_decode(payload, out)) return "data uri is not valid base64";
  } else {
    std::string raw;
    if (!percent_decode(payload, raw)) return "malformed data uri";
    out.assign(raw.begin(), raw.end());
  }
  return nullptr;
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

}  // namespace

/// Makes text from the file safe for a one-line message: control characters
/// become spaces, invalid UTF-8 bytes '?', and long text is cut with "...".
std::string one_line(std::string_view text, size_t max_chars) {
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

bool starts_with_ci(std::string_view s, std::string_view prefix) {
  if (s.size() < prefix.size()) return false;
  for (size_t i = 0; i < prefix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(s[i])) != prefix[i]) return false;
  }
  return true;
}

// --- errors and warnings -----------------------------------------------------

void GltfLoader::fail(const std::string& message) const {
  throw InputError(label_ + ": " + message);
}

void GltfLoader::fail_triangle_limit() const {
  fail("the scene has more triangles than the limit of " +
       std::to_string(settings_.limits.max_triangles) + " (LoadLimits::max_triangles)");
}

void GltfLoader::warn(const std::string& message) {
  scene_.warnings.push_back(message);
  log_warn(message);
}

// --- JSON access with validation ---------------------------------------------

const json* GltfLoader::member(const json& object, const char* key) const {
  if (!object.is_object()) return nullptr;
  auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

const json& GltfLoader::top_array(const char* key) const {
  static const json empty = json::array();
  const json* value = member(doc_, key);
  if (!value) return empty;
  if (!value->is_array()) fail(std::string("'") + key + "' must be an array");
  return *value;
}

const json& GltfLoader::element(const json& array, uint64_t index, const std::string& what) const {
  const json& value = array[size_t(index)];
  if (!value.is_object()) fail(what + " must be a JSON object");
  return value;
}

uint64_t GltfLoader::as_uint(const json& value, const std::string& what) const {
  if (value.is_number_unsigned()) return value.get<uint64_t>();
  if (value.is_number_integer() && value.get<int64_t>() >= 0) return value.get<uint64_t>();
  if (value.is_number_float()) {
    const double d = value.get<double>();
    if (d >= 0 && d <= 9007199254740992.0 && std::floor(d) == d) return static_cast<uint64_t>(d);
  }
  fail(what + " must be a non-negative integer, not " +
       one_line(value.dump(-1, ' ', false, json::error_handler_t::replace), 40));
}

uint64_t GltfLoader::opt_uint(const json& object, const char* key, uint64_t fallback,
                              const std::string& what) const {
  const json* value = member(object, key);
  return value ? as_uint(*value, what + " '" + key + "'") : fallback;
}

int64_t GltfLoader::opt_index(const json& object, const char* key, size_t size,
                              const std::string& what, const char* things) const {
  const json* value = member(object, key);
  if (!value) return -1;
  const uint64_t index = as_uint(*value, what + " '" + key + "'");
  if (index >= size)
    fail(what + " '" + key + "' = " + std::to_string(index) + " is out of range (" +
         std::to_string(size) + " " + things + ")");
  return int64_t(index);
}

double GltfLoader::as_number(const json& value, const std::string& what) const {
  if (!value.is_number()) fail(what + " must be a number");
  const double d = value.get<double>();
  if (!std::isfinite(d)) fail(what + " is not finite");
  return d;
}

std::string GltfLoader::opt_string(const json& object, const char* key) const {
  const json* value = member(object, key);
  return value && value->is_string() ? value->get<std::string>() : std::string();
}

std::string GltfLoader::mesh_label(int mesh) const {
  const std::string name = opt_string(meshes()[size_t(mesh)], "name");
  return name.empty() ? "mesh " + std::to_string(mesh)
                      : "mesh " + std::to_string(mesh) + " ('" + one_line(name, 60) + "')";
}

std::string GltfLoader::node_label(int node) const {
  const std::string name = opt_string(nodes()[size_t(node)], "name");
  return name.empty() ? "node " + std::to_string(node)
                      : "node " + std::to_string(node) + " ('" + one_line(name, 60) + "')";
}

// --- files and URIs ------------------------------------------------------------

Bytes GltfLoader::read_file(const fs::path& file, const std::string& what, bool missing_ok,
                            bool* missing, uint64_t at_most) {
  std::error_code ec;
  const auto status = fs::status(file, ec);
  if (ec || !fs::exists(status)) {
    if (missing) *missing = true;
    if (missing_ok) return {};
    fail(what + ": file '" + one_line(file.string()) + "' does not exist");
  }
  if (!fs::is_regular_file(status))
    fail(what + ": '" + one_line(file.string()) + "' is not a regular file");
  const uint64_t size = std::min<uint64_t>(fs::file_size(file, ec), at_most);
  if (ec) fail(what + ": cannot read '" + one_line(file.string()) + "'");
  if (size > settings_.limits.max_file_bytes)
    fail(what + ": '" + one_line(file.string()) + "' is " + std::to_string(size) +
         " bytes, over the limit of " + std::to_string(settings_.limits.max_file_bytes) +
         " (LoadLimits::max_file_bytes)");
  charge(size, what);
  Bytes bytes(size);
  std::string why;
  if (!read_regular_file(file, size, bytes.data(), &why))
    fail(what + ": '" + one_line(file.string()) + "' " + why);
  return bytes;
}

void GltfLoader::charge(uint64_t bytes, const std::string& what) {
  const uint64_t budget = settings_.limits.memory_budget;
  if (bytes <= budget && loaded_bytes_ <= budget - bytes) {
    loaded_bytes_ += bytes;
    return;
  }
  const auto gib = [](uint64_t b) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3g GiB", double(b) / double(uint64_t(1) << 30));
    return std::string(text);
  };
  fail(what + ": " + gib(bytes) + " more would bring the scene's data in memory to " +
       gib(loaded_bytes_ + std::min(bytes, UINT64_MAX - loaded_bytes_)) +
       ", over the memory budget of " + gib(budget) + " (--memory-budget)");
}

fs::path GltfLoader::resolve_uri(const std::string& uri, const std::string& what) const {
  std::string why;
  std::optional<fs::path> file = resolve_relative_uri(folder_, uri, &why);
  if (!file) fail(what + ": uri '" + one_line(uri) + "' " + why);
  return *file;
}

Bytes GltfLoader::decode_data_uri(const std::string& uri, const std::string& what,
                                  std::string* mime) const {
  Bytes bytes;
  if (const char* why = data_uri_bytes(uri, bytes, mime)) fail(what + ": " + why);
  if (bytes.size() > settings_.limits.max_file_bytes)
    fail(what + ": data uri is over the limit of " +
         std::to_string(settings_.limits.max_file_bytes) + " bytes (LoadLimits::max_file_bytes)");
  return bytes;
}

// --- document --------------------------------------------------------------------

void GltfLoader::read_document() {
  {
    // Looked at, not opened: a FIFO would block the open.
    const std::string problem = regular_file_problem(path_);
    if (problem == "does not exist") throw IOError(label_ + ": file does not exist");
    if (problem == "is a folder") throw IOError(label_ + ": is a folder, not a glTF file");
    if (!problem.empty()) fail(problem);
    if (::access(path_.c_str(), R_OK) != 0) throw IOError(label_ + ": cannot open file");
  }
  std::error_code time_error;
  file_modified_ = fs::last_write_time(path_, time_error);  // for SourceGltf::modified
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
  check_json_depth(std::string_view(reinterpret_cast<const char*>(json_begin), size_t(json_size)),
                   label_);
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
  if (asset) scene_.generator = one_line(opt_string(*asset, "generator"), 100);
  if (version.empty()) {
    warn("'asset.version' is missing; reading the file as glTF 2.0");
  } else if (version[0] != '2') {
    fail("glTF version " + one_line(version, 20) + " is not supported (only 2.x)");
  }
}

void GltfLoader::parse_glb_container(const uint8_t*& json_begin, uint64_t& json_size) {
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

void GltfLoader::check_extensions() {
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

void GltfLoader::check_uris() const {
  for (const char* key : {"buffers", "images"}) {
    const json& array = top_array(key);
    for (size_t i = 0; i < array.size(); ++i) {
      const json* uri = member(array[i], "uri");
      if (!uri || !uri->is_string() || starts_with_ci(uri->get_ref<const std::string&>(), "data:"))
        continue;  // the element's reader checks the rest
      resolve_uri(uri->get<std::string>(),
                  std::string(key).substr(0, std::strlen(key) - 1) + " " + std::to_string(i));
    }
  }
}

// --- buffers and views -----------------------------------------------------------

const BufferSlot& GltfLoader::buffer(uint64_t index) {
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
      charge(slot.owned.size(), what);
    } else {
      const fs::path file = resolve_uri(uri, what);
      // Only the declared bytes: a larger file's rest is never read.
      slot.owned =
          read_file(file, what + " ('" + one_line(uri, 60) + "')", false, nullptr, slot.size);
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

ViewRange GltfLoader::view(uint64_t index, const std::string& user) {
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

}  // namespace gltf

std::optional<std::vector<uint8_t>> decode_data_uri(const std::string& uri, std::string* mime,
                                                    std::string* why) {
  std::vector<uint8_t> bytes;
  const char* problem = gltf::starts_with_ci(uri, "data:") ? gltf::data_uri_bytes(uri, bytes, mime)
                                                           : "is not a data uri";
  if (!problem) return bytes;
  if (why) *why = problem;
  return std::nullopt;
}

std::optional<std::filesystem::path> resolve_relative_uri(const std::filesystem::path& folder,
                                                          const std::string& uri,
                                                          std::string* why) {
  std::string decoded;
  const auto refuse = [&](const char* reason) -> std::optional<std::filesystem::path> {
    if (why) *why = reason;
    return std::nullopt;
  };
  if (!gltf::percent_decode(uri, decoded)) return refuse("is malformed");
  std::replace(decoded.begin(), decoded.end(), '\\', '/');
  // A scheme ("http:", "file:", "data:", "C:") is not a relative path.
  const size_t colon = decoded.find(':');
  const size_t slash = decoded.find('/');
  if (colon != std::string::npos && (slash == std::string::npos || colon < slash))
    return refuse("is not a relative file path (refused)");
  if (decoded.empty()) return refuse("is empty");
  const std::filesystem::path relative(decoded);
  if (relative.is_absolute() || relative.has_root_path())
    return refuse("is an absolute path (refused)");
  for (const auto& part : relative) {
    if (part == "..") return refuse("leaves the scene's folder (refused)");
  }
  // A symlink on the way may still lead out of the folder.
  const std::filesystem::path file = folder / relative;
  if (!inside_folder(folder, file))
    return refuse("leads out of the scene's folder through a symlink (refused)");
  return file;
}

}  // namespace snow

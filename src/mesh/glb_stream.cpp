// The combined GLB streamed from the input's files (mesh/glb_stream.h; GLB
// layout: Khronos glTF 2.0 specification, section 4).
#include "mesh/glb_stream.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"
#include "mesh/export.h"
#include "mesh/gltf_writer.h"
#include "scene/input_policy.h"
#include "scene/load_gltf.h"

namespace snow {
namespace fs = std::filesystem;
using nlohmann::json;

std::string sniff_mime_type(const std::vector<unsigned char>& b) {
  auto starts = [&](std::initializer_list<int> sig, size_t at = 0) {
    if (b.size() < at + sig.size()) return false;
    size_t k = at;
    for (int c : sig) {
      if (b[k++] != static_cast<unsigned char>(c)) return false;
    }
    return true;
  };
  if (starts({0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a})) return "image/png";
  if (starts({0xff, 0xd8, 0xff})) return "image/jpeg";
  if (starts({'R', 'I', 'F', 'F'}) && starts({'W', 'E', 'B', 'P'}, 8)) return "image/webp";
  if (starts({0xab, 'K', 'T', 'X', ' ', '2', '0', 0xbb})) return "image/ktx2";
  return {};
}

namespace {

constexpr uint32_t kGlbMagic = 0x46546C67u;  // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534Au;
constexpr uint32_t kChunkBin = 0x004E4942u;

uint32_t u32_at(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

bool is_index(const json& v) { return v.is_number_unsigned(); }

/// `text` with control characters as spaces, cut at 200 bytes: for a
/// one-line message.
std::string one_line(std::string text) {
  if (text.size() > 200) text = text.substr(0, 200) + "...";
  for (char& c : text)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) c = ' ';
  return text;
}

/// A data: URI (RFC 2397; the scheme is case-insensitive).
bool starts_with_data(const std::string& uri) {
  static const char kData[] = "data:";
  if (uri.size() < 5) return false;
  for (size_t i = 0; i < 5; ++i)
    if (std::tolower(static_cast<unsigned char>(uri[i])) != kData[i]) return false;
  return true;
}
bool is_array_or_absent(const json& j, const char* key) {
  return !j.contains(key) || j[key].is_array();
}

/// `bytes` of `file`, with the file's size and modification time now;
/// nullopt when they cannot be read.
std::optional<FileBytes> file_bytes(const fs::path& file, uint64_t offset, uint64_t length) {
  std::error_code ec;
  FileBytes bytes{file, offset, length, fs::file_size(file, ec), {}};
  if (ec) return std::nullopt;
  bytes.modified = fs::last_write_time(file, ec);
  if (ec) return std::nullopt;
  return bytes;
}

}  // namespace

std::optional<StreamPlan> plan_streamed_glb(const fs::path& input) {
  std::error_code ec;
  const uint64_t file_size = fs::file_size(input, ec);
  if (ec) return std::nullopt;
  std::ifstream in(input, std::ios::binary);
  unsigned char header[20] = {};
  if (!in || !in.read(reinterpret_cast<char*>(header), std::min<uint64_t>(20, file_size)))
    return std::nullopt;
  std::string text;
  std::optional<FileBytes> bin;  // a GLB's BIN chunk
  if (file_size >= 20 && u32_at(header) == kGlbMagic) {
    const uint64_t length = u32_at(header + 8), json_length = u32_at(header + 12);
    if (u32_at(header + 4) != 2 || length > file_size || u32_at(header + 16) != kChunkJson ||
        20 + json_length > length) {
      return std::nullopt;
    }
    text.resize(json_length);
    if (!in.read(text.data(), std::streamsize(json_length))) return std::nullopt;
    const uint64_t next = 20 + ((json_length + 3) & ~uint64_t(3));
    unsigned char chunk[8];
    if (next + 8 <= length && in.seekg(std::streamoff(next)) &&
        in.read(reinterpret_cast<char*>(chunk), 8) && u32_at(chunk + 4) == kChunkBin) {
      const uint64_t bin_length = u32_at(chunk);
      if (next + 8 + bin_length > length) return std::nullopt;
      bin = file_bytes(input, next + 8, bin_length);
      if (!bin) return std::nullopt;
    }
  } else {
    text.resize(file_size);
    in.seekg(0);
    if (!in.read(text.data(), std::streamsize(file_size))) return std::nullopt;
  }
  StreamPlan plan;
  check_json_depth(text, input.string());  // before any parser sees it
  try {
    plan.gltf = json::parse(text);
  } catch (const json::exception&) {
    return std::nullopt;
  }
  text = {};
  json& g = plan.gltf;
  if (!g.is_object() || !g.contains("asset") || !g["asset"].is_object()) return std::nullopt;
  for (const char* key : {"buffers", "bufferViews", "accessors", "images", "materials", "meshes",
                          "nodes", "scenes"}) {
    if (!is_array_or_absent(g, key)) return std::nullopt;
  }
  if (g.contains("scene") && !is_index(g["scene"])) return std::nullopt;
  if (g.contains("scenes")) {
    for (const json& scene : g["scenes"]) {
      if (!scene.is_object() || !is_array_or_absent(scene, "nodes")) return std::nullopt;
    }
  }
  const fs::path folder = input.parent_path();
  // One buffer at most: buffer indices then need no change anywhere
  // (EXT_meshopt_compression's included).
  if (g.contains("buffers")) {
    const json& buffers = g["buffers"];
    if (buffers.size() > 1) return std::nullopt;
    if (buffers.size() == 1) {
      const json& b = buffers[0];
      if (!b.is_object() || !b.contains("byteLength") || !is_index(b["byteLength"]))
        return std::nullopt;
      const uint64_t length = b["byteLength"].get<uint64_t>();
      if (b.contains("uri")) {
        if (bin || !b["uri"].is_string()) return std::nullopt;
        const std::string uri = b["uri"].get<std::string>();
        std::string why;
        const std::optional<fs::path> file = resolve_relative_uri(folder, uri, &why);
        if (!file && !starts_with_data(uri))
          throw InputError(input.string() + ": buffer 0: uri '" + one_line(uri) + "' " + why);
        if (file) plan.buffer = file_bytes(*file, 0, length);
        if (!plan.buffer || plan.buffer->file_size < length) return std::nullopt;
      } else if (length > 0) {
        if (!bin || bin->length < length) return std::nullopt;
        plan.buffer = bin;  // its bytes' start, with the file's size and time read above
        plan.buffer->length = length;
      }
    }
  }
  if (g.contains("images")) {
    json& images = g["images"];
    for (size_t i = 0; i < images.size(); ++i) {
      const json& image = images[i];
      if (!image.is_object()) return std::nullopt;
      if (!image.contains("uri")) continue;  // in a buffer view: kept as it is
      if (!image["uri"].is_string()) return std::nullopt;
      const std::string uri = image["uri"].get<std::string>();
      const std::string what = input.string() + ": image " + std::to_string(i) + " ('" + uri + "')";
      std::string why;
      const std::optional<fs::path> file = resolve_relative_uri(folder, uri, &why);
      if (!file && starts_with_data(uri)) return std::nullopt;  // tinygltf decodes it
      if (!file) throw InputError(one_line(what) + ": uri " + why);
      const auto keep_uri = [&](const char* reason) {
        plan.kept_by_uri.push_back(what + reason + "; the output refers to it by its URI as it is");
      };
      // The whole file, and its first bytes for its format.
      std::optional<FileBytes> bytes = file ? file_bytes(*file, 0, 0) : std::nullopt;
      std::vector<unsigned char> start;
      if (bytes && bytes->file_size > 0) {
        bytes->length = bytes->file_size;
        start.resize(size_t(std::min<uint64_t>(12, bytes->length)));
        std::ifstream head(*file, std::ios::binary);
        if (!head.read(reinterpret_cast<char*>(start.data()), std::streamsize(start.size())))
          start.clear();
      }
      if (start.empty()) {
        keep_uri(" could not be read");
        continue;
      }
      std::string mime = sniff_mime_type(start);
      if (mime.empty() && image.contains("mimeType") && image["mimeType"].is_string())
        mime = image["mimeType"].get<std::string>();
      if (mime.empty()) {
        keep_uri(" has an unknown format");
        continue;
      }
      plan.images.push_back({i, *bytes, mime});
    }
  }
  return plan;
}

namespace {

/// Writes all of `data` to `fd`, or throws IOError naming `out`.
void write_all(int fd, const void* data, size_t size, const fs::path& out) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw IOError("cannot write " + out.string() + ": " + std::strerror(errno));
    p += n;
    size -= size_t(n);
  }
}

/// Appends `src`'s bytes to `fd`: copy_file_range (in the kernel), else
/// reads and writes.
void copy_bytes(const FileBytes& src, int fd, const fs::path& out) {
  // Without blocking: a file swapped for a FIFO since the plan is refused,
  // not waited on (scene/input_policy.h).
  const int in = ::open(src.file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (in < 0) throw IOError("cannot read " + src.file.string() + ": " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{in};
  struct stat st {};
  if (::fstat(in, &st) != 0 || !S_ISREG(st.st_mode))
    throw IOError("cannot read " + src.file.string() + ": not a regular file");
  loff_t at = loff_t(src.offset);
  uint64_t left = src.length;
  bool in_kernel = true;
  std::vector<char> buffer;
  while (left > 0) {
    ssize_t n;
    if (in_kernel) {
      n = ::copy_file_range(in, &at, fd, nullptr, size_t(std::min<uint64_t>(left, 1u << 30)), 0);
      if (n < 0 && (errno == EXDEV || errno == EINVAL || errno == ENOSYS || errno == EOPNOTSUPP)) {
        in_kernel = false;  // not between these files: read and write
        continue;
      }
    } else {
      buffer.resize(size_t(1) << 20);
      n = ::pread(in, buffer.data(), size_t(std::min<uint64_t>(left, buffer.size())), at);
      if (n > 0) {
        write_all(fd, buffer.data(), size_t(n), out);
        at += n;
      }
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw IOError("cannot write " + out.string() + ": " + std::strerror(errno));
    if (n == 0) {
      throw IOError("cannot write " + out.string() + ": " + src.file.string() +
                    " became shorter while snowmodel ran");
    }
    left -= uint64_t(n);
  }
}

uint64_t aligned(uint64_t v) { return (v + 3) & ~uint64_t(3); }

/// Adds the snow model's JSON (`snow`, from glb_json, its buffer's bytes at
/// `offset` in buffer 0) to `g`: its buffer views, accessors, materials,
/// meshes and nodes after g's, their indices shifted, and its root nodes in
/// g's default scene (made if there is none), as append_meshes adds them.
void merge_snow(json& g, const json& snow, uint64_t offset) {
  const auto count = [&](const char* key) { return g.contains(key) ? g[key].size() : size_t(0); };
  const size_t views = count("bufferViews"), accessors = count("accessors"),
               materials = count("materials"), meshes = count("meshes"), nodes = count("nodes");
  const auto append = [&](const char* key, auto&& shift) {
    if (!snow.contains(key) || snow[key].empty()) return;
    json& into = g[key];
    if (!into.is_array()) into = json::array();
    for (json item : snow[key]) {
      shift(item);
      into.push_back(std::move(item));
    }
  };
  const auto add = [](json& v, size_t by) { v = v.get<uint64_t>() + by; };
  append("bufferViews", [&](json& v) {
    v["buffer"] = 0;
    v["byteOffset"] = v.value("byteOffset", uint64_t(0)) + offset;
  });
  append("accessors", [&](json& a) {
    if (a.contains("bufferView")) add(a["bufferView"], views);
  });
  append("materials", [](json&) {});
  append("meshes", [&](json& m) {
    for (json& p : m["primitives"]) {
      for (auto& [name, accessor] : p["attributes"].items()) add(accessor, accessors);
      if (p.contains("indices")) add(p["indices"], accessors);
      if (p.contains("material")) add(p["material"], materials);
    }
  });
  append("nodes", [&](json& n) {
    if (n.contains("mesh")) add(n["mesh"], meshes);
    if (n.contains("children")) {
      for (json& c : n["children"]) add(c, nodes);
    }
  });
  if (!g.contains("scenes") || g["scenes"].empty()) g["scenes"] = json::array({json::object()});
  uint64_t scene = g.contains("scene") ? g["scene"].get<uint64_t>() : 0;
  if (scene >= g["scenes"].size()) scene = 0;
  g["scene"] = scene;
  json& roots = g["scenes"][scene]["nodes"];
  if (!roots.is_array()) roots = json::array();
  for (const json& r : snow["scenes"][0]["nodes"]) roots.push_back(r.get<uint64_t>() + nodes);
  if (!g["asset"].contains("generator")) g["asset"]["generator"] = "snowmodel";
}

}  // namespace

void write_streamed_glb(StreamPlan& plan, const std::vector<TriMesh>& snow, const fs::path& out) {
  // The input is read at the start of a run and copied at its end: a file
  // changed in between would no longer match the JSON read then.
  const auto check_unchanged = [&](const FileBytes& source) {
    const std::optional<FileBytes> now = file_bytes(source.file, source.offset, source.length);
    if (!now || now->file_size != source.file_size || now->modified != source.modified) {
      throw IOError("cannot write " + out.string() + ": " + source.file.string() +
                    " changed while snowmodel ran; run it again");
    }
  };
  if (plan.buffer) check_unchanged(*plan.buffer);
  for (const StreamPlan::EmbeddedImage& e : plan.images) check_unchanged(e.bytes);
  for (const std::string& warning : plan.kept_by_uri) log_warn(warning);
  json& g = plan.gltf;
  // The BIN chunk: the buffer's bytes, the images', then the snow's, each
  // from a 4-byte boundary.
  uint64_t size = plan.buffer ? plan.buffer->length : 0;
  for (const StreamPlan::EmbeddedImage& e : plan.images) {
    size = aligned(size);
    json& image = g["images"][e.index];
    json view = {{"buffer", 0}, {"byteOffset", size}, {"byteLength", e.bytes.length}};
    view["name"] = image.contains("name") && image["name"].is_string() &&
                           !image["name"].get<std::string>().empty()
                       ? image["name"]
                       : json("image" + std::to_string(e.index));
    if (!g["bufferViews"].is_array()) g["bufferViews"] = json::array();
    g["bufferViews"].push_back(std::move(view));
    image["bufferView"] = g["bufferViews"].size() - 1;
    image["mimeType"] = e.mime;
    image.erase("uri");
    size += e.bytes.length;
  }
  tinygltf::Model model;
  append_meshes(model, snow, {snow_material()}, "Snow");
  std::vector<unsigned char> snow_bytes;
  if (!model.buffers.empty()) snow_bytes.swap(model.buffers[0].data);
  const uint64_t snow_offset = snow_bytes.empty() ? size : aligned(size);
  merge_snow(g, json::parse(glb_json(model, out)), snow_offset);
  size = snow_offset + snow_bytes.size();
  if (size > 0) {
    if (!g.contains("buffers") || g["buffers"].empty())
      g["buffers"] = json::array({json::object()});
    g["buffers"][0].erase("uri");
    g["buffers"][0]["byteLength"] = size;
  }
  std::string text = g.dump(-1, ' ', false, json::error_handler_t::replace);
  text.resize(aligned(text.size()), ' ');
  const bool has_bin = g.contains("buffers") && !g["buffers"].empty();
  const uint64_t total = 12 + 8 + text.size() + (has_bin ? 8 + aligned(size) : 0);
  if (total > UINT32_MAX) {
    throw IOError("cannot write " + out.string() +
                  ": a GLB holds at most 4 GiB; write .gltf (its buffers go to .bin files)");
  }
  write_file_atomically(out, [&](const fs::path& tmp) {
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) throw IOError("cannot write " + out.string() + ": " + std::strerror(errno));
    struct Closer {
      int fd;
      ~Closer() {
        if (fd >= 0) ::close(fd);
      }
    } closer{fd};
    const auto put_u32 = [&](uint32_t v) {
      const unsigned char b[4] = {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)};
      write_all(fd, b, 4, out);
    };
    const char zeros[4] = {0, 0, 0, 0};
    uint64_t at = 0;  // bytes of the BIN chunk written
    const auto pad_to = [&](uint64_t to) {
      write_all(fd, zeros, size_t(to - at), out);
      at = to;
    };
    write_all(fd, "glTF", 4, out);
    put_u32(2);
    put_u32(uint32_t(total));
    put_u32(uint32_t(text.size()));
    put_u32(kChunkJson);
    write_all(fd, text.data(), text.size(), out);
    if (has_bin) {
      put_u32(uint32_t(aligned(size)));
      put_u32(kChunkBin);
      if (plan.buffer) {
        copy_bytes(*plan.buffer, fd, out);
        at = plan.buffer->length;
      }
      for (const StreamPlan::EmbeddedImage& e : plan.images) {
        pad_to(aligned(at));
        copy_bytes(e.bytes, fd, out);
        at += e.bytes.length;
      }
      if (!snow_bytes.empty()) {
        pad_to(snow_offset);
        write_all(fd, snow_bytes.data(), snow_bytes.size(), out);
        at += snow_bytes.size();
      }
      pad_to(aligned(at));
    }
    closer.fd = -1;
    if (::close(fd) != 0)
      throw IOError("cannot write " + out.string() + ": " + std::strerror(errno));
  });
}

}  // namespace snow

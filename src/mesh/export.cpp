// Snow mesh export (DESIGN.md, "Outputs"). glTF files follow the Khronos
// glTF 2.0 specification (images in buffer views: section 3.8.2 "Images");
// OBJ and PLY are written by obj_writer.cpp and ply_writer.cpp.
#include "mesh/export.h"

#include <fcntl.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <system_error>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"
#include "mesh/gltf_writer.h"
#include "mesh/obj_writer.h"
#include "mesh/ply_writer.h"
#include "scene/load_gltf.h"

namespace snow {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

std::vector<TriMesh> patch_meshes(const std::vector<SnowPatch>& patches) {
  std::vector<TriMesh> meshes;
  meshes.reserve(patches.size());
  for (const SnowPatch& p : patches) {
    if (p.mesh.indices.size() < 3) continue;
    meshes.push_back(p.mesh);
    meshes.back().material = 0;
  }
  return meshes;
}

/// tinygltf image callback that keeps the encoded bytes (in Image::image) of
/// images stored in files or data URIs instead of decoding them, so they can
/// be written back unchanged. Images in buffer views stay where they are.
bool keep_image_bytes(tinygltf::Image* image, const int /*index*/, std::string* /*err*/,
                      std::string* /*warn*/, int /*req_width*/, int /*req_height*/,
                      const unsigned char* bytes, int size, void* /*user_data*/) {
  image->image.clear();
  if (image->bufferView < 0 && bytes != nullptr && size > 0) {
    image->image.assign(bytes, bytes + size);
  }
  image->as_is = true;
  return true;
}

/// MIME type of encoded image bytes, from their signature; empty if unknown.
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

/// Moves every image held as bytes (from a file or a data URI) into buffer 0
/// as a new buffer view, with room for `then` more bytes after them.
void embed_images(tinygltf::Model& model, const fs::path& input, size_t then) {
  // What the images still to embed take (each padded to 4 bytes), and what
  // comes after them: buffer 0 grows once, not per image.
  size_t to_embed = then;
  for (const tinygltf::Image& image : model.images) {
    if (image.bufferView < 0) to_embed += image.image.size() + 3;
  }
  for (size_t i = 0; i < model.images.size(); ++i) {
    tinygltf::Image& image = model.images[i];
    if (image.bufferView >= 0) {
      image.image.clear();
      continue;
    }
    to_embed -= image.image.size() + 3;
    if (image.image.empty()) {
      log_warn(input.string() + ": image " + std::to_string(i) + " ('" + image.uri +
               "') could not be read; the output refers to it by its URI as it is");
      continue;
    }
    std::string mime = sniff_mime_type(image.image);
    if (mime.empty()) mime = image.mimeType;
    if (mime.empty()) {
      log_warn(input.string() + ": image " + std::to_string(i) + " ('" + image.uri +
               "') has an unknown format; the output refers to it by its URI as it is");
      image.image.clear();
      continue;
    }
    if (model.buffers.empty()) model.buffers.emplace_back();
    std::vector<unsigned char>& bytes = model.buffers[0].data;
    bytes.reserve(bytes.size() + image.image.size() + 3 + to_embed);
    bytes.resize((bytes.size() + 3) & ~size_t(3), 0);
    tinygltf::BufferView view;
    view.name = image.name.empty() ? "image" + std::to_string(i) : image.name;
    view.buffer = 0;
    view.byteOffset = bytes.size();
    view.byteLength = image.image.size();
    bytes.insert(bytes.end(), image.image.begin(), image.image.end());
    model.bufferViews.push_back(view);
    image.bufferView = int(model.bufferViews.size()) - 1;
    image.mimeType = mime;
    image.uri.clear();
    image.image.clear();
    image.as_is = false;
  }
}

/// Fails early, before any file (a .bin, a .mtl beside the target) is
/// written, when `path` cannot be the output.
void check_output_path(const fs::path& path) {
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw IOError("cannot write " + path.string() + ": folder " + folder.string() +
                  " does not exist");
  }
  if (fs::is_directory(path, ec))
    throw IOError("cannot write " + path.string() + ": it is a folder");
}

/// First line of a tinygltf message.
std::string first_line(const std::string& text) {
  const size_t end = text.find('\n');
  return end == std::string::npos ? text : text.substr(0, end);
}

}  // namespace

MeshFormat format_from_path(const fs::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".glb") return MeshFormat::Glb;
  if (ext == ".gltf") return MeshFormat::Gltf;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".ply") return MeshFormat::Ply;
  throw InputError(path.string() + ": unknown mesh format '" + path.extension().string() +
                   "' (use .glb, .gltf, .obj or .ply)");
}

const char* format_name(MeshFormat format) {
  switch (format) {
    case MeshFormat::Glb:
      return "glb";
    case MeshFormat::Gltf:
      return "gltf";
    case MeshFormat::Obj:
      return "obj";
    case MeshFormat::Ply:
      return "ply";
  }
  return "?";
}

MeshMaterial snow_material() {
  MeshMaterial m;
  m.name = "snow";
  m.base_color = glm::vec4(0.9f, 0.9f, 0.9f, 1.0f);
  m.roughness = 0.8f;
  m.metallic = 0.0f;
  return m;
}

void write_snow_meshes(const std::vector<SnowPatch>& patches, const fs::path& path,
                       MeshFormat format) {
  check_output_path(path);
  const std::vector<TriMesh> meshes = patch_meshes(patches);
  switch (format) {
    case MeshFormat::Glb:
    case MeshFormat::Gltf: {
      if (lower_extension(path) != (format == MeshFormat::Glb ? ".glb" : ".gltf")) {
        throw InputError(path.string() + ": a " + format_name(format) +
                         " file needs the extension ." + format_name(format));
      }
      tinygltf::Model model;
      append_meshes(model, meshes, {snow_material()}, "Snow");
      save_gltf(std::move(model), path);
      break;
    }
    case MeshFormat::Obj:
      write_obj(meshes, snow_material(), path);
      break;
    case MeshFormat::Ply:
      write_ply(meshes, path);
      break;
  }
}

namespace {

using nlohmann::json;

/// Bytes of a file that the streamed GLB copies.
struct FileBytes {
  fs::path file;
  uint64_t offset = 0, length = 0;
};

/// The combined GLB of an input whose data lie in one buffer and in image
/// files, written without reading them into memory: the input's JSON,
/// changed, then the buffer's and the images' bytes copied from their files
/// by the kernel (copy_file_range), then the snow. tinygltf's path reads the
/// buffer, copies it into its model and again to embed the images (ToyCar's
/// 5.8 MB: 1,500 fresh pages, 6 of a 42 ms run); this copies nothing.
struct StreamPlan {
  json gltf;
  std::optional<FileBytes> buffer;  // buffer 0's bytes
  struct EmbeddedImage {
    size_t index;
    FileBytes bytes;
    std::string mime;
  };
  std::vector<EmbeddedImage> images;     // images in files, to embed
  std::vector<std::string> kept_by_uri;  // warnings: images left at their uri
};

constexpr uint32_t kGlbMagic = 0x46546C67u;  // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534Au;
constexpr uint32_t kChunkBin = 0x004E4942u;

uint32_t u32_at(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

bool is_index(const json& v) { return v.is_number_unsigned(); }
bool is_array_or_absent(const json& j, const char* key) {
  return !j.contains(key) || j[key].is_array();
}

/// The plan for `input`, or nullopt where the input is not of that common
/// form (several buffers, data URIs, a GLB or JSON that is not as expected):
/// tinygltf's path then writes it, and reports what is wrong with it.
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
      bin = FileBytes{input, next + 8, bin_length};
    }
  } else {
    text.resize(file_size);
    in.seekg(0);
    if (!in.read(text.data(), std::streamsize(file_size))) return std::nullopt;
  }
  StreamPlan plan;
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
        const std::optional<fs::path> file =
            resolve_relative_uri(folder, b["uri"].get<std::string>());
        if (!file || fs::file_size(*file, ec) < length || ec) return std::nullopt;
        plan.buffer = FileBytes{*file, 0, length};
      } else if (length > 0) {
        if (!bin || bin->length < length) return std::nullopt;
        plan.buffer = FileBytes{input, bin->offset, length};
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
      const std::optional<fs::path> file = resolve_relative_uri(folder, uri);
      if (!file) {
        if (uri.compare(0, 5, "data:") == 0) return std::nullopt;  // tinygltf's path decodes it
        plan.kept_by_uri.push_back(
            what + " could not be read; the output refers to it by its URI as it is");
        continue;
      }
      const uint64_t size = fs::file_size(*file, ec);
      std::ifstream head(*file, std::ios::binary);
      std::vector<unsigned char> start(12, 0);
      if (ec || size == 0 || !head ||
          !head.read(reinterpret_cast<char*>(start.data()),
                     std::streamsize(std::min<uint64_t>(12, size)))) {
        plan.kept_by_uri.push_back(
            what + " could not be read; the output refers to it by its URI as it is");
        continue;
      }
      start.resize(std::min<uint64_t>(12, size));
      std::string mime = sniff_mime_type(start);
      if (mime.empty() && image.contains("mimeType") && image["mimeType"].is_string())
        mime = image["mimeType"].get<std::string>();
      if (mime.empty()) {
        plan.kept_by_uri.push_back(
            what + " has an unknown format; the output refers to it by its URI as it is");
        continue;
      }
      plan.images.push_back({i, FileBytes{*file, 0, size}, mime});
    }
  }
  return plan;
}

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
  const int in = ::open(src.file.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) throw IOError("cannot read " + src.file.string() + ": " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{in};
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

void write_streamed_glb(StreamPlan& plan, const std::vector<TriMesh>& snow, const fs::path& out) {
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

}  // namespace

struct CombinedInput {
  fs::path path;
  std::optional<StreamPlan> plan;  // a GLB streamed from the input's files
  tinygltf::Model model;           // else the input as tinygltf reads it
  std::string warnings;            // tinygltf's, one per line
};

void CombinedInputDeleter::operator()(CombinedInput* input) const { delete input; }

namespace {

void check_combined_output(const fs::path& out) {
  const std::string out_ext = lower_extension(out);
  if (out_ext != ".glb" && out_ext != ".gltf") {
    throw InputError(out.string() + ": the scene plus snow is written as .glb or .gltf only");
  }
  check_output_path(out);
}

}  // namespace

namespace {

void read_with_tinygltf(CombinedInput& input) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keep_image_bytes, nullptr);
  std::string err;
  const bool binary = lower_extension(input.path) == ".glb";
  const bool ok =
      binary ? loader.LoadBinaryFromFile(&input.model, &err, &input.warnings, input.path.string())
             : loader.LoadASCIIFromFile(&input.model, &err, &input.warnings, input.path.string());
  if (!ok) {
    throw InputError(input.path.string() + ": " +
                     (err.empty() ? std::string("not a valid glTF file") : first_line(err)));
  }
}

}  // namespace

CombinedInputPtr read_combined_input(const fs::path& input_scene, const fs::path& out) {
  std::error_code ec;
  if (!fs::is_regular_file(input_scene, ec)) {
    throw IOError("cannot read " + input_scene.string() + ": no such file");
  }
  CombinedInputPtr input(new CombinedInput);
  input->path = input_scene;
  if (lower_extension(out) == ".glb") input->plan = plan_streamed_glb(input_scene);
  if (!input->plan) read_with_tinygltf(*input);
  return input;
}

namespace {

// write_combined_gltf once `out` is checked.
void write_checked_combined(CombinedInput& input, const std::vector<SnowPatch>& patches,
                            const fs::path& out) {
  if (input.plan && lower_extension(out) == ".glb") {
    write_streamed_glb(*input.plan, patch_meshes(patches), out);
    return;
  }
  if (input.plan) {  // read for a GLB, written as .gltf
    input.plan.reset();
    read_with_tinygltf(input);
  }
  std::istringstream lines(input.warnings);
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty()) log_warn(input.path.string() + ": " + line);
  }
  const std::vector<TriMesh> snow = patch_meshes(patches);
  embed_images(input.model, input.path, mesh_buffer_bytes(snow));
  append_meshes(input.model, snow, {snow_material()}, "Snow");
  save_gltf(std::move(input.model), out);
}

}  // namespace

void write_combined_gltf(CombinedInputPtr input, const std::vector<SnowPatch>& patches,
                         const fs::path& out) {
  check_combined_output(out);
  write_checked_combined(*input, patches, out);
}

void write_combined_gltf(const fs::path& input_scene, const std::vector<SnowPatch>& patches,
                         const fs::path& out) {
  check_combined_output(out);  // before reading the input
  write_checked_combined(*read_combined_input(input_scene, out), patches, out);
}

}  // namespace snow

// The combined writer (mesh/glb_stream.h): the input's JSON as the loader
// parsed it, its buffers merged into one, plus snow. GLB layout: Khronos
// glTF 2.0 specification, section 4; buffers, bufferViews: section 3.6;
// EXT_meshopt_compression's bufferView extension (buffer, byteOffset).
#include "mesh/glb_stream.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>

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

constexpr uint32_t kChunkJson = 0x4E4F534Au;
constexpr uint32_t kChunkBin = 0x004E4942u;

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

/// A whole number >= 0 (an integral float up to 2^53 too, as the loader
/// reads one); nullopt for anything else.
std::optional<uint64_t> whole_number(const json& v) {
  if (v.is_number_unsigned()) return v.get<uint64_t>();
  if (v.is_number_integer()) {
    if (v.get<int64_t>() < 0) return std::nullopt;
    return v.get<uint64_t>();
  }
  if (v.is_number_float()) {
    const double d = v.get<double>();
    if (d >= 0 && d <= 9007199254740992.0 && d == double(uint64_t(d))) return uint64_t(d);
  }
  return std::nullopt;
}

uint64_t aligned(uint64_t v) { return (v + 3) & ~uint64_t(3); }
uint64_t aligned8(uint64_t v) { return (v + 7) & ~uint64_t(7); }

/// Plans the input's buffers (CombinedInput::buffers) and points its
/// bufferViews (and EXT_/KHR_meshopt_compression's) into the one output
/// buffer. `fail` throws.
template <class Fail>
void plan_buffers(const SourceGltf& source, const fs::path& folder, CombinedInput& plan,
                  const Fail& fail) {
  json& g = plan.gltf;
  if (!is_array_or_absent(g, "buffers")) fail("'buffers' must be an array");
  if (!is_array_or_absent(g, "bufferViews")) fail("'bufferViews' must be an array");
  const json no_buffers = json::array();
  const json& buffers = g.contains("buffers") ? g["buffers"] : no_buffers;
  uint64_t end = 0;
  for (size_t i = 0; i < buffers.size(); ++i) {
    const std::string what = "buffer " + std::to_string(i);
    const json& b = buffers[i];
    if (!b.is_object()) fail(what + " must be a JSON object");
    const std::optional<uint64_t> length =
        b.contains("byteLength") ? whole_number(b["byteLength"]) : std::nullopt;
    if (!length) fail(what + " has no whole 'byteLength'");
    CombinedInput::Piece piece;
    piece.offset = i == 0 ? 0 : aligned8(end);
    if (!b.contains("uri")) {
      if (*length > 0 && (i != 0 || !source.has_bin)) fail(what + " has no 'uri'");
      if (*length > source.bin_length)
        fail(what + ": the GLB's BIN chunk holds " + std::to_string(source.bin_length) +
             " bytes, but byteLength is " + std::to_string(*length));
      if (*length > 0)
        piece.bytes.file =
            FileBytes{source.path, source.bin_offset, *length, source.file_size, source.modified};
    } else {
      if (!b["uri"].is_string()) fail(what + " 'uri' must be a string");
      const std::string& uri = b["uri"].get_ref<const std::string&>();
      if (starts_with_data(uri)) {
        std::string why;
        std::optional<std::vector<uint8_t>> bytes = decode_data_uri(uri, nullptr, &why);
        if (!bytes) fail(what + ": " + why);
        if (bytes->size() < *length)
          fail(what + " (data uri) holds " + std::to_string(bytes->size()) +
               " bytes, but byteLength is " + std::to_string(*length));
        bytes->resize(size_t(*length));
        piece.bytes.bytes = std::move(*bytes);
      } else {
        const std::string named = what + " ('" + one_line(uri) + "')";
        std::string why;
        const std::optional<fs::path> file = resolve_relative_uri(folder, uri, &why);
        if (!file) fail(what + ": uri '" + one_line(uri) + "' " + why);
        const std::string problem = regular_file_problem(*file);
        if (!problem.empty()) fail(named + " " + problem);
        piece.bytes.file = file_bytes(*file, 0, *length);
        if (!piece.bytes.file) fail(named + " cannot be read");
        if (piece.bytes.file->file_size < *length)
          fail(named + " holds " + std::to_string(piece.bytes.file->file_size) +
               " bytes, but byteLength is " + std::to_string(*length));
      }
    }
    end = piece.offset + *length;
    plan.buffers.push_back(std::move(piece));
  }
  plan.buffers_end = end;
  // A view's buffer index and byteOffset, into the output buffer.
  const auto repoint = [&](json& object, const std::string& what) {
    const std::optional<uint64_t> index =
        object.contains("buffer") ? whole_number(object["buffer"]) : std::nullopt;
    if (!index || *index >= plan.buffers.size())
      fail(what + ": 'buffer' is not the index of a buffer");
    const uint64_t shift = plan.buffers[size_t(*index)].offset;
    if (*index != 0) object["buffer"] = 0;
    if (shift == 0) return;
    const std::optional<uint64_t> offset =
        object.contains("byteOffset") ? whole_number(object["byteOffset"]) : uint64_t(0);
    if (!offset) fail(what + ": 'byteOffset' is not a whole number");
    object["byteOffset"] = *offset + shift;
  };
  if (g.contains("bufferViews")) {
    json& views = g["bufferViews"];
    for (size_t i = 0; i < views.size(); ++i) {
      const std::string what = "bufferView " + std::to_string(i);
      json& view = views[i];
      if (!view.is_object()) fail(what + " must be a JSON object");
      repoint(view, what);
      if (!view.contains("extensions") || !view["extensions"].is_object()) continue;
      for (const char* name : {"EXT_meshopt_compression", "KHR_meshopt_compression"}) {
        json& extensions = view["extensions"];
        if (extensions.contains(name) && extensions[name].is_object())
          repoint(extensions[name], what + " " + name);
      }
    }
  }
  // One buffer: the first, its uri and byteLength set by the write.
  if (!buffers.empty()) {
    json first = buffers[0];
    first.erase("uri");
    g["buffers"] = json::array({std::move(first)});
  }
}

/// Plans the images in files or data URIs to embed (CombinedInput::images).
template <class Fail>
void plan_images(const fs::path& folder, CombinedInput& plan, const Fail& fail) {
  json& g = plan.gltf;
  if (!is_array_or_absent(g, "images")) fail("'images' must be an array");
  if (!g.contains("images")) return;
  const json& images = g["images"];
  for (size_t i = 0; i < images.size(); ++i) {
    const json& image = images[i];
    if (!image.is_object()) fail("image " + std::to_string(i) + " must be a JSON object");
    if (!image.contains("uri")) continue;  // in a buffer view: kept as it is
    if (!image["uri"].is_string()) fail("image " + std::to_string(i) + " 'uri' must be a string");
    const std::string& uri = image["uri"].get_ref<const std::string&>();
    const bool data = starts_with_data(uri);
    const std::string what = plan.path.string() + ": image " + std::to_string(i) + " ('" +
                             (data ? std::string("data uri") : uri) + "')";
    const auto keep_uri = [&](const char* reason) {
      plan.kept_by_uri.push_back(one_line(what) + reason +
                                 "; the output refers to it by its URI as it is");
    };
    InputBytes bytes;
    std::vector<unsigned char> start;  // its first bytes, for its format
    std::string data_mime;
    if (data) {
      std::optional<std::vector<uint8_t>> decoded = decode_data_uri(uri, &data_mime, nullptr);
      if (decoded) bytes.bytes = std::move(*decoded);
      start.assign(bytes.bytes.begin(),
                   bytes.bytes.begin() + long(std::min<size_t>(12, bytes.bytes.size())));
    } else {
      std::string why;
      const std::optional<fs::path> file = resolve_relative_uri(folder, uri, &why);
      if (!file) fail("image " + std::to_string(i) + " ('" + one_line(uri) + "'): uri " + why);
      if (regular_file_problem(*file).empty()) bytes.file = file_bytes(*file, 0, 0);
      if (bytes.file && bytes.file->file_size > 0) {
        bytes.file->length = bytes.file->file_size;
        start.resize(size_t(std::min<uint64_t>(12, bytes.file->length)));
        if (!read_regular_file(*file, start.size(), start.data(), nullptr)) start.clear();
      }
    }
    if (start.empty()) {
      keep_uri(data ? " could not be decoded" : " could not be read");
      continue;
    }
    std::string mime = sniff_mime_type(start);
    if (mime.empty() && image.contains("mimeType") && image["mimeType"].is_string())
      mime = image["mimeType"].get<std::string>();
    if (mime.empty() && data_mime.rfind("image/", 0) == 0) mime = data_mime;
    if (mime.empty()) {
      keep_uri(" has an unknown format");
      continue;
    }
    plan.images.push_back({i, std::move(bytes), mime});
  }
}

}  // namespace

CombinedInput plan_combined(const SourceGltf& source) {
  CombinedInput plan;
  plan.path = source.path;
  plan.gltf = source.json;
  const auto fail = [&](const std::string& what) {
    throw InputError(source.path.string() + ": " + what);
  };
  if (!plan.gltf.is_object()) fail("broken JSON: the top level is not an object");
  if (!plan.gltf.contains("asset") || !plan.gltf["asset"].is_object())
    plan.gltf["asset"] = {{"version", "2.0"}};
  for (const char* key : {"accessors", "materials", "meshes", "nodes", "scenes"}) {
    if (!is_array_or_absent(plan.gltf, key)) fail(std::string("'") + key + "' must be an array");
  }
  if (plan.gltf.contains("scene") && !is_index(plan.gltf["scene"]))
    fail("'scene' must be an index");
  if (plan.gltf.contains("scenes")) {
    for (const json& scene : plan.gltf["scenes"]) {
      if (!scene.is_object() || !is_array_or_absent(scene, "nodes"))
        fail("a scene must be an object whose 'nodes' is an array");
    }
  }
  const fs::path folder =
      source.path.parent_path().empty() ? fs::path(".") : source.path.parent_path();
  plan_buffers(source, folder, plan, fail);
  plan_images(folder, plan, fail);
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

/// Writes the output buffer's bytes to `fd` (`out` names it in errors):
/// the input's buffers at their offsets, the images at theirs, the snow's
/// bytes at `snow_offset`; zeros between them and up to `size`.
void write_buffer(int fd, const CombinedInput& plan, const std::vector<uint64_t>& image_offsets,
                  const std::vector<unsigned char>& snow_bytes, uint64_t snow_offset, uint64_t size,
                  const fs::path& out) {
  static const char zeros[8] = {};
  uint64_t at = 0;  // bytes written
  const auto pad_to = [&](uint64_t to) {
    write_all(fd, zeros, size_t(to - at), out);
    at = to;
  };
  const auto put = [&](const InputBytes& bytes) {
    if (bytes.file)
      copy_bytes(*bytes.file, fd, out);
    else
      write_all(fd, bytes.bytes.data(), bytes.bytes.size(), out);
    at += bytes.length();
  };
  for (const CombinedInput::Piece& piece : plan.buffers) {
    pad_to(piece.offset);
    put(piece.bytes);
  }
  for (size_t k = 0; k < plan.images.size(); ++k) {
    pad_to(image_offsets[k]);
    put(plan.images[k].bytes);
  }
  if (!snow_bytes.empty()) {
    pad_to(snow_offset);
    write_all(fd, snow_bytes.data(), snow_bytes.size(), out);
    at += snow_bytes.size();
  }
  pad_to(size);
}

/// Opens `tmp` for writing, calls write(fd) and closes it; IOError naming
/// `out` on failure.
template <class Write>
void write_fd(const fs::path& tmp, const fs::path& out, const Write& write) {
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) throw IOError("cannot write " + out.string() + ": " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() {
      if (fd >= 0) ::close(fd);
    }
  } closer{fd};
  write(fd);
  closer.fd = -1;
  if (::close(fd) != 0) throw IOError("cannot write " + out.string() + ": " + std::strerror(errno));
}

}  // namespace

void write_combined(CombinedInput& plan, const std::vector<TriMesh>& snow, const fs::path& out) {
  // The input is read at the start of a run and copied at its end: a file
  // changed in between would no longer match the JSON read then.
  const auto check_unchanged = [&](const InputBytes& bytes) {
    if (!bytes.file) return;
    const FileBytes& source = *bytes.file;
    const std::optional<FileBytes> now = file_bytes(source.file, source.offset, source.length);
    if (!now || now->file_size != source.file_size || now->modified != source.modified) {
      throw IOError("cannot write " + out.string() + ": " + source.file.string() +
                    " changed while snowmodel ran; run it again");
    }
  };
  for (const CombinedInput::Piece& piece : plan.buffers) check_unchanged(piece.bytes);
  for (const CombinedInput::EmbeddedImage& e : plan.images) check_unchanged(e.bytes);
  for (const std::string& warning : plan.kept_by_uri) log_warn(warning);
  json& g = plan.gltf;
  // The output buffer: the input's buffers, the images', then the snow's,
  // each image and the snow from a 4-byte boundary.
  uint64_t size = plan.buffers_end;
  std::vector<uint64_t> image_offsets;
  for (const CombinedInput::EmbeddedImage& e : plan.images) {
    size = aligned(size);
    image_offsets.push_back(size);
    json& image = g["images"][e.index];
    json view = {{"buffer", 0}, {"byteOffset", size}, {"byteLength", e.bytes.length()}};
    view["name"] = image.contains("name") && image["name"].is_string() &&
                           !image["name"].get<std::string>().empty()
                       ? image["name"]
                       : json("image" + std::to_string(e.index));
    if (!g["bufferViews"].is_array()) g["bufferViews"] = json::array();
    g["bufferViews"].push_back(std::move(view));
    image["bufferView"] = g["bufferViews"].size() - 1;
    image["mimeType"] = e.mime;
    image.erase("uri");
    size += e.bytes.length();
  }
  tinygltf::Model model;
  append_meshes(model, snow, {snow_material()}, "Snow");
  std::vector<unsigned char> snow_bytes;
  if (!model.buffers.empty()) snow_bytes.swap(model.buffers[0].data);
  const uint64_t snow_offset = snow_bytes.empty() ? size : aligned(size);
  merge_snow(g, json::parse(glb_json(model, out)), snow_offset);
  size = snow_offset + snow_bytes.size();
  if (size > 0 && (!g.contains("buffers") || g["buffers"].empty()))
    g["buffers"] = json::array({json::object()});
  const bool has_buffer = g.contains("buffers") && !g["buffers"].empty();
  if (has_buffer) g["buffers"][0]["byteLength"] = size;
  const auto write_bytes = [&](int fd, uint64_t until) {
    write_buffer(fd, plan, image_offsets, snow_bytes, snow_offset, until, out);
  };

  if (lower_extension(out) == ".gltf") {
    // The buffer in "<stem>.bin" beside it, written first: the .gltf names it.
    const std::string bin_name = out.stem().string() + ".bin";
    if (has_buffer) {
      g["buffers"][0]["uri"] = bin_name;
      const fs::path bin = out.parent_path() / bin_name;
      write_file_atomically(bin, [&](const fs::path& tmp) {
        write_fd(tmp, bin, [&](int fd) { write_bytes(fd, size); });
      });
    }
    write_text_atomically(out, g.dump(2, ' ', false, json::error_handler_t::replace) + "\n");
    return;
  }
  std::string text = g.dump(-1, ' ', false, json::error_handler_t::replace);
  text.resize(aligned(text.size()), ' ');
  const uint64_t total = 12 + 8 + text.size() + (has_buffer ? 8 + aligned(size) : 0);
  if (total > UINT32_MAX) {
    throw IOError("cannot write " + out.string() +
                  ": a GLB holds at most 4 GiB; write .gltf (its buffers go to .bin files)");
  }
  write_file_atomically(out, [&](const fs::path& tmp) {
    write_fd(tmp, out, [&](int fd) {
      const auto put_u32 = [&](uint32_t v) {
        const unsigned char b[4] = {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16),
                                    uint8_t(v >> 24)};
        write_all(fd, b, 4, out);
      };
      write_all(fd, "glTF", 4, out);
      put_u32(2);
      put_u32(uint32_t(total));
      put_u32(uint32_t(text.size()));
      put_u32(kChunkJson);
      write_all(fd, text.data(), text.size(), out);
      if (has_buffer) {
        put_u32(uint32_t(aligned(size)));
        put_u32(kChunkBin);
        write_bytes(fd, aligned(size));
      }
    });
  });
}

}  // namespace snow

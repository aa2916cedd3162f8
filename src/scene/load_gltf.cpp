// glTF 2.0 loader following the Khronos glTF 2.0 specification: GLB container
// (section 4.4), buffers/bufferViews/accessors with byteStride and sparse
// storage (3.6), meshes and primitive topologies (3.7.2), the node hierarchy
// (3.5), materials (3.9.2) and textures (3.8); extensions
// KHR_mesh_quantization, KHR_texture_transform, KHR_draco_mesh_compression
// and EXT_mesh_gpu_instancing; with LoadSettings::lines line primitives, and
// with LoadSettings::motions animations (3.11).
//
// This file holds the entry points and the order of the steps
// (GltfLoader::load); the steps are in scene/gltf/ (see
// scene/gltf/internal.h). The JSON is parsed with nlohmann::json and every
// value is validated there: the file is untrusted.
#include "scene/load_gltf.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>
#include <system_error>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"
#include "scene/gltf/internal.h"
#include "scene/input_policy.h"

namespace snow {
namespace gltf {

GltfLoader::GltfLoader(const std::filesystem::path& path, const LoadSettings& settings)
    : path_(path), settings_(settings), label_(path.string()) {
  folder_ = path.parent_path();
  if (folder_.empty()) folder_ = ".";
}

Scene GltfLoader::load() {
  read_document();
  check_uris();
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
  if (settings_.motions) read_motions();
  if (settings_.load_images) load_images();
  if (settings_.keep_source) {
    // The JSON is moved, not copied: the loader is done with it.
    auto source = std::make_shared<SourceGltf>();
    source->path = path_;
    source->json = std::move(doc_);
    source->has_bin = has_glb_bin_;
    source->bin_offset = has_glb_bin_ ? uint64_t(glb_bin_ - file_.data()) : 0;
    source->bin_length = glb_bin_size_;
    source->file_size = file_.size();
    source->modified = file_modified_;
    scene_.source = std::move(source);
  }
  return std::move(scene_);
}

}  // namespace gltf

uint64_t gltf_input_bytes(const std::filesystem::path& path) {
  const auto extension_is = [](const std::filesystem::path& p, const char* ext) {
    return lower_extension(p) == ext;
  };
  if (!regular_file_problem(path).empty()) return 0;
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

namespace {

/// The JSON text of the glTF at `path` (a .glb's JSON chunk, by its magic),
/// at most `limit` bytes; empty where it cannot be read.
std::string gltf_json_text(const std::filesystem::path& path, uint64_t limit) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) return {};
  std::string text;
  unsigned char header[20] = {};
  const size_t got = std::fread(header, 1, sizeof header, file);
  const auto u32 = [&](size_t at) {
    return uint32_t(header[at]) | uint32_t(header[at + 1]) << 8 | uint32_t(header[at + 2]) << 16 |
           uint32_t(header[at + 3]) << 24;
  };
  uint64_t size = limit;
  if (got >= 4 && std::memcmp(header, "glTF", 4) == 0) {
    // GLB (glTF 2.0, 4.4): a 12-byte header, then the JSON chunk's length
    // and type.
    if (got == sizeof header && u32(16) == 0x4E4F534Au)
      size = std::min<uint64_t>(u32(12), limit);
    else
      size = 0;
  } else if (std::fseek(file, 0, SEEK_SET) != 0) {
    size = 0;
  }
  std::vector<char> buffer(1 << 16);
  while (text.size() < size) {
    const size_t want = size_t(std::min<uint64_t>(buffer.size(), size - text.size()));
    const size_t n = std::fread(buffer.data(), 1, want, file);
    if (n == 0) break;
    text.append(buffer.data(), n);
  }
  std::fclose(file);
  return text;
}

}  // namespace

std::vector<std::filesystem::path> gltf_input_files(const std::filesystem::path& path) {
  std::vector<std::filesystem::path> files = {path};
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return files;  // a FIFO would block
  try {
    const std::string text = gltf_json_text(path, LoadLimits{}.max_json_bytes);
    // Only the top three levels are kept (root, buffers/images, their
    // members): deep nesting elsewhere costs no memory.
    const nlohmann::json root = nlohmann::json::parse(
        text, [](int depth, nlohmann::json::parse_event_t, nlohmann::json&) { return depth <= 3; },
        false);
    if (!root.is_object()) return files;
    std::filesystem::path folder = path.parent_path();
    if (folder.empty()) folder = ".";
    for (const char* kind : {"buffers", "images"}) {
      const auto list = root.find(kind);
      if (list == root.end() || !list->is_array()) continue;
      for (const nlohmann::json& item : *list) {
        if (!item.is_object()) continue;
        const auto uri = item.find("uri");
        if (uri == item.end() || !uri->is_string()) continue;
        const std::string& text_uri = uri->get_ref<const std::string&>();
        if (text_uri.empty() || text_uri.rfind("data:", 0) == 0) continue;
        const std::optional<std::filesystem::path> file = resolve_relative_uri(folder, text_uri);
        files.push_back(file ? *file : folder / text_uri);
      }
    }
  } catch (const std::exception&) {
    // Tolerant: what was listed so far.
  }
  return files;
}

Scene load_scene(const std::filesystem::path& path, const LoadSettings& settings) {
  try {
    gltf::GltfLoader loader(path, settings);
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

using gltf::json;
using gltf::one_line;

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

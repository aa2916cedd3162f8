// Part of the glTF loader (see scene/gltf/internal.h): materials (glTF 2.0
// section 3.9.2: baseColorFactor and baseColorTexture), textures and images
// (3.8) decoded with stb_image, and KHR_texture_transform.
#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>

#include <stb_image.h>

#include "scene/gltf/internal.h"

namespace snow::gltf {

namespace fs = std::filesystem;

void GltfLoader::read_materials() {
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
      if (const json* v = member(*transform, "offset")) offset = numbers<2>(*v, twhat + " offset");
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

int GltfLoader::texture_source(uint64_t texture) {
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

void GltfLoader::load_images() {
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

int GltfLoader::decode_image(int index) {
  const std::string what = "image " + std::to_string(index);
  const json& object = element(top_array("images"), uint64_t(index), what);
  const std::string name = opt_string(object, "name");
  std::string mime = opt_string(object, "mimeType");
  Bytes owned;  // an image file or data: URI, charged while it is held
  struct Refund {
    uint64_t& loaded;
    const Bytes& owned;
    ~Refund() { loaded -= owned.size(); }
  } refund{loaded_bytes_, owned};
  const uint8_t* data = nullptr;
  uint64_t size = 0;
  std::string label = what;
  if (const json* uri_value = member(object, "uri")) {
    if (!uri_value->is_string()) fail(what + " 'uri' must be a string");
    const std::string uri = uri_value->get<std::string>();
    if (starts_with_ci(uri, "data:")) {
      owned = decode_data_uri(uri, what, &mime);
      charge(owned.size(), what);
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
  charge(uint64_t(width) * uint64_t(height) * 4,
         label + " (" + std::to_string(width) + "x" + std::to_string(height) + " pixels decoded)");
  stbi_uc* pixels = stbi_load_from_memory(data, int(size), &width, &height, &channels, 4);
  if (!pixels) {
    loaded_bytes_ -= uint64_t(width) * uint64_t(height) * 4;
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

}  // namespace snow::gltf

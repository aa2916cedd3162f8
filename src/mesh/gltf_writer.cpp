// glTF 2.0 writer (Khronos glTF 2.0 specification, sections 3.6 "Binary
// data storage" and 3.7 "Geometry"; GLB layout from section 4). Built on
// tinygltf's serializer; buffers are laid out here so that every buffer view
// and accessor is 4-byte aligned and the output is byte-identical for the
// same input.
#include "mesh/gltf_writer.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"

namespace snow {
namespace {

constexpr int kArrayBuffer = TINYGLTF_TARGET_ARRAY_BUFFER;
constexpr int kElementArrayBuffer = TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER;

/// Appends `size` bytes to buffer 0 (4-byte aligned) as a new buffer view;
/// returns its index.
int add_view(tinygltf::Model& model, const void* data, size_t size, int target) {
  std::vector<unsigned char>& bytes = model.buffers[0].data;
  bytes.resize((bytes.size() + 3) & ~size_t(3), 0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = bytes.size();
  view.byteLength = size;
  view.target = target;
  const auto* p = static_cast<const unsigned char*>(data);
  bytes.insert(bytes.end(), p, p + size);
  model.bufferViews.push_back(view);
  return int(model.bufferViews.size()) - 1;
}

int add_accessor(tinygltf::Model& model, int view, int component_type, int type, size_t count,
                 std::vector<double> min = {}, std::vector<double> max = {}) {
  tinygltf::Accessor a;
  a.bufferView = view;
  a.byteOffset = 0;
  a.normalized = false;
  a.componentType = component_type;
  a.type = type;
  a.count = count;
  a.minValues = std::move(min);
  a.maxValues = std::move(max);
  a.sparse.isSparse = false;
  a.sparse.count = 0;
  model.accessors.push_back(a);
  return int(model.accessors.size()) - 1;
}

double clamp01(float v) { return std::isfinite(v) ? std::clamp(double(v), 0.0, 1.0) : 1.0; }

/// Checks `mesh` for writing; returns false (with a warning) when it has no
/// triangles to write.
bool check_mesh(const TriMesh& mesh, size_t index, size_t material_count) {
  const std::string who = "mesh '" + mesh.name + "' (" + std::to_string(index) + ")";
  if (mesh.indices.empty() || mesh.positions.empty()) {
    log_warn("glTF writer: skipping " + who + " because it has no triangles");
    return false;
  }
  if (mesh.indices.size() % 3 != 0)
    throw InputError("glTF writer: " + who + ": index count is not a multiple of 3");
  if (mesh.positions.size() > size_t(std::numeric_limits<uint32_t>::max()))
    throw InputError("glTF writer: " + who + ": too many vertices");
  for (uint32_t i : mesh.indices)
    if (i >= mesh.positions.size())
      throw InputError("glTF writer: " + who + ": index " + std::to_string(i) + " out of range");
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
    throw InputError("glTF writer: " + who + ": normal count differs from position count");
  if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size())
    throw InputError("glTF writer: " + who + ": uv count differs from position count");
  if (mesh.material >= int(material_count))
    throw InputError("glTF writer: " + who + ": material " + std::to_string(mesh.material) +
                     " does not exist");
  for (const glm::vec3& p : mesh.positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw InputError("glTF writer: " + who + ": non-finite position");
  return true;
}

void add_primitive(tinygltf::Model& model, const TriMesh& mesh, int material_offset) {
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.material = mesh.material >= 0 ? material_offset + mesh.material : -1;

  // POSITION with min/max (the validator requires both).
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const glm::vec3& p : mesh.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const size_t n = mesh.positions.size();
  int view = add_view(model, mesh.positions.data(), n * sizeof(glm::vec3), kArrayBuffer);
  prim.attributes["POSITION"] =
      add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n,
                   {lo.x, lo.y, lo.z}, {hi.x, hi.y, hi.z});

  if (!mesh.normals.empty()) {
    // Unit length is required; zero or broken normals become +Y.
    std::vector<glm::vec3> normals(n);
    for (size_t i = 0; i < n; ++i) {
      const glm::vec3 v = mesh.normals[i];
      const float len = glm::length(v);
      normals[i] = (std::isfinite(len) && len > 1e-12f) ? v / len : glm::vec3(0, 1, 0);
    }
    view = add_view(model, normals.data(), n * sizeof(glm::vec3), kArrayBuffer);
    prim.attributes["NORMAL"] =
        add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
  }
  if (!mesh.uvs.empty()) {
    view = add_view(model, mesh.uvs.data(), n * sizeof(glm::vec2), kArrayBuffer);
    prim.attributes["TEXCOORD_0"] =
        add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, n);
  }

  // Indices: uint16 when every index fits below the primitive-restart value.
  const uint32_t max_index = *std::max_element(mesh.indices.begin(), mesh.indices.end());
  if (max_index < 0xFFFFu) {
    std::vector<uint16_t> small(mesh.indices.begin(), mesh.indices.end());
    view = add_view(model, small.data(), small.size() * sizeof(uint16_t), kElementArrayBuffer);
    prim.indices = add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                TINYGLTF_TYPE_SCALAR, small.size());
  } else {
    view = add_view(model, mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t),
                    kElementArrayBuffer);
    prim.indices = add_accessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                TINYGLTF_TYPE_SCALAR, mesh.indices.size());
  }

  tinygltf::Mesh gm;
  gm.name = mesh.name;
  gm.primitives.push_back(std::move(prim));
  model.meshes.push_back(std::move(gm));
}

void serialize(const tinygltf::Model& model, bool binary, const std::filesystem::path& path,
               std::ostream& out) {
  tinygltf::TinyGLTF writer;
  // Keep images as they are (their uri or buffer view) instead of re-encoding.
  writer.SetImageWriter(nullptr, nullptr);
  if (!writer.WriteGltfSceneToStream(&model, out, /*prettyPrint=*/true, binary))
    throw IOError("cannot serialize glTF for " + path.string());
}

}  // namespace

size_t detail::empty_buffer0_length_at(const std::string& json) {
  static const std::string key = "\"buffers\":[{\"byteLength\":0";
  int depth = 0;
  for (size_t k = 0; k < json.size(); ++k) {
    const char c = json[k];
    if (c == '"') {
      if (depth == 1 && json.compare(k, key.size(), key) == 0) {
        const size_t zero = k + key.size() - 1;
        const char after = zero + 1 < json.size() ? json[zero + 1] : '\0';
        return after == ',' || after == '}' ? zero : std::string::npos;
      }
      for (++k; k < json.size() && json[k] != '"'; ++k) {
        if (json[k] == '\\') ++k;  // an escaped character
      }
    } else if (c == '{' || c == '[') {
      ++depth;
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return std::string::npos;
}

namespace {

void put_u32(std::ostream& out, uint32_t v) {
  const unsigned char b[4] = {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)};
  out.write(reinterpret_cast<const char*>(b), 4);
}

/// Writes `model` as GLB with buffer 0 as its BIN chunk, the same bytes as
/// tinygltf's GLB writer but without its copy of buffer 0: tinygltf
/// serializes the JSON with buffer 0 emptied, its byteLength is set in the
/// text, and the chunk is written from the model's own bytes.
void write_glb(tinygltf::Model& model, const std::filesystem::path& path, std::ostream& out) {
  std::vector<unsigned char> bin;
  if (!model.buffers.empty()) bin.swap(model.buffers[0].data);
  std::string json = glb_json(model, path);
  const size_t zero = detail::empty_buffer0_length_at(json);
  if (uint64_t(bin.size()) + json.size() + 64 > UINT32_MAX) {
    throw IOError("cannot write " + path.string() +
                  ": a GLB holds at most 4 GiB; write .gltf (its buffers go to .bin files)");
  }
  if (bin.empty() || zero == std::string::npos) {
    // No bytes to move, or JSON of an unexpected form: tinygltf writes it all.
    if (!model.buffers.empty()) model.buffers[0].data.swap(bin);
    serialize(model, true, path, out);
    return;
  }
  json.replace(zero, 1, std::to_string(bin.size()));
  const size_t json_padded = (json.size() + 3) & ~size_t(3);
  const size_t bin_padded = (bin.size() + 3) & ~size_t(3);
  const size_t total = 12 + 8 + json_padded + 8 + bin_padded;
  out.write("glTF", 4);
  put_u32(out, 2);
  put_u32(out, uint32_t(total));
  put_u32(out, uint32_t(json_padded));
  out.write("JSON", 4);
  out.write(json.data(), std::streamsize(json.size()));
  out.write("   ", std::streamsize(json_padded - json.size()));
  put_u32(out, uint32_t(bin_padded));
  out.write("BIN\0", 4);
  out.write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
  out.write("\0\0\0", std::streamsize(bin_padded - bin.size()));
}

}  // namespace

std::string glb_json(const tinygltf::Model& model, const std::filesystem::path& path) {
  std::ostringstream glb;
  serialize(model, true, path, glb);
  std::string json = glb.str();
  if (json.size() < 20) return {};
  json = json.substr(20);  // the header and the JSON chunk's header
  while (!json.empty() && json.back() == ' ') json.pop_back();  // its padding
  return json;
}

void append_meshes(tinygltf::Model& model, const std::vector<TriMesh>& meshes,
                   const std::vector<MeshMaterial>& materials, const std::string& root_name) {
  std::vector<bool> write(meshes.size());
  for (size_t i = 0; i < meshes.size(); ++i) write[i] = check_mesh(meshes[i], i, materials.size());

  if (model.asset.version.empty()) model.asset.version = "2.0";
  if (model.asset.generator.empty()) model.asset.generator = "snowmodel";
  if (model.buffers.empty() && std::find(write.begin(), write.end(), true) != write.end())
    model.buffers.emplace_back();
  // Buffer 0 grows once (unless the caller made room).
  if (!model.buffers.empty()) {
    model.buffers[0].data.reserve(model.buffers[0].data.size() + mesh_buffer_bytes(meshes));
  }

  const int material_offset = int(model.materials.size());
  for (const MeshMaterial& m : materials) {
    tinygltf::Material gm;
    gm.name = m.name;
    gm.pbrMetallicRoughness.baseColorFactor = {clamp01(m.base_color.r), clamp01(m.base_color.g),
                                               clamp01(m.base_color.b), clamp01(m.base_color.a)};
    gm.pbrMetallicRoughness.roughnessFactor = clamp01(m.roughness);
    gm.pbrMetallicRoughness.metallicFactor = clamp01(m.metallic);
    if (m.base_color.a < 1.0f) gm.alphaMode = "BLEND";
    model.materials.push_back(std::move(gm));
  }

  tinygltf::Node root;
  root.name = root_name;
  for (size_t i = 0; i < meshes.size(); ++i) {
    if (!write[i]) continue;
    add_primitive(model, meshes[i], material_offset);
    tinygltf::Node node;
    node.name = meshes[i].name;
    node.mesh = int(model.meshes.size()) - 1;
    model.nodes.push_back(std::move(node));
    root.children.push_back(int(model.nodes.size()) - 1);
  }
  model.nodes.push_back(std::move(root));
  const int root_index = int(model.nodes.size()) - 1;

  if (model.scenes.empty()) model.scenes.emplace_back();
  if (model.defaultScene < 0 || model.defaultScene >= int(model.scenes.size()))
    model.defaultScene = 0;
  model.scenes[size_t(model.defaultScene)].nodes.push_back(root_index);
}

size_t mesh_buffer_bytes(const std::vector<TriMesh>& meshes) {
  size_t bytes = 0;
  for (const TriMesh& m : meshes) {
    // add_primitive's views: positions, normals, UVs and indices (uint32 at
    // most), each padded to 4 bytes.
    bytes += m.positions.size() * sizeof(glm::vec3) + m.normals.size() * sizeof(glm::vec3) +
             m.uvs.size() * sizeof(glm::vec2) + m.indices.size() * sizeof(uint32_t) + 4 * 3;
  }
  return bytes;
}

void save_gltf(tinygltf::Model model, const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".glb") {
    // Buffer 0 becomes the GLB's BIN chunk. Streamed into the file: no copy
    // of the buffers in memory, which on a large scene would be much of the
    // export's time.
    if (!model.buffers.empty()) model.buffers[0].uri.clear();
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
      std::ofstream out(tmp, std::ios::binary);
      if (!out) throw IOError("cannot write " + path.string() + ": " + std::strerror(errno));
      write_glb(model, path, out);
      out.flush();
      if (!out) throw IOError("cannot write " + path.string() + ": " + std::strerror(errno));
    });
    return;
  }
  if (ext != ".gltf")
    throw InputError("glTF writer: " + path.string() + ": extension must be .glb or .gltf");

  // .gltf: every buffer goes to "<stem>.bin", "<stem>1.bin", ... beside it.
  // The JSON is serialized with empty buffers, then their uri and
  // byteLength are set.
  std::vector<std::vector<unsigned char>> data(model.buffers.size());
  std::vector<std::string> uris(model.buffers.size());
  const std::string stem = path.stem().string();
  for (size_t i = 0; i < model.buffers.size(); ++i) {
    data[i] = std::move(model.buffers[i].data);
    model.buffers[i].data.clear();
    model.buffers[i].uri.clear();
    uris[i] = stem + (i == 0 ? std::string() : std::to_string(i)) + ".bin";
  }
  nlohmann::json json;
  try {
    std::ostringstream text;
    serialize(model, false, path, text);
    json = nlohmann::json::parse(text.str());
    for (size_t i = 0; i < data.size(); ++i) {
      json["buffers"][i]["uri"] = uris[i];
      json["buffers"][i]["byteLength"] = data[i].size();
    }
  } catch (const nlohmann::json::exception& e) {
    throw IOError("cannot serialize glTF for " + path.string() + ": " + e.what());
  }
  for (size_t i = 0; i < data.size(); ++i)
    write_bytes_atomically(path.parent_path() / uris[i], data[i].data(), data[i].size());
  write_text_atomically(path, json.dump(2) + "\n");
}

}  // namespace snow

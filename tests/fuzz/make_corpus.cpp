// Writes the seed corpus of the fuzz targets into a folder: the scenes of
// src/scene/builder.h as .glb (through the glTF writer) and as single-file
// .gltf JSON (data-URI buffer), plus crafted bad files like the ones of
// tests/test_scene_load.cpp (broken containers, out-of-range references,
// absurd counts, cycles, non-finite values, refused extensions, JSON nested
// too deep, files outside the scene's folder).
//   snowmodel_fuzz_corpus <out_dir>
#include <tiny_gltf.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <vector>

#include "../support/base64.h"
#include "mesh/gltf_writer.h"
#include "scene/builder.h"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

void write_file(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

using snow::test::base64;

uint32_t u32_at(const std::vector<uint8_t>& b, size_t at) {
  return uint32_t(b[at]) | uint32_t(b[at + 1]) << 8 | uint32_t(b[at + 2]) << 16 |
         uint32_t(b[at + 3]) << 24;
}

/// Splits a GLB into its JSON and BIN chunks.
void split_glb(const std::vector<uint8_t>& glb, json& doc, std::vector<uint8_t>& bin) {
  const uint32_t json_len = u32_at(glb, 12);
  doc = json::parse(glb.begin() + 20, glb.begin() + 20 + json_len);
  bin.clear();
  const size_t at = 20 + json_len;
  if (at + 8 <= glb.size()) {
    const uint32_t bin_len = u32_at(glb, at);
    bin.assign(glb.begin() + long(at + 8), glb.begin() + long(at + 8 + bin_len));
  }
}

std::vector<uint8_t> make_glb(const json& doc, std::vector<uint8_t> bin) {
  std::string text = doc.dump();
  while (text.size() % 4) text += ' ';
  while (bin.size() % 4) bin.push_back(0);
  std::vector<uint8_t> out;
  auto u32 = [&out](uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
  };
  u32(0x46546C67);
  u32(2);
  u32(uint32_t(12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size())));
  u32(uint32_t(text.size()));
  u32(0x4E4F534A);
  out.insert(out.end(), text.begin(), text.end());
  if (!bin.empty()) {
    u32(uint32_t(bin.size()));
    u32(0x004E4942);
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

/// The same document as one .gltf JSON file with a data-URI buffer.
std::string to_gltf_text(json doc, const std::vector<uint8_t>& bin) {
  if (doc.contains("buffers") && !doc["buffers"].empty()) {
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64(bin);
  }
  return doc.dump();
}

std::vector<uint8_t> scene_glb(const snow::Scene& scene, const fs::path& scratch) {
  std::vector<snow::TriMesh> meshes;
  for (const snow::SceneObject& o : scene.objects) {
    snow::TriMesh m;
    m.name = o.name;
    for (uint32_t t = 0; t < o.triangle_count; ++t) {
      for (int k = 0; k < 3; ++k) {
        const size_t v = (size_t(o.first_triangle) + t) * 3 + size_t(k);
        m.indices.push_back(uint32_t(m.positions.size()));
        m.positions.push_back(scene.positions[v]);
      }
    }
    meshes.push_back(std::move(m));
  }
  tinygltf::Model model;
  snow::append_meshes(model, meshes, {snow::MeshMaterial{}}, "Scene");
  snow::save_gltf(model, scratch);
  std::ifstream in(scratch, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

/// A one-triangle document (positions, normals, uint16 indices) plus its buffer.
void triangle_doc(json& doc, std::vector<uint8_t>& bin) {
  const float pos[9] = {0, 0, 0, 0, 0, 1, 1, 0, 0};
  const float nrm[9] = {0, 1, 0, 0, 1, 0, 0, 1, 0};
  const uint16_t idx[4] = {0, 1, 2, 0};
  bin.assign(reinterpret_cast<const uint8_t*>(pos), reinterpret_cast<const uint8_t*>(pos) + 36);
  bin.insert(bin.end(), reinterpret_cast<const uint8_t*>(nrm),
             reinterpret_cast<const uint8_t*>(nrm) + 36);
  bin.insert(bin.end(), reinterpret_cast<const uint8_t*>(idx),
             reinterpret_cast<const uint8_t*>(idx) + 8);
  doc = json::parse(R"({
    "asset": {"version": "2.0"},
    "buffers": [{"byteLength": 80}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                    {"buffer": 0, "byteOffset": 36, "byteLength": 36},
                    {"buffer": 0, "byteOffset": 72, "byteLength": 6}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 0, 1]},
                  {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
                  {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    "meshes": [{"name": "Tri", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1},
                                               "indices": 2, "mode": 4}]}],
    "nodes": [{"name": "N", "mesh": 0, "translation": [1, 2, 3]}],
    "scenes": [{"nodes": [0]}],
    "scene": 0
  })");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: snowmodel_fuzz_corpus <out_dir>\n";
    return 2;
  }
  const fs::path out = argv[1];
  fs::create_directories(out);
  const fs::path scratch = out / "scratch.glb";
  int written = 0;
  auto emit = [&](const std::string& name, const std::vector<uint8_t>& bytes) {
    write_file(out / name, bytes);
    ++written;
  };
  auto emit_doc = [&](const std::string& name, const json& doc, const std::vector<uint8_t>& bin) {
    emit(name + ".glb", make_glb(doc, bin));
    const std::string text = to_gltf_text(doc, bin);
    emit(name + ".gltf", std::vector<uint8_t>(text.begin(), text.end()));
  };

  // Generated scenes.
  snow::TableDims table;
  const std::vector<std::pair<std::string, snow::Scene>> scenes = {
      {"plane", snow::make_open_plane(4.0f)},     {"table", snow::make_table_scene(table)},
      {"box", snow::make_closed_box_scene(1.0f)}, {"wall", snow::make_wall_scene(2.0f, 3.0f, 5.0f)},
      {"house", snow::make_house_scene(45.0f)},   {"stairs", snow::make_stairs_scene()},
      {"bowl", snow::make_bowl_scene()},
  };
  for (const auto& [name, scene] : scenes) {
    const std::vector<uint8_t> glb = scene_glb(scene, scratch);
    emit("gen_" + name + ".glb", glb);
    json doc;
    std::vector<uint8_t> bin;
    split_glb(glb, doc, bin);
    const std::string text = to_gltf_text(doc, bin);
    emit("gen_" + name + ".gltf", std::vector<uint8_t>(text.begin(), text.end()));
  }
  fs::remove(scratch);

  // Crafted files, good and bad, around one triangle.
  json doc;
  std::vector<uint8_t> bin;
  triangle_doc(doc, bin);
  emit_doc("tri", doc, bin);
  const std::vector<uint8_t> glb = make_glb(doc, bin);
  emit("bad_truncated.glb", std::vector<uint8_t>(glb.begin(), glb.begin() + long(glb.size() / 2)));
  emit("bad_tiny.glb", {'g', 'l', 'T', 'F', 2, 0});
  std::vector<uint8_t> magic = glb;
  magic[3] = 'X';
  emit("bad_magic.glb", magic);
  std::vector<uint8_t> chunk = glb;
  chunk[12] = chunk[13] = 0xFF;
  emit("bad_chunk.glb", chunk);
  const std::string broken = R"({"asset": {"version": "2.0"}, "nodes": [)";
  emit("bad_broken.gltf", std::vector<uint8_t>(broken.begin(), broken.end()));
  const std::string overflow =
      R"({"asset": {"version": "2.0"}, "nodes": [{"scale": [1e999, 1, 1]}]})";
  emit("bad_overflow.gltf", std::vector<uint8_t>(overflow.begin(), overflow.end()));

  auto variant = [&](const std::string& name, auto&& edit) {
    json d = doc;
    std::vector<uint8_t> b = bin;
    edit(d, b);
    emit_doc(name, d, b);
  };
  variant("bad_index", [](json&, std::vector<uint8_t>& b) { b[72 + 4] = 7; });
  variant("bad_view_range", [](json& d, auto&) { d["bufferViews"][0]["byteLength"] = 4000; });
  variant("bad_view_buffer", [](json& d, auto&) { d["bufferViews"][0]["buffer"] = 3; });
  variant("bad_count", [](json& d, auto&) { d["accessors"][0]["count"] = 1000000000; });
  variant("bad_count_zero", [](json& d, auto&) { d["accessors"][0]["count"] = 0; });
  variant("bad_count_noview", [](json& d, auto&) {
    d["accessors"][0]["count"] = 1000000000;
    d["accessors"][0].erase("bufferView");
  });
  variant("bad_count_huge", [](json& d, auto&) { d["accessors"][0]["count"] = 10000000000000ull; });
  variant("bad_count_negative", [](json& d, auto&) { d["accessors"][0]["count"] = -3; });
  variant("bad_stride", [](json& d, auto&) { d["bufferViews"][0]["byteStride"] = 4; });
  variant("bad_type", [](json& d, auto&) { d["accessors"][0]["type"] = "VEC2"; });
  variant("bad_material", [](json& d, auto&) { d["meshes"][0]["primitives"][0]["material"] = 5; });
  variant("bad_nan", [](json&, std::vector<uint8_t>& b) {
    const float nan = std::nanf("");
    std::memcpy(b.data() + 24, &nan, 4);
  });
  // Issue 48: a texCoord beyond int (kept by the combined writer, never
  // wrapped).
  variant("wide_texcoord", [](json& d, auto&) {
    d["textures"] = json::array({json::object()});
    d["materials"] = {{{"pbrMetallicRoughness",
                        {{"baseColorTexture", {{"index", 0}, {"texCoord", 2147483648u}}}}}}};
    d["meshes"][0]["primitives"][0]["material"] = 0;
  });
  variant("bad_inf_scale", [](json& d, auto&) { d["nodes"][0]["scale"] = {1e39, 1, 1}; });
  variant("bad_quat", [](json& d, auto&) { d["nodes"][0]["rotation"] = {0, 0, 0, 0}; });
  variant("bad_matrix", [](json& d, auto&) { d["nodes"][0]["matrix"] = {1, 0, 0}; });
  variant("bad_cycle", [](json& d, auto&) {
    d["nodes"][0]["children"] = {1};
    d["nodes"][1] = {{"children", {0}}};
  });
  variant("bad_self", [](json& d, auto&) { d["nodes"][0]["children"] = {0}; });
  variant("bad_shared", [](json& d, auto&) {
    d["nodes"][1] = {{"children", {0}}};
    d["nodes"][2] = {{"children", {0}}};
    d["scenes"][0]["nodes"] = {1, 2};
  });
  variant("bad_child", [](json& d, auto&) { d["nodes"][0]["children"] = {42}; });
  variant("bad_meshopt", [](json& d, auto&) {
    d["extensionsUsed"] = {"EXT_meshopt_compression"};
    d["extensionsRequired"] = {"EXT_meshopt_compression"};
  });
  variant("bad_points", [](json& d, auto&) { d["meshes"][0]["primitives"][0]["mode"] = 0; });
  variant("strip", [](json& d, auto&) { d["meshes"][0]["primitives"][0]["mode"] = 5; });
  variant("fan", [](json& d, auto&) { d["meshes"][0]["primitives"][0]["mode"] = 6; });
  variant("noindex", [](json& d, auto&) { d["meshes"][0]["primitives"][0].erase("indices"); });
  variant("no_scenes", [](json& d, auto&) {
    d.erase("scenes");
    d.erase("scene");
  });
  variant("sparse", [](json& d, std::vector<uint8_t>& b) {
    const uint32_t index = 1;
    const float value[3] = {0, 1, 1};
    const size_t at = b.size();
    b.resize(at + 16);
    std::memcpy(b.data() + at, &index, 4);
    std::memcpy(b.data() + at + 4, value, 12);
    d["buffers"][0]["byteLength"] = b.size();
    d["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", at}, {"byteLength", 4}});
    d["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", at + 4}, {"byteLength", 12}});
    d["accessors"][0]["sparse"] = {{"count", 1},
                                   {"indices", {{"bufferView", 3}, {"componentType", 5125}}},
                                   {"values", {{"bufferView", 4}}}};
  });
  variant("instancing", [](json& d, std::vector<uint8_t>& b) {
    const float t[6] = {0, 0, 0, 2, 0, 0};
    const size_t at = b.size();
    b.resize(at + 24);
    std::memcpy(b.data() + at, t, 24);
    d["buffers"][0]["byteLength"] = b.size();
    d["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", at}, {"byteLength", 24}});
    d["accessors"].push_back(
        {{"bufferView", 3}, {"componentType", 5126}, {"count", 2}, {"type", "VEC3"}});
    d["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
    d["nodes"][0]["extensions"] = {
        {"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", 3}}}}}};
  });
  variant("material_texture", [](json& d, auto&) {
    d["materials"] = json::array(
        {{{"pbrMetallicRoughness",
           {{"baseColorFactor", {1, 0.5, 0.5, 1}},
            {"baseColorTexture",
             {{"index", 0}, {"extensions", {{"KHR_texture_transform", {{"scale", {2, 2}}}}}}}}}}}});
    d["textures"] = json::array({{{"source", 0}}});
    // A 1x1 PNG as a data URI.
    d["images"] = json::array(
        {{{"uri",
           "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8/"
           "5+hHgAHggJ/PchI7wAAAABJRU5ErkJggg=="}}});
    d["meshes"][0]["primitives"][0]["material"] = 0;
  });
  variant("uri_escape", [](json& d, auto&) { d["buffers"][0]["uri"] = "../outside.bin"; });
  // The combined writer (mesh/glb_stream.h): buffers merged into one, a
  // view into a second buffer (a data URI, as seeds are single files), an
  // unused buffer that holds less than its byteLength, an
  // EXT_meshopt_compression view naming a buffer.
  variant("two_buffers", [](json& d, auto&) {
    d["buffers"].push_back(
        {{"uri", "data:application/octet-stream;base64,AAAAAAAAgD8AAAAA"}, {"byteLength", 12}});
    d["bufferViews"].push_back({{"buffer", 1}, {"byteLength", 12}});
  });
  variant("unused_short_buffer", [](json& d, auto&) {
    d["buffers"].push_back(
        {{"uri", "data:application/octet-stream;base64,AAAA"}, {"byteLength", 144}});
  });
  variant("meshopt_view", [](json& d, auto&) {
    d["extensionsUsed"] = {"EXT_meshopt_compression"};
    d["bufferViews"][0]["extensions"] = {
        {"EXT_meshopt_compression",
         {{"buffer", 0}, {"byteOffset", 4}, {"byteLength", 8}, {"count", 1}, {"byteStride", 4}}}};
  });
  // The input policy (scene/input_policy.h): JSON nested past kMaxJsonDepth,
  // image files outside the scene's folder ("..", percent-encoded, absolute).
  // Symlinks and FIFOs are no seeds: the fuzz targets read bytes, not folders.
  {
    std::string deep = to_gltf_text(doc, bin);
    deep.insert(deep.rfind('}'),
                ",\"extras\":" + std::string(30000, '[') + std::string(30000, ']'));
    emit("bad_deep_json.gltf", std::vector<uint8_t>(deep.begin(), deep.end()));
  }
  {
    // 100,000 levels: refused by the loader, which is the only parser of
    // the input (the combined writer included).
    std::string deep = to_gltf_text(doc, bin);
    deep.insert(deep.rfind('}'),
                ",\"extras\":" + std::string(100000, '[') + std::string(100000, ']'));
    emit("bad_deeper_json.gltf", std::vector<uint8_t>(deep.begin(), deep.end()));
  }
  for (const auto& [name, uri] : {std::pair<const char*, const char*>{"dotdot", "../x.png"},
                                  {"percent", "%2e%2e/x.png"},
                                  {"absolute", "/etc/hostname"}}) {
    variant(std::string("bad_image_") + name, [uri = uri](json& d, auto&) {
      d["images"] = json::array({{{"uri", uri}}});
      d["textures"] = json::array({{{"source", 0}}});
      d["materials"] =
          json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
      d["meshes"][0]["primitives"][0]["material"] = 0;
    });
  }
  std::cout << "wrote " << written << " seed files to " << out.string() << "\n";
  return 0;
}

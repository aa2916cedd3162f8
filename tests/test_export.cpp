// Tests for snow mesh export: snow-only GLB/glTF/OBJ/PLY and the input scene
// plus snow. Every glTF and GLB written here goes through the Khronos glTF
// validator (tools/validator, installed with `npm ci` there) when node and the
// validator are installed.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <tiny_gltf.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb_image_write.h>

#include "core/error.h"
#include "mesh/export.h"
#include "mesh/gltf_writer.h"
#include "mesh/polygonize.h"
#include "scene/load_gltf.h"
#include "support/draco_quad.h"
#include "support/validator.h"

namespace snow {
namespace {
namespace fs = std::filesystem;
using test::expect_valid_gltf;
using test::run_validator;
using test::Validation;

// ---------------------------------------------------------------------------
// Helpers

/// A fresh, empty folder for one test, removed afterwards (kept when the
/// environment variable SNOW_KEEP_TEST_OUTPUT is set, to look at the files).
struct TestDir {
  fs::path path;
  TestDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path = fs::temp_directory_path() /
           ("snow_test_export_" + std::string(info->name()) + "_" + std::to_string(getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TestDir() {
    std::error_code ec;
    if (!std::getenv("SNOW_KEEP_TEST_OUTPUT")) fs::remove_all(path, ec);
  }
  TestDir(const TestDir&) = delete;
  TestDir& operator=(const TestDir&) = delete;
};

tinygltf::Model load_gltf(const fs::path& path) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  const bool ok = path.extension() == ".glb"
                      ? loader.LoadBinaryFromFile(&model, &err, &warn, path.string())
                      : loader.LoadASCIIFromFile(&model, &err, &warn, path.string());
  EXPECT_TRUE(ok) << path << ": " << err;
  return model;
}

/// Snow on a table and the floor around (see test_polygonize): two patches,
/// "snow/Floor" and "snow/Table Top" (a name with a space).
std::vector<SnowPatch> table_patches() {
  SnowMaps maps;
  MapGrid grid;
  grid.origin = glm::vec2(-1.6f);
  grid.texel = 0.1f;
  grid.width = grid.height = 32;
  maps.allocate(grid, 3);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 0; j < 32; ++j) {
    for (int i = 0; i < 32; ++i) {
      const bool under = i >= 10 && i < 22 && j >= 10 && j < 22;
      auto set = [&](int l, float g, float c, glm::vec3 n, int object, float d) {
        const size_t k = maps.index(l, i, j);
        maps.ground[k] = g;
        maps.ceiling[k] = c;
        maps.normal[k] = n;
        maps.object[k] = object;
        depth[k] = d;
      };
      const float floor_snow = (i >= 2 && i < 30 && j >= 2 && j < 30) ? 0.2f : 0.0f;
      if (under) {
        set(0, 0.75f, kOpenSky, {0, 1, 0}, 1, 0.15f);
        set(1, 0.70f, 0.75f, {0, -1, 0}, 1, 0.0f);
        set(2, 0.0f, 0.70f, {0, 1, 0}, 0, 0.0f);
      } else {
        set(0, 0.0f, kOpenSky, {0, 1, 0}, 0, floor_snow);
      }
    }
  }
  Scene scene;
  for (const char* name : {"Floor", "Table Top"}) {
    SceneObject o;
    o.name = name;
    scene.objects.push_back(o);
  }
  return polygonize(maps, depth, scene, {});
}

size_t count_lines(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  size_t n = 0;
  for (std::string line; std::getline(in, line);) n += line.rfind(prefix, 0) == 0;
  return n;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// ---------------------------------------------------------------------------

TEST(Export, FormatFromPath) {
  EXPECT_EQ(format_from_path("a/b.glb"), MeshFormat::Glb);
  EXPECT_EQ(format_from_path("b.GLTF"), MeshFormat::Gltf);
  EXPECT_EQ(format_from_path("snow.Obj"), MeshFormat::Obj);
  EXPECT_EQ(format_from_path("snow.ply"), MeshFormat::Ply);
  EXPECT_THROW(format_from_path("snow.fbx"), InputError);
  EXPECT_THROW(format_from_path("snow"), InputError);
  EXPECT_STREQ(format_name(MeshFormat::Ply), "ply");
  const MeshMaterial m = snow_material();
  EXPECT_NEAR(m.roughness, 0.8f, 1e-6f);
  EXPECT_EQ(m.metallic, 0.0f);
  EXPECT_GE(m.base_color.r, 0.85f);
  EXPECT_EQ(m.base_color.r, m.base_color.b);
}

TEST(Export, ValidatorIsInstalled) {
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  write_snow_meshes(table_patches(), dir / "probe.glb", MeshFormat::Glb);
  const Validation v = run_validator({dir / "probe.glb"});
  if (!v.ran) {
    GTEST_SKIP() << "node or the glTF validator is missing: run `npm ci` in tools/validator";
  }
  EXPECT_EQ(v.status, 0) << v.output;
  // And it does catch errors: a GLB cut short is reported.
  const std::string bytes = read_text(dir / "probe.glb");
  std::ofstream(dir / "broken.glb", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  const Validation broken = run_validator({dir / "broken.glb"});
  EXPECT_NE(broken.status, 0) << broken.output;
}

TEST(Export, SnowOnlyGltfHasASnowRootPerPatchNodesAndValidates) {
  const auto patches = table_patches();
  ASSERT_EQ(patches.size(), 2u);
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  for (const char* name : {"snow.glb", "snow.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path path = dir / name;
    write_snow_meshes(patches, path, format_from_path(path));
    ASSERT_TRUE(fs::exists(path));
    if (path.extension() == ".gltf") {
      EXPECT_TRUE(fs::exists(dir / "snow.bin"));
    }
    const tinygltf::Model model = load_gltf(path);
    ASSERT_EQ(model.scenes.size(), 1u);
    const auto& roots = model.scenes[size_t(std::max(model.defaultScene, 0))].nodes;
    ASSERT_EQ(roots.size(), 1u);
    const tinygltf::Node& snow = model.nodes[size_t(roots[0])];
    EXPECT_EQ(snow.name, "Snow");
    EXPECT_TRUE(snow.matrix.empty() && snow.translation.empty() && snow.rotation.empty());
    ASSERT_EQ(snow.children.size(), patches.size());
    std::set<std::string> names;
    for (size_t c = 0; c < snow.children.size(); ++c) {
      const tinygltf::Node& node = model.nodes[size_t(snow.children[c])];
      names.insert(node.name);
      ASSERT_GE(node.mesh, 0);
      const tinygltf::Primitive& prim = model.meshes[size_t(node.mesh)].primitives.at(0);
      EXPECT_TRUE(prim.attributes.count("NORMAL"));
      EXPECT_TRUE(prim.attributes.count("TEXCOORD_0"));
      const tinygltf::Accessor& idx = model.accessors[size_t(prim.indices)];
      EXPECT_EQ(idx.count, patches[c].mesh.indices.size());
      const tinygltf::Material& m = model.materials[size_t(prim.material)];
      EXPECT_EQ(m.name, "snow");
      EXPECT_NEAR(m.pbrMetallicRoughness.roughnessFactor, 0.8, 1e-6);
      EXPECT_NEAR(m.pbrMetallicRoughness.baseColorFactor[0], 0.9, 1e-6);
    }
    EXPECT_EQ(names, (std::set<std::string>{"snow/Floor", "snow/Table Top"}));
  }
  // No patches at all still gives valid, empty files.
  write_snow_meshes({}, dir / "empty.glb", MeshFormat::Glb);
  write_snow_meshes({}, dir / "empty.gltf", MeshFormat::Gltf);
  expect_valid_gltf({dir / "snow.glb", dir / "snow.gltf", dir / "empty.glb", dir / "empty.gltf"});
}

TEST(Export, ObjHasOneObjectPerPatchWithNormalsUvsAndMaterial) {
  const auto patches = table_patches();
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  write_snow_meshes(patches, dir / "snow.obj", MeshFormat::Obj);
  const std::string obj = read_text(dir / "snow.obj");
  const std::string mtl = read_text(dir / "snow.mtl");
  size_t vertices = 0, faces = 0;
  for (const auto& p : patches) {
    vertices += p.mesh.positions.size();
    faces += p.mesh.indices.size() / 3;
  }
  EXPECT_EQ(count_lines(obj, "mtllib snow.mtl"), 1u);
  EXPECT_EQ(count_lines(obj, "o "), patches.size());
  EXPECT_EQ(count_lines(obj, "o snow/Floor"), 1u);
  EXPECT_EQ(count_lines(obj, "o snow/Table_Top"), 1u);
  EXPECT_EQ(count_lines(obj, "v "), vertices);
  EXPECT_EQ(count_lines(obj, "vt "), vertices);
  EXPECT_EQ(count_lines(obj, "vn "), vertices);
  EXPECT_EQ(count_lines(obj, "f "), faces);
  EXPECT_EQ(count_lines(obj, "usemtl snow"), patches.size());
  EXPECT_EQ(count_lines(mtl, "newmtl snow"), 1u);
  EXPECT_EQ(count_lines(mtl, "Pr 0.8"), 1u);
  // Every face refers to existing v/vt/vn, the same index for all three.
  std::istringstream in(obj);
  size_t checked = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("f ", 0) != 0) continue;
    std::istringstream f(line.substr(2));
    for (int c = 0; c < 3; ++c) {
      std::string corner;
      f >> corner;
      size_t v = 0, vt = 0, vn = 0;
      ASSERT_EQ(std::sscanf(corner.c_str(), "%zu/%zu/%zu", &v, &vt, &vn), 3) << line;
      ASSERT_GE(v, 1u);
      ASSERT_LE(v, vertices);
      ASSERT_EQ(v, vt);
      ASSERT_EQ(v, vn);
    }
    ++checked;
  }
  EXPECT_EQ(checked, faces);
  // The first vertex round-trips.
  std::istringstream again(obj);
  for (std::string line; std::getline(again, line);) {
    if (line.rfind("v ", 0) != 0) continue;
    float x, y, z;
    ASSERT_EQ(std::sscanf(line.c_str(), "v %f %f %f", &x, &y, &z), 3);
    EXPECT_EQ(x, patches[0].mesh.positions[0].x);
    EXPECT_EQ(y, patches[0].mesh.positions[0].y);
    EXPECT_EQ(z, patches[0].mesh.positions[0].z);
    break;
  }
}

TEST(Export, PlyHoldsAllPatchesInOneBinaryMesh) {
  const auto patches = table_patches();
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  write_snow_meshes(patches, dir / "snow.ply", MeshFormat::Ply);
  const std::string bytes = read_text(dir / "snow.ply");
  const size_t end = bytes.find("end_header\n");
  ASSERT_NE(end, std::string::npos);
  const std::string header = bytes.substr(0, end);
  size_t vertices = 0, faces = 0;
  for (const auto& p : patches) {
    vertices += p.mesh.positions.size();
    faces += p.mesh.indices.size() / 3;
  }
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  EXPECT_NE(header.find("element vertex " + std::to_string(vertices) + "\n"), std::string::npos);
  EXPECT_NE(header.find("element face " + std::to_string(faces) + "\n"), std::string::npos);
  EXPECT_NE(header.find("property float nx"), std::string::npos);
  EXPECT_NE(header.find("property float s"), std::string::npos);
  EXPECT_NE(header.find("comment mesh snow/Table Top faces"), std::string::npos);
  const size_t body = end + std::strlen("end_header\n");
  ASSERT_EQ(bytes.size(), body + vertices * 32 + faces * 13);
  // Vertices of the second patch follow the first's; faces index them.
  const glm::vec3 p = patches[1].mesh.positions[0];
  float xyz[3];
  std::memcpy(xyz, bytes.data() + body + patches[0].mesh.positions.size() * 32, sizeof(xyz));
  EXPECT_EQ(xyz[0], p.x);
  EXPECT_EQ(xyz[1], p.y);
  EXPECT_EQ(xyz[2], p.z);
  const char* face = bytes.data() + body + vertices * 32;
  uint32_t max_index = 0;
  for (size_t f = 0; f < faces; ++f, face += 13) {
    ASSERT_EQ(face[0], 3);
    for (int c = 0; c < 3; ++c) {
      uint32_t v;
      std::memcpy(&v, face + 1 + 4 * c, 4);
      max_index = std::max(max_index, v);
    }
  }
  EXPECT_EQ(max_index + 1, vertices);
}

/// The input as the batch job reads it: loaded once, its JSON kept
/// (LoadSettings::keep_source) for the combined writer.
std::shared_ptr<const SourceGltf> source_of(const fs::path& input) {
  LoadSettings settings;
  settings.load_images = false;
  settings.shading = false;
  settings.keep_source = true;
  return load_scene(input, settings).source;
}

/// write_combined_gltf of the scene at `input` (loaded by source_of).
void combined_from(const fs::path& input, const std::vector<SnowPatch>& patches,
                   const fs::path& out) {
  write_combined_gltf(*source_of(input), patches, out);
}

/// The combined output of the scene at `input`, planned ahead.
CombinedInputPtr planned(const fs::path& input) { return plan_combined_gltf(*source_of(input)); }

TEST(Export, UnwritablePathIsAnIOErrorAndLeavesNothing) {
  const auto patches = table_patches();
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  for (const char* name : {"snow.glb", "snow.gltf", "snow.obj", "snow.ply"}) {
    SCOPED_TRACE(name);
    const fs::path missing = dir / "no" / "such" / "folder" / name;
    EXPECT_THROW(write_snow_meshes(patches, missing, format_from_path(missing)), IOError);
    const fs::path folder = dir / (std::string(name) + ".d");
    fs::create_directories(folder / name);  // the target is a folder
    EXPECT_THROW(write_snow_meshes(patches, folder / name, format_from_path(name)), IOError);
    if (geteuid() != 0) {  // root writes anywhere
      const fs::path locked = dir / (std::string(name) + ".locked");
      fs::create_directories(locked);
      fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
      EXPECT_THROW(write_snow_meshes(patches, locked / name, format_from_path(name)), IOError);
      fs::permissions(locked, fs::perms::owner_all);
      EXPECT_TRUE(fs::is_empty(locked));
    }
  }
  // Nothing but the folders made above.
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    EXPECT_TRUE(entry.is_directory()) << entry.path();
  }
  EXPECT_THROW(combined_from(dir / "absent.gltf", patches, dir / "out.glb"), IOError);
  std::ofstream(dir / "garbage.gltf") << "{ not json";
  EXPECT_THROW(combined_from(dir / "garbage.gltf", patches, dir / "out.glb"), InputError);
  // Planned ahead, the input fails the same way.
  EXPECT_THROW(planned(dir / "absent.gltf"), IOError);
  EXPECT_THROW(planned(dir / "garbage.gltf"), InputError);
  EXPECT_FALSE(fs::exists(dir / "out.glb"));
}

/// A small input scene made here: a textured triangle (image in a PNG file
/// beside the .gltf), a camera, an animation and a material extension.
fs::path write_input_scene(const fs::path& folder, std::vector<unsigned char>* png) {
  const unsigned char pixels[2 * 2 * 3] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
  png->clear();
  stbi_write_png_to_func(
      [](void* ctx, void* data, int size) {
        auto* out = static_cast<std::vector<unsigned char>*>(ctx);
        out->insert(out->end(), static_cast<unsigned char*>(data),
                    static_cast<unsigned char*>(data) + size);
      },
      png, 2, 2, 3, pixels, 0);
  std::ofstream(folder / "checker.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(png->data()), std::streamsize(png->size()));

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.buffers.emplace_back();
  auto add = [&](const void* data, size_t size, int count, int type, int target,
                 std::vector<double> min = {}, std::vector<double> max = {}) {
    auto& bytes = model.buffers[0].data;
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = bytes.size();
    view.byteLength = size;
    view.target = target;
    bytes.insert(bytes.end(), static_cast<const unsigned char*>(data),
                 static_cast<const unsigned char*>(data) + size);
    model.bufferViews.push_back(view);
    tinygltf::Accessor a;
    a.bufferView = int(model.bufferViews.size()) - 1;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = type;
    a.count = size_t(count);
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    model.accessors.push_back(a);
    return int(model.accessors.size()) - 1;
  };
  const float positions[9] = {-2, 0, -2, 2, 0, -2, 0, 0, 2};
  const float uvs[6] = {0, 0, 1, 0, 0.5f, 1};
  const float times[2] = {0, 1};
  const float moves[6] = {0, 0, 0, 0, 0.5f, 0};
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.attributes["POSITION"] = add(positions, sizeof(positions), 3, TINYGLTF_TYPE_VEC3,
                                    TINYGLTF_TARGET_ARRAY_BUFFER, {-2, 0, -2}, {2, 0, 2});
  prim.attributes["TEXCOORD_0"] =
      add(uvs, sizeof(uvs), 3, TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER);
  prim.material = 0;
  tinygltf::Mesh mesh;
  mesh.name = "Ground";
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);

  tinygltf::Image image;
  image.name = "checker";
  image.uri = "checker.png";
  model.images.push_back(image);
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_NEAREST;
  model.samplers.push_back(sampler);
  tinygltf::Texture texture;
  texture.source = 0;
  texture.sampler = 0;
  model.textures.push_back(texture);
  tinygltf::Material material;
  material.name = "Checker";
  material.pbrMetallicRoughness.baseColorTexture.index = 0;
  material.emissiveFactor = {1, 1, 1};
  tinygltf::Value::Object strength;
  strength["emissiveStrength"] = tinygltf::Value(2.0);
  material.extensions["KHR_materials_emissive_strength"] = tinygltf::Value(strength);
  model.materials.push_back(material);
  model.extensionsUsed.push_back("KHR_materials_emissive_strength");

  tinygltf::Camera camera;
  camera.type = "perspective";
  camera.perspective.yfov = 0.8;
  camera.perspective.znear = 0.1;
  camera.perspective.zfar = 100;
  camera.perspective.aspectRatio = 1.5;
  model.cameras.push_back(camera);

  tinygltf::Node ground;
  ground.name = "Ground";
  ground.mesh = 0;
  tinygltf::Node eye;
  eye.name = "Eye";
  eye.camera = 0;
  eye.translation = {0, 2, 6};
  model.nodes = {ground, eye};
  tinygltf::Scene scene;
  scene.name = "World";
  scene.nodes = {0, 1};
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  tinygltf::Animation animation;
  animation.name = "Bob";
  tinygltf::AnimationSampler as;
  as.input = add(times, sizeof(times), 2, TINYGLTF_TYPE_SCALAR, 0, {0}, {1});
  as.output = add(moves, sizeof(moves), 2, TINYGLTF_TYPE_VEC3, 0);
  as.interpolation = "LINEAR";
  animation.samplers.push_back(as);
  tinygltf::AnimationChannel channel;
  channel.sampler = 0;
  channel.target_node = 0;
  channel.target_path = "translation";
  animation.channels.push_back(channel);
  model.animations.push_back(animation);

  const fs::path path = folder / "input.gltf";
  save_gltf(model, path);
  return path;
}

// save_gltf writes buffer 0 into the GLB itself (tinygltf's writer copies
// it first): the file is byte for byte what tinygltf writes, also with
// names that look like the JSON it patches, odd lengths that need padding,
// and a model without buffers.
TEST(Export, GlbIsTinygltfsGlbByteForByte) {
  const TestDir test_dir;
  const auto same_as_tinygltf = [&](const tinygltf::Model& model, const char* name) {
    SCOPED_TRACE(name);
    const fs::path ours = test_dir.path / (std::string(name) + ".glb");
    save_gltf(model, ours);
    std::ostringstream theirs;
    tinygltf::TinyGLTF writer;
    writer.SetImageWriter(nullptr, nullptr);
    ASSERT_TRUE(writer.WriteGltfSceneToStream(&model, theirs, true, true));
    std::ifstream in(ours, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(bytes.size(), theirs.str().size());
    EXPECT_TRUE(bytes == theirs.str());
  };
  TriMesh mesh;
  mesh.name = "x\"buffers\":[{\"byteLength\":0}],\\\"";
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}};
  mesh.normals = {{0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
  mesh.indices = {0, 2, 1};
  tinygltf::Model model;
  append_meshes(model, {mesh}, {snow_material()}, "\"buffers\":[{\"byteLength\":0");
  model.buffers[0].name = "buffers";
  {
    // The JSON tinygltf writes for it with buffer 0 emptied has the length
    // to set where the scanner finds it: the GLB is not tinygltf's own.
    tinygltf::Model emptied = model;
    emptied.buffers[0].data.clear();
    std::ostringstream glb;
    tinygltf::TinyGLTF writer;
    writer.SetImageWriter(nullptr, nullptr);
    ASSERT_TRUE(writer.WriteGltfSceneToStream(&emptied, glb, true, true));
    const std::string json = glb.str().substr(20);
    const size_t at = detail::empty_buffer0_length_at(json);
    ASSERT_NE(at, std::string::npos);
    EXPECT_EQ(json.compare(at - 25, 26, "\"buffers\":[{\"byteLength\":0"), 0);
    EXPECT_NE(json.find("byteLength\\\":0"), std::string::npos);  // the decoy names
  }
  same_as_tinygltf(model, "names");
  model.buffers[0].data.push_back(7);  // 1 to 3 bytes of BIN padding
  same_as_tinygltf(model, "padded");
  model.buffers.emplace_back();  // a second buffer, written by its URI
  model.buffers[1].uri = "other.bin";
  model.buffers[1].data = {1, 2, 3, 4};
  same_as_tinygltf(model, "two buffers");
  same_as_tinygltf(tinygltf::Model{}, "empty");
}

TEST(Export, Buffer0LengthIsFoundAtTheTopLevelOnly) {
  const auto at = [](const std::string& json) { return detail::empty_buffer0_length_at(json); };
  EXPECT_EQ(at(R"({"buffers":[{"byteLength":0}]})"), 26u);
  EXPECT_EQ(
      at(R"({"asset":{"a":"\"buffers\":[{\"byteLength\":0"},"buffers":[{"byteLength":0,"n":1}]})"),
      73u);
  EXPECT_EQ(at(R"({"extras":{"buffers":[{"byteLength":0}]}})"), std::string::npos);
  EXPECT_EQ(at(R"({"buffers":[{"byteLength":01}]})"), std::string::npos);
  EXPECT_EQ(at(R"({"buffers":[{"byteLength":0)"), std::string::npos);
  EXPECT_EQ(at(R"({"buffers":[]})"), std::string::npos);
  EXPECT_EQ(at(""), std::string::npos);
}

TEST(Export, CombinedKeepsTheInputAndEmbedsItsImages) {
  const auto patches = table_patches();
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  fs::create_directories(dir / "in");
  fs::create_directories(dir / "out");
  std::vector<unsigned char> png;
  const fs::path input = write_input_scene(dir / "in", &png);
  const tinygltf::Model before = load_gltf(input);
  expect_valid_gltf({input});

  for (const char* name : {"combined.glb", "combined.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path out = dir / "out" / name;
    combined_from(input, patches, out);
    const tinygltf::Model after = load_gltf(out);
    EXPECT_EQ(after.nodes.size(), before.nodes.size() + patches.size() + 1);
    EXPECT_EQ(after.meshes.size(), before.meshes.size() + patches.size());
    EXPECT_EQ(after.materials.size(), before.materials.size() + 1);
    EXPECT_EQ(after.textures.size(), before.textures.size());
    EXPECT_EQ(after.images.size(), before.images.size());
    EXPECT_EQ(after.samplers.size(), before.samplers.size());
    EXPECT_EQ(after.cameras.size(), before.cameras.size());
    EXPECT_EQ(after.animations.size(), before.animations.size());
    EXPECT_EQ(after.extensionsUsed, before.extensionsUsed);
    ASSERT_EQ(after.scenes.size(), 1u);
    EXPECT_EQ(after.scenes[0].name, "World");
    // The input's nodes come first, unchanged; the snow root is added.
    const auto& roots = after.scenes[0].nodes;
    ASSERT_EQ(roots.size(), 3u);
    EXPECT_EQ(after.nodes[size_t(roots[0])].name, "Ground");
    EXPECT_EQ(after.nodes[size_t(roots[1])].name, "Eye");
    EXPECT_EQ(after.nodes[1].translation, before.nodes[1].translation);
    EXPECT_EQ(after.nodes[size_t(roots[2])].name, "Snow");
    EXPECT_EQ(after.nodes[size_t(roots[2])].children.size(), patches.size());
    EXPECT_EQ(after.materials[0].name, "Checker");
    EXPECT_TRUE(after.materials[0].extensions.count("KHR_materials_emissive_strength"));
    EXPECT_EQ(after.animations[0].channels.at(0).target_path, "translation");
    // The image is embedded byte for byte.
    const tinygltf::Image& image = after.images[0];
    EXPECT_TRUE(image.uri.empty());
    ASSERT_GE(image.bufferView, 0);
    EXPECT_EQ(image.mimeType, "image/png");
    const tinygltf::BufferView& view = after.bufferViews[size_t(image.bufferView)];
    const auto& data = after.buffers[size_t(view.buffer)].data;
    ASSERT_EQ(view.byteLength, png.size());
    EXPECT_TRUE(std::equal(png.begin(), png.end(), data.begin() + long(view.byteOffset)));
  }
  // The output folder holds only what was written (no image files copied).
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(dir / "out")) files.insert(e.path().filename());
  EXPECT_EQ(files, (std::set<std::string>{"combined.glb", "combined.gltf", "combined.bin"}));
  expect_valid_gltf({dir / "out" / "combined.glb", dir / "out" / "combined.gltf"});
  // The input planned ahead (as the batch job does) gives the same file, and an
  // output that is not glTF is refused at the write.
  fs::create_directories(dir / "ahead");
  write_combined_gltf(planned(input), patches, dir / "ahead" / "combined.glb");
  const auto bytes = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(bytes(dir / "ahead" / "combined.glb"), bytes(dir / "out" / "combined.glb"));
  EXPECT_THROW(write_combined_gltf(planned(input), patches, dir / "ahead" / "x.obj"), InputError);
}

/// What the streamed-GLB tests start from: the table's patches, a test
/// folder, and the input scene written into it (write_input_scene).
struct CombinedSetup {
  std::vector<SnowPatch> patches = table_patches();
  TestDir test_dir;
  const fs::path& dir = test_dir.path;
  std::vector<unsigned char> png;
  fs::path input = write_input_scene(dir, &png);
};

/// The bytes of accessor `a` of `m` (its buffer view's range).
std::vector<unsigned char> accessor_bytes(const tinygltf::Model& m, const tinygltf::Accessor& a) {
  if (a.bufferView < 0) return {};
  const tinygltf::BufferView& v = m.bufferViews[size_t(a.bufferView)];
  const auto& data = m.buffers[size_t(v.buffer)].data;
  return {data.begin() + long(v.byteOffset), data.begin() + long(v.byteOffset + v.byteLength)};
}

/// Writes a GLB of `json` (its chunk padded with spaces; its declared length
/// `extra` bytes longer than it is) and, when not empty, a BIN chunk of `bin`.
void write_glb_file(const fs::path& path, std::string json, std::string bin, uint32_t extra = 0) {
  json.resize((json.size() + 3) & ~size_t(3), ' ');
  bin.resize((bin.size() + 3) & ~size_t(3), '\0');
  const auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  const size_t total = 20 + json.size() + (bin.empty() ? 0 : 8 + bin.size());
  std::ofstream out(path, std::ios::binary);
  out << "glTF" << u32(2) << u32(uint32_t(total)) << u32(uint32_t(json.size() + extra)) << "JSON"
      << json;
  if (!bin.empty()) out << u32(uint32_t(bin.size())) << std::string("BIN\0", 4) << bin;
}

/// The JSON chunk of a GLB.
nlohmann::json glb_json_of(const fs::path& path) {
  const std::string bytes = read_text(path);
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return nlohmann::json::parse(bytes.substr(20, length));
}

// Whatever the input's buffers are (a .gltf with a .bin, a .glb, a data
// URI, two buffers), the .glb output holds the same thing as the .gltf
// output of the first: every accessor's bytes, the images' bytes, the
// nodes and scenes. The input's JSON is kept as written: a top-level
// property that tinygltf would drop is still there (c.gltf, written by
// tinygltf, has lost it).
TEST(Export, CombinedGlbIsTheSameForEveryBufferLayout) {
  const CombinedSetup setup;
  const auto& [patches, test_dir, dir, png, gltf] = setup;
  nlohmann::json json = nlohmann::json::parse(read_text(gltf));
  json["x-kept"] = 1;
  const std::string bin = read_text(dir / "input.bin");
  // The inputs: a .gltf with a .bin, a .glb, a data URI, two buffers.
  std::ofstream(dir / "a.gltf") << json.dump();
  {
    nlohmann::json j = json;
    j["buffers"][0].erase("uri");
    write_glb_file(dir / "b.glb", j.dump(), bin);
  }
  {
    tinygltf::Model model = load_gltf(gltf);
    tinygltf::TinyGLTF writer;
    writer.SetImageWriter(nullptr, nullptr);
    ASSERT_TRUE(
        writer.WriteGltfSceneToFile(&model, (dir / "c.gltf").string(), false, true, true, false));
  }
  {
    nlohmann::json j = json;
    j["buffers"].push_back({{"uri", "input.bin"}, {"byteLength", bin.size()}});
    std::ofstream(dir / "d.gltf") << j.dump();
  }
  fs::create_directories(dir / "out");
  combined_from(gltf, patches, dir / "out" / "reference.gltf");
  const tinygltf::Model reference = load_gltf(dir / "out" / "reference.gltf");
  for (const auto& [input, kept] : std::vector<std::pair<std::string, bool>>{
           {"a.gltf", true}, {"b.glb", true}, {"c.gltf", false}, {"d.gltf", true}}) {
    SCOPED_TRACE(input);
    const fs::path out = dir / "out" / (fs::path(input).stem().string() + ".glb");
    write_combined_gltf(planned(dir / input), patches, out);
    EXPECT_EQ(glb_json_of(out).contains("x-kept"), kept);
    EXPECT_EQ(glb_json_of(out)["buffers"].size(), 1u);
    const tinygltf::Model m = load_gltf(out);
    ASSERT_EQ(m.accessors.size(), reference.accessors.size());
    for (size_t i = 0; i < m.accessors.size(); ++i) {
      EXPECT_EQ(m.accessors[i].count, reference.accessors[i].count) << "accessor " << i;
      EXPECT_EQ(accessor_bytes(m, m.accessors[i]),
                accessor_bytes(reference, reference.accessors[i]))
          << "accessor " << i;
    }
    ASSERT_EQ(m.images.size(), 1u);
    ASSERT_GE(m.images[0].bufferView, 0);
    const tinygltf::BufferView& view = m.bufferViews[size_t(m.images[0].bufferView)];
    EXPECT_EQ(std::vector<unsigned char>(
                  m.buffers[0].data.begin() + long(view.byteOffset),
                  m.buffers[0].data.begin() + long(view.byteOffset + view.byteLength)),
              png);
    EXPECT_EQ(m.images[0].mimeType, "image/png");
    ASSERT_EQ(m.nodes.size(), reference.nodes.size());
    for (size_t i = 0; i < m.nodes.size(); ++i) {
      EXPECT_EQ(m.nodes[i].name, reference.nodes[i].name);
      EXPECT_EQ(m.nodes[i].mesh, reference.nodes[i].mesh);
      EXPECT_EQ(m.nodes[i].children, reference.nodes[i].children);
    }
    ASSERT_EQ(m.scenes.size(), 1u);
    EXPECT_EQ(m.scenes[0].nodes, reference.scenes[0].nodes);
    EXPECT_EQ(m.materials.size(), reference.materials.size());
    EXPECT_EQ(m.meshes.size(), reference.meshes.size());
  }
  expect_valid_gltf(
      {dir / "out" / "a.glb", dir / "out" / "b.glb", dir / "out" / "c.glb", dir / "out" / "d.glb"});
}

// Inputs of odd shapes reach the combined writer only through the loader,
// which refuses most of them; each is written or refused with InputError,
// and no output is left half-written.
TEST(Export, CombinedGlbOfOddInputsIsWrittenOrRefused) {
  const CombinedSetup setup;
  const auto& [patches, test_dir, dir, png, gltf] = setup;
  const nlohmann::json good = nlohmann::json::parse(read_text(gltf));
  const auto variant = [&](const char* name, auto&& change) {
    nlohmann::json j = good;
    change(j);
    std::ofstream(dir / name) << j.dump();
    return dir / name;
  };
  std::vector<fs::path> inputs = {
      variant("scenes_object.gltf", [](auto& j) { j["scenes"] = 5; }),
      variant("scene_negative.gltf", [](auto& j) { j["scene"] = -1; }),
      variant("scene_too_big.gltf", [](auto& j) { j["scene"] = 99; }),
      variant("scene_nodes_string.gltf", [](auto& j) { j["scenes"][0]["nodes"] = "x"; }),
      variant("image_uri_number.gltf", [](auto& j) { j["images"][0]["uri"] = 7; }),
      variant("image_missing.gltf", [](auto& j) { j["images"][0]["uri"] = "absent.png"; }),
      variant("image_folder.gltf", [&](auto& j) { j["images"][0]["uri"] = "."; }),
      variant("image_unknown.gltf", [](auto& j) { j["images"][0]["uri"] = "input.bin"; }),
      variant("length_string.gltf", [](auto& j) { j["buffers"][0]["byteLength"] = "12"; }),
      variant("length_too_big.gltf", [](auto& j) { j["buffers"][0]["byteLength"] = 1 << 30; }),
      variant("buffer_outside.gltf", [](auto& j) { j["buffers"][0]["uri"] = "../x.bin"; }),
      variant("no_asset.gltf", [](auto& j) { j.erase("asset"); }),
      variant("no_scenes.gltf",
              [](auto& j) {
                j.erase("scenes");
                j.erase("scene");
              }),
  };
  // A GLB whose JSON chunk claims more bytes than the file holds.
  write_glb_file(dir / "short.glb", good.dump(), "", 64);
  inputs.push_back(dir / "short.glb");
  fs::create_directories(dir / "out");
  for (const fs::path& input : inputs) {
    SCOPED_TRACE(input.filename().string());
    const fs::path out = dir / "out" / "x.glb";
    fs::remove(out);
    try {
      write_combined_gltf(planned(input), patches, out);
      // Read back by snowmodel's loader (tinygltf would try to read an
      // image uri that names a folder, and run out of memory).
      LoadSettings settings;
      settings.load_images = false;
      const Scene scene = load_scene(out, settings);
      EXPECT_GT(scene.triangle_count(), 1u);
      EXPECT_EQ(glb_json_of(out)["nodes"].back()["name"], "Snow");
    } catch (const InputError& e) {
      std::printf("%s: %s\n", input.filename().c_str(), e.what());
      EXPECT_FALSE(fs::exists(out));
    }
    size_t files = 0;
    for (const auto& e : fs::directory_iterator(dir / "out")) files += e.path() != out;
    EXPECT_EQ(files, 0u) << "a temporary file was left";
  }
}

/// A deep nest of arrays: `levels` '[' then as many ']'.
std::string nested_arrays(size_t levels) {
  return std::string(levels, '[') + std::string(levels, ']');
}

// The combined writer takes the input as the loader read it, under the
// same input policy (scene/input_policy.h), to a .glb and to a .gltf.
TEST(Export, CombinedInputFollowsTheInputPolicy) {
  const CombinedSetup setup;
  const auto& [patches, test_dir, dir, png, gltf] = setup;
  const fs::path inner = dir / "inner";
  fs::create_directories(inner);
  fs::copy_file(dir / "input.bin", inner / "input.bin");
  fs::copy_file(dir / "checker.png", inner / "checker.png");
  fs::create_symlink(dir / "checker.png", inner / "link.png");
  fs::create_symlink(dir / "input.bin", inner / "link.bin");
  const nlohmann::json good = nlohmann::json::parse(read_text(gltf));
  const std::string bin = read_text(dir / "input.bin");
  struct Case {
    std::string name;
    std::function<void(nlohmann::json&)> change;
    std::string needle;
  };
  const std::vector<Case> cases = {
      {"image_dotdot", [](auto& j) { j["images"][0]["uri"] = "../checker.png"; }, "refused"},
      {"image_percent", [](auto& j) { j["images"][0]["uri"] = "%2e%2e/checker.png"; }, "refused"},
      {"image_absolute", [&](auto& j) { j["images"][0]["uri"] = (dir / "checker.png").string(); },
       "refused"},
      {"image_symlink", [](auto& j) { j["images"][0]["uri"] = "link.png"; }, "symlink"},
      {"buffer_symlink", [](auto& j) { j["buffers"][0]["uri"] = "link.bin"; }, "symlink"},
      {"deep_extras", [](auto& j) { j["extras"] = nlohmann::json::parse(nested_arrays(600)); },
       "JSON nested deeper than 512 levels"},
  };
  fs::create_directories(dir / "out");
  const fs::path out = dir / "out" / "x.glb";
  for (const Case& c : cases) {
    nlohmann::json j = good;
    c.change(j);
    const fs::path input = inner / (c.name + ".gltf");
    std::ofstream(input) << j.dump();
    for (const fs::path& to : {dir / "out" / "x.glb", dir / "out" / "x.gltf"}) {
      SCOPED_TRACE(c.name + " to " + to.filename().string());
      try {
        write_combined_gltf(planned(input), patches, to);
        ADD_FAILURE() << "not refused";
      } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find(c.needle), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
      }
      EXPECT_TRUE(fs::is_empty(dir / "out"));
      fs::remove_all(dir / "out");
      fs::create_directories(dir / "out");
    }
  }
  // JSON far deeper than any stack holds (tinygltf's parser recursed into it).
  const std::string deep = R"({"asset":{"version":"2.0"},"extras":)" + nested_arrays(30000) + "}";
  std::ofstream(inner / "deep.gltf") << deep;
  EXPECT_THROW(planned(inner / "deep.gltf"), InputError);
  write_glb_file(inner / "deep.glb", deep, bin);
  EXPECT_THROW(planned(inner / "deep.glb"), InputError);
  // A FIFO as the input is refused, not opened (which would wait for a writer).
  ASSERT_EQ(mkfifo((inner / "fifo.gltf").c_str(), 0600), 0);
  EXPECT_THROW(planned(inner / "fifo.gltf"), InputError);
}

// The input is read at the start of a run and its files copied at the end:
// a .bin that changed in between no longer matches the JSON read first, and
// the write says so instead of mixing the two.
// The usual Draco file (issue 48): its primitive's indices accessor has no
// bufferView, which tinygltf refuses ("accessor[1] invalid bufferView").
// Read by tinygltf (a data URI to a .glb; a .glb to a .gltf), the scene plus
// snow keeps the primitive and its indices.
TEST(Export, CombinedKeepsADracoPrimitiveWithIndices) {
#ifdef SNOW_TEST_DRACO_ENCODER
  if (!gltf_draco_supported()) GTEST_SKIP() << "this build has no Draco decoder";
  const fs::path dir = fs::temp_directory_path() / "snow_export_draco_indices";
  fs::remove_all(dir);
  fs::create_directories(dir / "out");
  test::Gltf g = test::draco_quad_gltf(true);
  const std::vector<SnowPatch> no_snow;
  for (const auto& [input, out] : std::vector<std::pair<fs::path, fs::path>>{
           {g.write_data_uri(dir, "data"), dir / "out" / "data.glb"},
           {g.write_glb(dir, "binary"), dir / "out" / "binary.gltf"}}) {
    SCOPED_TRACE(input.string());
    ASSERT_NO_THROW(combined_from(input, no_snow, out));
    const Scene s = load_scene(out);
    EXPECT_EQ(s.triangle_count(), 2u);
    const nlohmann::json json =
        out.extension() == ".glb" ? glb_json_of(out) : nlohmann::json::parse(read_text(out));
    EXPECT_EQ(json["meshes"][0]["primitives"][0]["indices"], 1) << json.dump();
    EXPECT_FALSE(json["accessors"][1].contains("bufferView")) << json.dump();
  }
  fs::remove_all(dir);
#else
  GTEST_SKIP() << "Draco encoder headers not available";
#endif
}

// A whole number beyond int (a texCoord of 2^31) is kept as the input has
// it, whatever its buffers (a .bin, a data URI) and the output (.glb,
// .gltf): the input's JSON is copied, never written changed (issue 48).
TEST(Export, CombinedKeepsAWholeNumberBeyondInt) {
  const fs::path dir = fs::temp_directory_path() / "snow_export_wide_texcoord";
  fs::remove_all(dir);
  fs::create_directories(dir / "out");
  test::Gltf g = test::triangle_gltf();
  g.doc["textures"] = nlohmann::json::array({nlohmann::json::object()});
  g.doc["materials"] = {{{"pbrMetallicRoughness",
                          {{"baseColorTexture", {{"index", 0}, {"texCoord", 2147483648u}}}}}}};
  g.doc["meshes"][0]["primitives"][0]["material"] = 0;
  g.scene({g.node({{"mesh", 0}})});
  const std::vector<SnowPatch> no_snow;
  for (const fs::path& input : {g.write_gltf(dir, "bin"), g.write_data_uri(dir, "data")}) {
    for (const char* name : {"kept.glb", "kept.gltf"}) {
      SCOPED_TRACE(input.filename().string() + " to " + name);
      const fs::path out = dir / "out" / name;
      combined_from(input, no_snow, out);
      const nlohmann::json json =
          out.extension() == ".glb" ? glb_json_of(out) : nlohmann::json::parse(read_text(out));
      EXPECT_EQ(json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"],
                2147483648u)
          << json.dump();
    }
  }
  fs::remove_all(dir);
}

TEST(Export, CombinedGlbRefusesAnInputThatChangedMeanwhile) {
  const CombinedSetup setup;
  const auto& [patches, test_dir, dir, png, input] = setup;
  fs::create_directories(dir / "out");
  const fs::path out = dir / "out" / "x.glb";
  CombinedInputPtr ahead = planned(input);
  std::ofstream(dir / "input.bin", std::ios::binary | std::ios::app) << "more";
  try {
    write_combined_gltf(std::move(ahead), patches, out);
    ADD_FAILURE() << "a changed input was written";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("input.bin changed while snowmodel ran"),
              std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(fs::is_empty(dir / "out"));
}

TEST(Export, CombinedToyCarKeepsItsCounts) {
  const fs::path input = fs::path(SNOW_SHARED_SCENES) / "khronos" / "ToyCar" / "ToyCar.gltf";
  if (!fs::exists(input)) GTEST_SKIP() << input << " is absent";
  const auto patches = table_patches();
  const TestDir test_dir;
  const fs::path& dir = test_dir.path;
  const tinygltf::Model before = load_gltf(input);
  for (const char* name : {"toycar_snow.glb", "toycar_snow.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path out = dir / name;
    combined_from(input, patches, out);
    const tinygltf::Model after = load_gltf(out);
    EXPECT_EQ(after.nodes.size(), before.nodes.size() + patches.size() + 1);
    EXPECT_EQ(after.meshes.size(), before.meshes.size() + patches.size());
    EXPECT_EQ(after.materials.size(), before.materials.size() + 1);
    EXPECT_EQ(after.textures.size(), before.textures.size());
    EXPECT_EQ(after.images.size(), before.images.size());
    EXPECT_EQ(after.cameras.size(), before.cameras.size());
    EXPECT_EQ(after.animations.size(), before.animations.size());
    EXPECT_EQ(after.extensionsUsed, before.extensionsUsed);
    for (const auto& image : after.images) {
      EXPECT_TRUE(image.uri.empty());
      EXPECT_GE(image.bufferView, 0);
    }
    std::printf(
        "%s: %zu nodes, %zu meshes, %zu materials, %zu textures, %zu cameras "
        "(input: %zu, %zu, %zu, %zu, %zu)\n",
        name, after.nodes.size(), after.meshes.size(), after.materials.size(),
        after.textures.size(), after.cameras.size(), before.nodes.size(), before.meshes.size(),
        before.materials.size(), before.textures.size(), before.cameras.size());
  }
  expect_valid_gltf({dir / "toycar_snow.glb", dir / "toycar_snow.gltf"});
}

}  // namespace
}  // namespace snow

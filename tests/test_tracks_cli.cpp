// `snowmodel snow --track / --clear` end to end (issue 56): an animated box
// leaves a trail that survives --resume and that later snow fills partly, a
// glTF line clears a path, the meshes stay closed, and options that do not
// go together are one-line errors.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "mesh/gltf_writer.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "support/command.h"
#include "support/exr.h"

namespace snow {
namespace {
namespace fs = std::filesystem;

const std::string kFast = " --max-side 128 --directions 8";

test::CommandResult run(const std::string& args) { return test::run_snowmodel(args); }

std::string q(const fs::path& p) { return test::quoted(p); }

/// Appends `values` to buffer 0 as an accessor of `count` elements of `type`.
int add_floats(tinygltf::Model& m, const std::vector<float>& values, int type, size_t count) {
  std::vector<unsigned char>& data = m.buffers[0].data;
  while (data.size() % 4) data.push_back(0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = values.size() * sizeof(float);
  data.resize(data.size() + view.byteLength);
  std::memcpy(data.data() + view.byteOffset, values.data(), view.byteLength);
  m.bufferViews.push_back(view);
  tinygltf::Accessor a;
  a.bufferView = int(m.bufferViews.size() - 1);
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.type = type;
  a.count = count;
  if (type == TINYGLTF_TYPE_SCALAR) {
    a.minValues = {*std::min_element(values.begin(), values.end())};
    a.maxValues = {*std::max_element(values.begin(), values.end())};
  } else {
    a.minValues = {-1e9, -1e9, -1e9};
    a.maxValues = {1e9, 1e9, 1e9};
  }
  m.accessors.push_back(a);
  return int(m.accessors.size() - 1);
}

int node_named(const tinygltf::Model& m, const std::string& name) {
  for (size_t n = 0; n < m.nodes.size(); ++n) {
    if (m.nodes[n].name == name) return int(n);
  }
  return -1;
}

/// A 12 m yard with a sled (a box) that an animation pulls 6 m along +x in
/// 3 s, and a glTF line "Path" across the yard along z at x = 3.
fs::path save_yard(const fs::path& dir) {
  SceneBuilder b;
  b.add_plane("Yard", 0.0f, {-6.0f, -6.0f}, {6.0f, 6.0f});
  b.add_box("Sled", {-4.3f, 0.0f, -0.5f}, {-3.7f, 0.3f, 0.5f});
  tinygltf::Model model;
  append_meshes(model, b.meshes(), b.materials(), "Yard");
  const int sled = node_named(model, "Sled");
  EXPECT_GE(sled, 0);
  tinygltf::Animation pull;
  tinygltf::AnimationSampler sampler;
  sampler.input = add_floats(model, {0.0f, 3.0f}, TINYGLTF_TYPE_SCALAR, 2);
  sampler.output = add_floats(model, {0, 0, 0, 6, 0, 0}, TINYGLTF_TYPE_VEC3, 2);
  sampler.interpolation = "LINEAR";
  pull.samplers.push_back(sampler);
  tinygltf::AnimationChannel channel;
  channel.sampler = 0;
  channel.target_node = sled;
  channel.target_path = "translation";
  pull.channels.push_back(channel);
  pull.name = "Pull";
  model.animations.push_back(pull);
  // The path: a line strip across the yard.
  tinygltf::Mesh line;
  line.name = "Path";
  tinygltf::Primitive strip;
  strip.mode = TINYGLTF_MODE_LINE_STRIP;
  strip.attributes["POSITION"] =
      add_floats(model, {3.0f, 0.0f, -5.0f, 3.0f, 0.0f, 5.0f}, TINYGLTF_TYPE_VEC3, 2);
  line.primitives.push_back(strip);
  model.meshes.push_back(line);
  tinygltf::Node node;
  node.name = "Path";
  node.mesh = int(model.meshes.size() - 1);
  model.nodes.push_back(node);
  model.scenes[0].nodes.push_back(int(model.nodes.size() - 1));
  model.buffers[0].uri.clear();
  const fs::path path = dir / "yard.glb";
  save_gltf(model, path);
  return path;
}

/// `hours` hours of snow, 2 mm of water an hour at -5 C, from `from`.
fs::path save_snowfall(const fs::path& path, int from, int hours) {
  std::ofstream out(path);
  out << "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud\n";
  for (int h = from; h < from + hours; ++h) out << h << ",2,-5,0,0,1\n";
  return path;
}

std::vector<float> layer0(const fs::path& maps, const std::string& kind) {
  int w = 0, h = 0;
  return test::read_exr(maps / ("layer0_" + kind + ".exr"), &w, &h);
}

/// Mean of `values` where `mask(k)`.
template <class Mask>
double mean(const std::vector<float>& values, Mask mask) {
  double sum = 0.0;
  size_t n = 0;
  for (size_t k = 0; k < values.size(); ++k) {
    if (mask(k)) sum += double(values[k]), ++n;
  }
  return n ? sum / double(n) : 0.0;
}

TEST(TracksCli, AnAnimatedSledLeavesATrailThatLaterSnowFillsPartly) {
  const fs::path dir = test::fresh_dir("snow_tracks", "sled");
  const fs::path scene = save_yard(dir);
  const test::CommandResult first =
      run("snow " + q(scene) + " -o " + q(dir / "first.glb") + " --maps " + q(dir / "first") +
          " --weather " + q(save_snowfall(dir / "first.csv", 0, 12)) + " --track Sled" + kFast);
  ASSERT_EQ(first.code, 0) << first.output;
  EXPECT_NE(first.output.find("tracks: 1 source(s)"), std::string::npos) << first.output;
  const std::vector<float> compaction = layer0(dir / "first", "compaction");
  const std::vector<float> before = layer0(dir / "first", "depth");
  const auto trail = [&](size_t k) { return compaction[k] > 0.3f; };
  const auto open = [&](size_t k) { return compaction[k] == 0.0f && before[k] > 0.0f; };
  size_t trail_texels = 0;
  for (size_t k = 0; k < compaction.size(); ++k) trail_texels += trail(k);
  // The sled's 1 m wide, 6 m long path at 12 / 128 m texels.
  const double texel = 12.0 / 128.0;
  EXPECT_GT(double(trail_texels) * texel * texel, 0.7 * 6.0 * 1.0);
  const double step_before = mean(before, open) - mean(before, trail);
  std::printf("trail: %zu texels; open snow %.3f m, trail %.3f m\n", trail_texels,
              mean(before, open), mean(before, trail));
  EXPECT_GT(step_before, 0.03);

  // Six more hours of snow on the resumed pack, no --track: the trail is
  // still there, with new snow in it, and shallower against its sides.
  const test::CommandResult second =
      run("snow " + q(scene) + " -o " + q(dir / "second.glb") + " --maps " + q(dir / "second") +
          " --resume " + q(dir / "first") + " --weather " +
          q(save_snowfall(dir / "second.csv", 12, 6)) + kFast);
  ASSERT_EQ(second.code, 0) << second.output;
  const std::vector<float> after = layer0(dir / "second", "depth");
  const double step_after = mean(after, open) - mean(after, trail);
  std::printf("after: open %.3f m, trail %.3f m\n", mean(after, open), mean(after, trail));
  EXPECT_GT(mean(after, trail), mean(before, trail) + 0.02);  // new snow lies in the trail
  EXPECT_GT(step_after, 0.0);                                 // the trail still shows
  EXPECT_LT(step_after, step_before);                         // partly filled
  // The snow meshes with the trail are closed.
  const Scene snow = load_scene(dir / "second.glb");
  for (int o = 0; o < int(snow.objects.size()); ++o) {
    if (snow.objects[size_t(o)].name.rfind("snow", 0) != 0) continue;
    const TopologyReport t = check_object_topology(snow, o);
    EXPECT_TRUE(t.closed()) << snow.objects[size_t(o)].name;
  }
  fs::remove_all(dir);
}

// A weather sequence with the sled pulled at hour 6: the frame at hour 6
// shows the trail, the frame at hour 12 the trail with six hours of snow in
// it.
TEST(TracksCli, ASequenceShowsTheTrailFillingAfterTheTrackHour) {
  const fs::path dir = test::fresh_dir("snow_tracks", "sequence");
  const fs::path scene = save_yard(dir);
  const test::CommandResult r =
      run("snow " + q(scene) + " --maps " + q(dir / "maps") + " --weather " +
          q(save_snowfall(dir / "snow.csv", 0, 12)) + " --track Sled --track-hour 6 --sequence " +
          q(dir / "frames") + " --every 6 --sequence-maps" + kFast);
  ASSERT_EQ(r.code, 0) << r.output;
  const std::vector<float> compaction = layer0(dir / "maps", "compaction");
  const std::vector<float> at6 = layer0(dir / "frames" / "maps_0001", "depth");
  const std::vector<float> at12 = layer0(dir / "frames" / "maps_0002", "depth");
  const auto trail = [&](size_t k) { return compaction[k] > 0.3f; };
  const auto open = [&](size_t k) { return compaction[k] == 0.0f && at6[k] > 0.0f; };
  ASSERT_GT(mean(at6, open) - mean(at6, trail), 0.03);  // made at hour 6
  EXPECT_GT(mean(at12, trail), mean(at6, trail) + 0.02);
  EXPECT_LT(mean(at12, open) - mean(at12, trail), mean(at6, open) - mean(at6, trail));
  fs::remove_all(dir);
}

TEST(TracksCli, ALineClearsAPathAndTheSnowGoesBesideIt) {
  const fs::path dir = test::fresh_dir("snow_tracks", "path");
  const fs::path scene = save_yard(dir);
  const std::string common = " --depth 0.3 --ignore Sled" + kFast;
  const test::CommandResult plain =
      run("snow " + q(scene) + " --maps " + q(dir / "plain") + common);
  ASSERT_EQ(plain.code, 0) << plain.output;
  const test::CommandResult cleared =
      run("snow " + q(scene) + " -o " + q(dir / "cleared.glb") + " --maps " + q(dir / "cleared") +
          common + " --clear Path --track-width 1");
  ASSERT_EQ(cleared.code, 0) << cleared.output;
  const std::vector<float> compaction = layer0(dir / "cleared", "compaction");
  const std::vector<float> depth = layer0(dir / "cleared", "depth");
  const std::vector<float> was = layer0(dir / "plain", "depth");
  double total = 0.0, total_was = 0.0;
  size_t path = 0;
  for (size_t k = 0; k < depth.size(); ++k) {
    total += double(depth[k]), total_was += double(was[k]);
    if (compaction[k] == 1.0f) {
      ++path;
      EXPECT_EQ(depth[k], 0.0f);
    }
  }
  // A 1 m path, 10 m long, at 12 / 128 m texels.
  const double texel = 12.0 / 128.0;
  EXPECT_NEAR(double(path) * texel * texel, 10.0, 2.5);
  // Same settled density everywhere: what was cleared lies beside the path.
  EXPECT_NEAR(total, total_was, 1e-4 * total_was);
  const Scene snow = load_scene(dir / "cleared.glb");
  for (int o = 0; o < int(snow.objects.size()); ++o) {
    if (snow.objects[size_t(o)].name.rfind("snow", 0) != 0) continue;
    EXPECT_TRUE(check_object_topology(snow, o).closed()) << snow.objects[size_t(o)].name;
  }
  fs::remove_all(dir);
}

// The headless preview presses the sled's trail at its last frame and
// exports it: the exported snow has the trail's compacted floor.
TEST(TracksCli, ThePreviewPressesTheTracks) {
  const fs::path dir = test::fresh_dir("snow_tracks", "preview");
  const fs::path scene = save_yard(dir);
  const test::CommandResult r =
      run("preview " + q(scene) + " --headless --frames 12 --size 320x200 --track Sled --maps " +
          q(dir / "maps") + " --max-side 128 --directions 8 --fall-rate 2");
  if (r.code == 3) GTEST_SKIP() << "no OpenGL: " << r.output;
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("tracks: "), std::string::npos) << r.output;
  const std::vector<float> depth = layer0(dir / "maps", "depth");
  // The trail's middle against the open yard beside it (12 m over 128 texels).
  const auto at = [&](float x, float z) {
    return depth[size_t((z + 6.0f) / 12.0f * 128.0f) * 128 + size_t((x + 6.0f) / 12.0f * 128.0f)];
  };
  EXPECT_LT(at(0.0f, 0.0f), at(0.0f, 2.0f) - 0.05f);
  fs::remove_all(dir);
}

TEST(TracksCli, OptionsThatDoNotGoTogetherAreOneLineErrors) {
  const fs::path dir = test::fresh_dir("snow_tracks", "errors");
  const fs::path scene = save_yard(dir);
  const struct {
    std::string args, says;
  } cases[] = {
      {" --track Sled --track-hour 3", "--track-hour needs --weather"},
      {" --track Sled --track-hour 30 --weather " + q(save_snowfall(dir / "w.csv", 0, 12)),
       "--track-hour 30 is after the weather's end (hour 12)"},
      {" --track 'Sl*' --clear Sled", "both name 'Sled'"},
      {" --track Sled --tiles 2x2 --tile 0 --tile-dir " + q(dir / "tiles"), "--tiles and --track"},
  };
  for (const auto& c : cases) {
    const test::CommandResult r =
        run("snow " + q(scene) + " -o " + q(dir / "out.glb") + c.args + kFast);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir / "out.glb"));
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace snow

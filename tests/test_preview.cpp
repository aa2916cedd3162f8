// The live preview (`snowmodel preview`, src/live) run as a script: N frames
// on the bundled courtyard, headless and in a window under a virtual X
// server (the ctest entry test_preview_xvfb runs this binary under
// xvfb-run), then its screenshot is checked at world points projected with
// the same camera: snow-white on the roof and on open ground, none under the
// table; and the headless preview's snow against the batch job's.
#include <gtest/gtest.h>
#include <stb_image.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "core/error.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "live/live_sim.h"
#include "live/orbit.h"
#include "live/snow_view.h"
#include "plan/machine.h"
#include "render/camera.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "support/command.h"
#include "support/exr.h"
#include "support/gl_context.h"
#include "support/gltf_scene.h"
#include "support/stabilize_maps.h"

namespace snow {
namespace {

namespace fs = std::filesystem;

const fs::path kCourtyard = fs::path(SNOW_SOURCE_DIR) / "assets/scenes/courtyard.glb";

bool has_display() {
  const char* display = std::getenv("DISPLAY");
  return display && *display;
}

snow::test::CommandResult run_snowmodel(const std::string& args) {
  return snow::test::run_command(std::string(SNOWMODEL_EXE) + " " + args);
}

struct Picture {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
  glm::ivec3 at(int x, int y) const {
    const uint8_t* p = rgb.data() + (size_t(y) * size_t(width) + size_t(x)) * 3;
    return glm::ivec3(p[0], p[1], p[2]);
  }
};

Picture load_png(const fs::path& path) {
  Picture picture;
  int channels = 0;
  unsigned char* data = stbi_load(path.c_str(), &picture.width, &picture.height, &channels, 3);
  if (!data) return picture;
  picture.rgb.assign(data, data + size_t(picture.width) * size_t(picture.height) * 3);
  stbi_image_free(data);
  return picture;
}

/// Lit snow: bright and neutral or bluish (the courtyard's plaster, the
/// brightest other material, is yellowish).
bool snow_white(const glm::ivec3& c) {
  return c.r >= 175 && c.g >= 175 && c.b >= 175 && c.b >= c.r - 6;
}

/// Share of snow-white pixels in the (2r+1)^2 square around pixel p.
double white_share(const Picture& picture, const glm::ivec2& p, int r) {
  int white = 0, total = 0;
  for (int y = p.y - r; y <= p.y + r; ++y) {
    for (int x = p.x - r; x <= p.x + r; ++x) {
      if (x < 0 || y < 0 || x >= picture.width || y >= picture.height) continue;
      ++total;
      white += snow_white(picture.at(x, y));
    }
  }
  return total ? double(white) / double(total) : 0.0;
}

/// Pixel (x right, y down) of world point `p` for `camera` in a w x h image.
glm::ivec2 project(const render::PreviewCamera& camera, const glm::vec3& p, int w, int h) {
  const glm::vec4 clip = camera.view_projection() * glm::vec4(p, 1.0f);
  const glm::vec2 ndc = glm::vec2(clip) / clip.w;
  return glm::ivec2(int((ndc.x * 0.5f + 0.5f) * float(w)), int((0.5f - ndc.y * 0.5f) * float(h)));
}

TEST(OrbitView, StartsAsTheRenderOrbitCameraAndMoves) {
  Bounds bounds;
  bounds.extend(glm::vec3(-3, 0, -2));
  bounds.extend(glm::vec3(5, 4, 6));
  live::OrbitView view;
  view.azimuth = 30;
  view.elevation = 25;
  view.frame(bounds, 1.5f);
  const render::PreviewCamera a = view.camera(bounds, 1.5f);
  const render::PreviewCamera b = render::orbit_camera(bounds, 30, 25, 1.5f, 35.0f, view.margin);
  EXPECT_LT(glm::length(a.eye - b.eye), 1e-4f);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_NEAR(a.view[c][r], b.view[c][r], 1e-4f);
  const float d = view.distance;
  view.zoom(1);
  EXPECT_NEAR(view.distance, 0.9f * d, 1e-4f);
  view.orbit(100, 1000);  // clamps the elevation
  EXPECT_LE(view.elevation, 89.0f);
  const glm::vec3 target = view.target;
  view.pan(10, 0, 800);
  EXPECT_GT(glm::length(view.target - target), 0.0f);
  EXPECT_NEAR(view.target.y, target.y, 1e-4f);  // looking down steeply, a sideways pan stays level
  view.top = true;
  EXPECT_TRUE(view.camera(bounds, 1.5f).orthographic);
}

TEST(SnowView, AutoStrideKeepsTheDrawnGridSmall) {
  EXPECT_EQ(live::auto_stride(512, 300), 1);
  EXPECT_EQ(live::auto_stride(768, 768), 1);
  EXPECT_EQ(live::auto_stride(1024, 1024), 2);
  EXPECT_EQ(live::auto_stride(4096, 100), 6);
}

/// A camera at `eye` looking at `target` (perspective, 35 degrees).
render::PreviewCamera look_at(const glm::vec3& eye, const glm::vec3& target) {
  render::PreviewCamera camera;
  camera.eye = eye;
  camera.forward = glm::normalize(target - eye);
  camera.view = glm::lookAt(eye, target, glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(35.0f), 1.6f, 0.1f, 1000.0f);
  return camera;
}

// The snow grid's levels of detail: a 100 m flat field of 0.25 m texels
// seen from 300 m off is drawn with far fewer triangles than its finest
// level, looking away none, and seen from 2 m above one edge with more than
// from afar (the chunks near the eye fine) but fewer than all (the chunks
// behind the eye and beside the view left out).
TEST(SnowView, DrawsChunksInViewAtTheirLevelOfDetail) {
  REQUIRE_GL();
  MapGrid grid;
  grid.origin = glm::vec2(-50.0f);
  grid.texel = 0.25f;
  grid.width = grid.height = 400;
  SnowMaps maps;
  maps.allocate(grid, 1);
  std::fill(maps.ground.begin(), maps.ground.end(), 0.0f);
  live::SnowView view;
  view.set_maps(maps, 1);
  const size_t finest = view.triangle_count();
  EXPECT_GE(finest, size_t(2 * 399 * 399));  // quads plus skirts
  const gl::Texture depth =
      gl::create_texture_2d_array(GL_RG32F, grid.width, grid.height, 1, "test depth");
  // A framebuffer to draw into (a surfaceless context has none).
  const gl::Renderbuffer color = gl::create_renderbuffer(),
                         depth_buffer = gl::create_renderbuffer();
  glNamedRenderbufferStorage(color.id(), GL_RGBA8, 1280, 800);
  glNamedRenderbufferStorage(depth_buffer.id(), GL_DEPTH_COMPONENT32F, 1280, 800);
  const gl::Framebuffer fbo = gl::create_framebuffer();
  glNamedFramebufferRenderbuffer(fbo.id(), GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color.id());
  glNamedFramebufferRenderbuffer(fbo.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_buffer.id());
  glBindFramebuffer(GL_FRAMEBUFFER, fbo.id());
  glViewport(0, 0, 1280, 800);
  live::SnowViewSettings settings;
  settings.quad_pixels = 4.0f;
  const render::PreviewSettings shading;
  auto drawn = [&](const render::PreviewCamera& camera) {
    view.draw(camera, 800, shading, depth.id(), 1.0f, settings);
    return view.drawn_triangles();
  };
  const size_t far = drawn(look_at(glm::vec3(0, 300, 300), glm::vec3(0)));
  const size_t away = drawn(look_at(glm::vec3(0, 10, 60), glm::vec3(0, 10, 200)));
  const size_t close = drawn(look_at(glm::vec3(0, 2, 48), glm::vec3(0, 0, 40)));
  std::printf("triangles: finest %zu, far %zu, looking away %zu, close %zu\n", finest, far, away,
              close);
  EXPECT_LT(far, finest / 8);
  EXPECT_EQ(away, 0u);
  EXPECT_GT(close, far);
  EXPECT_LT(close, finest);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

// Live snowfall on the table scene's small maps: 0.2 m in 4 frames (0.05 m
// per frame).
live::LiveSettings table_live_settings(int passes_per_frame) {
  live::LiveSettings settings;
  settings.peel.max_side = 64;
  settings.peel.layers = 4;
  settings.coverage.directions = 16;
  settings.total_depth = 0.2f;
  settings.fall_rate = 1.5f;
  settings.passes_per_frame = passes_per_frame;
  return settings;
}

// The live snowfall with the stabilizer on the GPU and on the CPU: the same
// snow frame by frame within the backends' tolerance (1 mm per texel, 0.1 %
// of the volume), and the CPU's depth uploaded into the texture the snow is
// drawn from.
TEST(LiveSim, CpuAndGpuStabilizersGiveTheSameSnow) {
  auto context = gl::create_context();
  const Scene scene = make_table_scene(0.75f, 1.0f, 4.0f);
  live::LiveSettings settings = table_live_settings(8);
  settings.stabilize.device = "gpu";
  live::LiveSim gpu(scene, settings, plan::current_gl());
  settings.stabilize.device = "cpu";
  live::LiveSim cpu(scene, settings, plan::current_gl());
  EXPECT_FALSE(gpu.stabilizes_on_cpu());
  EXPECT_TRUE(cpu.stabilizes_on_cpu());
  for (int f = 0; f < 10; ++f) {
    gpu.step();
    cpu.step();
    SCOPED_TRACE(f);
    test::expect_agree(gpu.maps(), gpu.depth(), cpu.depth());
  }
  EXPECT_NEAR(gpu.lost_volume(), cpu.lost_volume(),
              test::kBackendVolumeTolerance * cpu.fallen_volume());
  const std::vector<float> depth = cpu.depth();
  std::vector<float> drawn(depth.size(), -1.0f);
  glGetTextureImage(cpu.depth_texture(), 0, GL_RED, GL_FLOAT, GLsizei(drawn.size() * sizeof(float)),
                    drawn.data());
  EXPECT_EQ(drawn, depth);
  // Switching the device keeps the snow.
  settings.stabilize.device = "gpu";
  cpu.apply(settings);
  EXPECT_FALSE(cpu.stabilizes_on_cpu());
  EXPECT_EQ(cpu.depth(), depth);
}

// Wind in the live snowfall: a 2 m cube in a field, 0.3 m of snow in 6
// frames with the panel's wind of 8 m/s along +x. Drifts form while it
// snows (more lies behind the cube than in the open after the first frames,
// and more than without the wind's transport), mass is conserved (lying +
// lost = fallen, the wind's in and out included), and turning the wind off
// in the panel keeps the snow.
TEST(LiveSim, WindBuildsDriftsWhileItSnows) {
  auto context = gl::create_context();
  SceneBuilder b;
  b.add_plane("Field", 0.0f, glm::vec2(-8.0f, -6.0f), glm::vec2(12.0f, 6.0f));
  b.add_box("Cube", glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 2.0f, 1.0f));
  const Scene scene = b.build();
  live::LiveSettings settings;
  settings.peel.max_side = 200;
  settings.peel.margin = 0.0f;
  settings.coverage.directions = 16;
  settings.coverage.wind = glm::vec2(8.0f, 0.0f);
  settings.total_depth = 0.3f;
  settings.fall_rate = 1.5f;  // 0.05 m per frame
  settings.passes_per_frame = 64;
  live::LiveSim sim(scene, settings, plan::current_gl());
  settings.wind_transport = false;
  live::LiveSim still(scene, settings, plan::current_gl());
  const SnowMaps& maps = sim.maps();
  const auto at = [&](const std::vector<float>& depth, float x, float z) {
    const int i = int((x - maps.grid.origin.x) / maps.grid.texel);
    const int j = int((z - maps.grid.origin.y) / maps.grid.texel);
    return depth[maps.index(0, i, j)];
  };
  const auto lee = [&](const std::vector<float>& depth) {
    float most = 0.0f;
    for (float x = 1.5f; x < 6.0f; x += maps.grid.texel) most = std::max(most, at(depth, x, 0.05f));
    return most;
  };
  for (int f = 0; f < 6; ++f) {
    sim.step();
    still.step();
    if (f == 2) {
      EXPECT_GT(lee(sim.depth()), at(sim.depth(), -6.0f, 4.0f)) << "frame " << f;
    }
  }
  const std::vector<float> depth = sim.depth();
  std::printf("after 0.3 m: lee peak %.3f m (no transport %.3f m), open field %.3f m\n",
              double(lee(depth)), double(lee(still.depth())), double(at(depth, -6.0f, 4.0f)));
  EXPECT_GT(lee(depth), 1.3f * 0.3f);
  EXPECT_GT(lee(depth), lee(still.depth()) + 0.1f);
  const double lying = snow_volume(maps, depth);
  EXPECT_NEAR(lying + sim.lost_volume(), sim.fallen_volume(), 1e-4 * sim.fallen_volume());
  live::LiveSettings calm = sim.settings();
  calm.coverage.wind = glm::vec2(0.0f);
  sim.apply(calm);
  EXPECT_NEAR(snow_volume(maps, sim.depth()), lying, 1e-4 * lying);
}

// The live snowfall on a table (headless context): snow accumulates frame
// by frame, mass is conserved (lying + lost = fallen), none lies under the
// table, and the panel's changes (repose, coverage, re-peel) keep a
// consistent state.
TEST(LiveSim, TableSnowfallConservesMassAndShelters) {
  auto context = gl::create_context();
  const Scene scene = make_table_scene(0.75f, 1.0f, 4.0f);
  const live::LiveSettings settings = table_live_settings(32);
  live::LiveSim sim(scene, settings, plan::current_gl());
  const SnowMaps& maps = sim.maps();
  for (int f = 0; f < 12; ++f) sim.step();
  EXPECT_EQ(sim.frame(), 12);
  EXPECT_FLOAT_EQ(sim.fallen_depth(), 0.2f);
  const std::vector<float> depth = sim.depth();
  const double lying = snow_volume(maps, depth), lost = sim.lost_volume();
  EXPECT_GT(sim.fallen_volume(), 0.5 * 16 * 0.2);
  EXPECT_NEAR(lying + lost, sim.fallen_volume(), 1e-3 * sim.fallen_volume());
  // Under the table's middle: the floor (lowest layer with a surface) is bare;
  // open floor far from the table carries about the fallen depth.
  const int ci = int((0.0f - maps.grid.origin.x) / maps.grid.texel);
  const int cj = int((0.0f - maps.grid.origin.y) / maps.grid.texel);
  int floor_layer = -1;
  for (int l = 0; l < maps.layers; ++l)
    if (maps.has_surface(l, ci, cj)) floor_layer = l;
  ASSERT_GE(floor_layer, 1);
  EXPECT_LT(depth[maps.index(floor_layer, ci, cj)], 1e-3f);
  const int oi = int((1.7f - maps.grid.origin.x) / maps.grid.texel);
  EXPECT_NEAR(depth[maps.index(0, oi, cj)], 0.2f, 0.03f);

  // Repose change: the snow is kept. Coverage change: recomputed.
  live::LiveSettings changed = settings;
  changed.stabilize.repose_deg = 35.0f;
  const uint64_t coverage_version = sim.coverage_version();
  sim.apply(changed);
  EXPECT_NEAR(snow_volume(maps, sim.depth()), lying, 1e-3 * lying);
  changed.coverage.flutter_deg = 25.0f;
  sim.apply(changed);
  EXPECT_GT(sim.coverage_version(), coverage_version);
  // A bad setting is refused and the state kept.
  live::LiveSettings bad = changed;
  bad.fall_rate = -1.0f;
  EXPECT_THROW(sim.apply(bad), InputError);
  EXPECT_FLOAT_EQ(sim.settings().fall_rate, changed.fall_rate);
  // Re-peel at another texel size restarts the snow.
  const uint64_t maps_version = sim.maps_version();
  changed.peel.max_side = 48;
  sim.apply(changed);
  EXPECT_GT(sim.maps_version(), maps_version);
  EXPECT_EQ(sim.maps().grid.width, 48);
  EXPECT_EQ(sim.fallen_depth(), 0.0f);
  EXPECT_EQ(snow_volume(sim.maps(), sim.depth()), 0.0);
  sim.step();
  EXPECT_GT(snow_volume(sim.maps(), sim.depth()), 0.0);
  sim.reset();
  EXPECT_EQ(snow_volume(sim.maps(), sim.depth()), 0.0);
  EXPECT_EQ(sim.frame(), 0);
}

TEST(Preview, RejectsBadSizeBeforeOpeningAWindow) {
  const snow::test::CommandResult run =
      run_snowmodel("preview " + kCourtyard.string() + " --size 0x10 --frames 1");
  EXPECT_NE(run.code, 0) << run.output;
  EXPECT_NE(run.output.find("--size"), std::string::npos) << run.output;
}

TEST(Preview, AppliesIgnoreBeforeOpeningAWindow) {
  const snow::test::CommandResult run =
      run_snowmodel("preview " + kCourtyard.string() + " --ignore '*' --frames 1");
  EXPECT_EQ(run.code, 2) << run.output;
  EXPECT_NE(run.output.find("--ignore removed every object"), std::string::npos) << run.output;
}

/// The courtyard's preview (in a window, or `headless`) after 250 frames:
/// its screenshot has snow on the roof and the open ground and none under
/// the table, where the same camera projects them.
void check_courtyard_screenshot(bool headless) {
  const fs::path dir =
      fs::temp_directory_path() /
      ("snow_test_preview_" + std::to_string(getpid()) + (headless ? "_headless" : ""));
  fs::create_directories(dir);
  const fs::path shot = dir / "shot.png";
  const fs::path exported = dir / "snow.ply";
  const int w = 640, h = 400;
  const float azimuth = 0.0f, elevation = 38.0f, fov = 35.0f, zoom = 2.0f;
  // 250 frames: 0.3 m of snow falls in the first 90 (0.1 m per simulated
  // second, 1/30 s per frame), the stabilizer keeps working after that.
  const snow::test::CommandResult run = run_snowmodel(
      "preview " + kCourtyard.string() + " --frames 250 --size " + std::to_string(w) + "x" +
      std::to_string(h) + " --max-side 128 --layers 4 --passes-per-frame 2 --fall-rate 0.1 " +
      "--depth 0.3 --flakes 0 --azimuth 0 --elevation 38 --fov 35 --zoom 2 --no-snow-on 'Table*' " +
      "--screenshot " + shot.string() + " --export " + exported.string() +
      (headless ? " --headless" : ""));
  ASSERT_EQ(run.code, 0) << run.output;
  const size_t summary = run.output.find("preview: 250 frames");
  ASSERT_NE(summary, std::string::npos) << run.output;
  std::printf("%s\n", run.output.substr(summary, run.output.find('\n', summary) - summary).c_str());
  ASSERT_TRUE(fs::exists(exported)) << run.output;
  EXPECT_GT(fs::file_size(exported), 1000u);

  const Picture picture = load_png(shot);
  ASSERT_EQ(picture.width, w);
  ASSERT_EQ(picture.height, h);

  // The viewer starts with OrbitView::frame on the scene's bounds, whose
  // view matrix is render::orbit_camera's; x and y on screen do not depend
  // on near and far.
  const Scene scene = load_scene(kCourtyard);
  live::OrbitView view;
  view.azimuth = azimuth;
  view.elevation = elevation;
  view.fov = fov;
  const float aspect = float(w) / float(h);
  view.frame(scene.bounds, aspect);
  const render::PreviewCamera framed = view.camera(scene.bounds, aspect);
  view.distance /= zoom;
  const render::PreviewCamera camera = view.camera(scene.bounds, aspect);
  const render::PreviewCamera reference =
      render::orbit_camera(scene.bounds, azimuth, elevation, aspect, fov, view.margin);
  for (const glm::vec3& p : {glm::vec3(0, 0, 0), glm::vec3(5, 2, -3)}) {
    const glm::ivec2 a = project(framed, p, w, h), b = project(reference, p, w, h);
    EXPECT_LE(std::abs(a.x - b.x) + std::abs(a.y - b.y), 1);
  }

  // Courtyard (src/scene/builder.cpp, make_courtyard): house x -10..-3,
  // z -10..-5, walls 3 m, 42-degree roof with the ridge along x at z = -7.5;
  // ground top at y = 0; table top 1.5 x 1 m at y = 0.75 centred on (2, 3).
  const float roof_y = 3.0f + 1.25f * std::tan(glm::radians(42.0f)) + 0.25f;  // + roof, snow
  const glm::ivec2 roof = project(camera, glm::vec3(-4.5f, roof_y, -6.25f), w, h);
  const glm::ivec2 ground = project(camera, glm::vec3(-2.0f, 0.3f, 3.0f), w, h);
  const glm::ivec2 ground2 = project(camera, glm::vec3(4.0f, 0.3f, 0.0f), w, h);
  const glm::ivec2 under_table = project(camera, glm::vec3(2.0f, 0.0f, 3.0f), w, h);
  for (const glm::ivec2& p : {roof, ground, ground2, under_table}) {
    ASSERT_TRUE(p.x >= 2 && p.y >= 2 && p.x < w - 2 && p.y < h - 2) << p.x << "," << p.y;
  }
  const double roof_share = white_share(picture, roof, 2);
  const double ground_share = white_share(picture, ground, 2);
  const double ground2_share = white_share(picture, ground2, 2);
  const double under_share = white_share(picture, under_table, 1);
  std::printf(
      "snow-white share: roof %.2f at (%d,%d), ground %.2f at (%d,%d), %.2f at (%d,%d), "
      "under the table %.2f at (%d,%d)\n",
      roof_share, roof.x, roof.y, ground_share, ground.x, ground.y, ground2_share, ground2.x,
      ground2.y, under_share, under_table.x, under_table.y);
  EXPECT_GE(roof_share, 0.8);
  EXPECT_GE(ground_share, 0.8);
  EXPECT_GE(ground2_share, 0.8);
  EXPECT_EQ(under_share, 0.0);
  // The picture as a whole: mostly snow where the scene is.
  int white = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) white += snow_white(picture.at(x, y));
  EXPECT_GT(white, w * h / 10);
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

TEST(Preview, CourtyardScreenshotHasSnowOnRoofAndGroundNoneUnderTheTable) {
  if (!has_display()) GTEST_SKIP() << "no DISPLAY (the xvfb-run ctest entry runs this)";
  check_courtyard_screenshot(false);
}

TEST(Preview, HeadlessCourtyardScreenshotHasSnowOnRoofAndGroundNoneUnderTheTable) {
  check_courtyard_screenshot(true);
}

// The preview's maps follow the planner like the batch job's: a 1 m
// triangle under 0.3 m of snow would lie 150 texels deep at the preview's
// 512 texels, so the maps are coarser, and the run says why.
TEST(Preview, SmallObjectsUnderDeepSnowGetThePlannersSide) {
  const fs::path dir = test::temp_dir("snow_test_preview_plan");
  int mesh = 0;
  test::Gltf gltf = test::triangle_gltf(&mesh);
  gltf.scene({gltf.node({{"mesh", mesh}})});
  const fs::path scene = gltf.write_gltf(dir, "triangle");
  const snow::test::CommandResult run =
      run_snowmodel("preview " + scene.string() + " --headless --frames 1 --size 64x40");
  EXPECT_EQ(run.code, 0) << run.output;
  EXPECT_NE(run.output.find("maps: automatic side"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("preview: 1 frames"), std::string::npos) << run.output;
  if (!HasFailure()) fs::remove_all(dir);
}

// Debian's Dear ImGui cannot load GL functions on an OSMesa context: a
// headless --screenshot-panel there is a one-line GL error (exit 3) and no
// screenshot, not a crash; without the panel the preview runs.
TEST(Preview, HeadlessPanelWhereImGuiCannotDrawIsAClearError) {
  const fs::path shot =
      fs::temp_directory_path() / ("snow_test_panel_" + std::to_string(getpid()) + ".png");
  const std::string run = "--gl-backend osmesa preview " + kCourtyard.string() +
                          " --headless --frames 2 --max-side 64 --size 160x100 --screenshot " +
                          shot.string();
  const snow::test::CommandResult plain = run_snowmodel(run);
  if (plain.code == 3) GTEST_SKIP() << "no OSMesa context here: " << plain.output;
  EXPECT_EQ(plain.code, 0) << plain.output;
  EXPECT_TRUE(fs::exists(shot));
  fs::remove(shot);
  const snow::test::CommandResult panel = run_snowmodel(run + " --screenshot-panel");
  if (panel.code == 0) {  // an ImGui that loads GL on OSMesa: the panel is drawn
    EXPECT_TRUE(fs::exists(shot));
    fs::remove(shot);
    return;
  }
  EXPECT_EQ(panel.code, 3) << panel.output;
  EXPECT_NE(panel.output.find("error: the settings panel (Dear ImGui) cannot load OpenGL"),
            std::string::npos)
      << panel.output;
  EXPECT_FALSE(fs::exists(shot));
}

/// The m^3 after `key` ("lying of ", "fell ") in a summary line, or -1.
double summary_volume(const std::string& output, const std::string& key) {
  const size_t at = output.find(key);
  return at == std::string::npos ? -1.0 : std::atof(output.c_str() + at + key.size());
}

// The headless preview, once the snow has fallen and come to rest, holds the
// snow the batch job lays with the same settings (the same maps): the same
// fallen and lying volume within 0.5 % (the preview adds the snow frame by
// frame, and the stabilizer routes what each addition brings), and the same
// depth on the top layer within 1 mm on 98 % of its texels and 3 mm on
// average (piles of slid snow, which is loose, form in a different order).
TEST(Preview, HeadlessSnowMatchesTheBatchJob) {
  const fs::path dir =
      fs::temp_directory_path() / ("snow_test_preview_batch_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string settings = " --max-side 128 --layers 4 --depth 0.3 --directions 16 ";
  const snow::test::CommandResult preview = run_snowmodel(
      "preview " + kCourtyard.string() + settings +
      "--headless --frames 120 --fall-rate 0.6 --passes-per-frame 64 --flakes 0 --size 320x200 " +
      "--maps " + (dir / "live").string());
  ASSERT_EQ(preview.code, 0) << preview.output;
  const snow::test::CommandResult batch =
      run_snowmodel("snow " + kCourtyard.string() + settings + "-o " + (dir / "snow.glb").string() +
                    " --maps " + (dir / "batch").string());
  ASSERT_EQ(batch.code, 0) << batch.output;
  const double live_lying = summary_volume(preview.output, "m^3 lying of ");
  const double live_fallen = summary_volume(preview.output, "lying of ");
  const double batch_lying = summary_volume(batch.output, "; snow ");
  const double batch_fallen = summary_volume(batch.output, "(fell ");
  ASSERT_GT(batch_fallen, 1.0) << batch.output;
  EXPECT_NEAR(live_fallen, batch_fallen, 0.005 * batch_fallen);
  EXPECT_NEAR(live_lying, batch_lying, 0.005 * batch_lying);

  int w = 0, h = 0, bw = 0, bh = 0;
  const std::vector<float> live = snow::test::read_exr(dir / "live" / "layer0_depth.exr", &w, &h);
  const std::vector<float> ref = snow::test::read_exr(dir / "batch" / "layer0_depth.exr", &bw, &bh);
  ASSERT_EQ(w, bw);
  ASSERT_EQ(h, bh);
  ASSERT_EQ(live.size(), ref.size());
  std::vector<double> errors(live.size());
  double sum = 0;
  for (size_t k = 0; k < live.size(); ++k) {
    errors[k] = std::abs(double(live[k]) - double(ref[k]));
    sum += errors[k];
  }
  std::sort(errors.begin(), errors.end());
  const double mean = sum / double(errors.size());
  const double p98 = errors[errors.size() * 98 / 100];
  std::printf(
      "preview %.3f of %.3f m^3 lying, batch %.3f of %.3f; top layer depth: mean "
      "difference %.2f mm, 98th percentile %.2f mm, largest %.1f mm\n",
      live_lying, live_fallen, batch_lying, batch_fallen, mean * 1e3, p98 * 1e3,
      errors.back() * 1e3);
  EXPECT_LE(mean, 0.003);
  EXPECT_LE(p98, 0.001);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace snow

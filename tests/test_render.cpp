// Tests of src/render: the headless preview renderer, its cameras and PNGs.
#include <gtest/gtest.h>

#include <stb_image.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "gl/context.h"
#include "render/preview.h"

namespace snow::render {
namespace {

// --- Scenes built in code ---------------------------------------------------

void add_triangle(Scene& scene, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 normal,
                  glm::vec2 ua = {}, glm::vec2 ub = {}, glm::vec2 uc = {}) {
  for (const glm::vec3& p : {a, b, c}) {
    scene.positions.push_back(p);
    scene.normals.push_back(normal);
    scene.bounds.extend(p);
  }
  for (const glm::vec2& uv : {ua, ub, uc}) scene.uvs.push_back(uv);
}

void begin_object(Scene& scene, const std::string& name, int material) {
  SceneObject object;
  object.name = name;
  object.material = material;
  object.first_triangle = static_cast<uint32_t>(scene.triangle_count());
  scene.objects.push_back(object);
}

void end_object(Scene& scene) {
  SceneObject& object = scene.objects.back();
  object.triangle_count = static_cast<uint32_t>(scene.triangle_count()) - object.first_triangle;
}

int add_material(Scene& scene, glm::vec4 color, int image = -1) {
  Material material;
  material.name = "m" + std::to_string(scene.materials.size());
  material.base_color = color;
  material.base_color_image = image;
  scene.materials.push_back(material);
  return static_cast<int>(scene.materials.size()) - 1;
}

// Horizontal quad at height y over [x0,x1] x [z0,z1], counter-clockwise seen
// from above, uv (0,0) at the north-west corner (x0, z0) and (1,1) south-east.
void add_floor(Scene& scene, const std::string& name, int material, float x0, float x1, float z0,
               float z1, float y, glm::vec3 normal = {0, 1, 0}) {
  begin_object(scene, name, material);
  const glm::vec3 nw(x0, y, z0), ne(x1, y, z0), sw(x0, y, z1), se(x1, y, z1);
  add_triangle(scene, nw, sw, se, normal, {0, 0}, {0, 1}, {1, 1});
  add_triangle(scene, nw, se, ne, normal, {0, 0}, {1, 1}, {1, 0});
  end_object(scene);
}

// Axis-aligned box, outward normals, counter-clockwise from outside.
void add_box(Scene& scene, const std::string& name, int material, glm::vec3 lo, glm::vec3 hi) {
  begin_object(scene, name, material);
  const glm::vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
                          {lo.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                          {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 4, 7, 3},
                           {1, 2, 6, 5}, {3, 7, 6, 2}, {0, 1, 5, 4}};
  const glm::vec3 normals[6] = {{0, 0, -1}, {0, 0, 1}, {-1, 0, 0},
                                {1, 0, 0},  {0, 1, 0}, {0, -1, 0}};
  for (int f = 0; f < 6; ++f) {
    const glm::vec3 a = c[faces[f][0]], b = c[faces[f][1]], d = c[faces[f][2]], e = c[faces[f][3]];
    add_triangle(scene, a, b, d, normals[f]);
    add_triangle(scene, a, d, e, normals[f]);
  }
  end_object(scene);
}

TriMesh quad_mesh(const std::string& name, float x0, float x1, float z0, float z1, float y) {
  TriMesh mesh;
  mesh.name = name;
  mesh.positions = {{x0, y, z0}, {x0, y, z1}, {x1, y, z1}, {x1, y, z0}};
  mesh.indices = {0, 1, 2, 0, 2, 3};  // no normals: the renderer makes them
  return mesh;
}

// --- Pixel helpers -------------------------------------------------------------

glm::vec3 rgb(const ImageRGBA8& image, int x, int y) {
  const uint8_t* p = image.at(x, y);
  return glm::vec3(p[0], p[1], p[2]);
}

glm::vec3 expected_pixel(const glm::vec3& albedo_linear, const glm::vec3& normal,
                         const PreviewSettings& settings) {
  const glm::vec3 c = shade_linear(albedo_linear, normal, settings);
  return glm::vec3(srgb_encode(c.r), srgb_encode(c.g), srgb_encode(c.b)) * 255.0f;
}

glm::vec3 background_pixel(const PreviewSettings& settings) { return settings.background * 255.0f; }

void expect_near(const glm::vec3& got, const glm::vec3& want, float tolerance,
                 const std::string& where) {
  EXPECT_NEAR(got.r, want.r, tolerance) << where;
  EXPECT_NEAR(got.g, want.g, tolerance) << where;
  EXPECT_NEAR(got.b, want.b, tolerance) << where;
}

bool is_background(const ImageRGBA8& image, int x, int y, const PreviewSettings& settings) {
  return glm::length(rgb(image, x, y) - background_pixel(settings)) < 3.0f;
}

// Mean pixel position of pixels close to `colour` (255 scale); (-1,-1) if none.
glm::vec2 centroid_of(const ImageRGBA8& image, const glm::vec3& colour, float tolerance) {
  glm::dvec2 sum(0.0);
  int count = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (glm::length(rgb(image, x, y) - colour) < tolerance) {
        sum += glm::dvec2(x, y);
        ++count;
      }
    }
  }
  return count ? glm::vec2(sum / double(count)) : glm::vec2(-1.0f);
}

class RenderTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    gl::ContextOptions options;
    options.backend = gl::Backend::EglSurfaceless;
    context_ = gl::create_context(options).release();
  }
  static void TearDownTestSuite() {
    delete context_;
    context_ = nullptr;
  }
  static gl::Context* context_;
};
gl::Context* RenderTest::context_ = nullptr;

PreviewSettings small(View view, int width = 160, int height = 100) {
  PreviewSettings settings;
  settings.width = width;
  settings.height = height;
  settings.view = view;
  return settings;
}

// --- Tests ---------------------------------------------------------------------

TEST_F(RenderTest, ImageSizeAndBackgroundWhereEmpty) {
  Scene scene;
  add_box(scene, "box", add_material(scene, {0.8f, 0.3f, 0.2f, 1.0f}), {-1, 0, -1}, {1, 1, 1});
  const PreviewSettings settings = small(View::ThreeQuarter);
  const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), settings);
  ASSERT_EQ(image.width, 160);
  ASSERT_EQ(image.height, 100);
  ASSERT_EQ(image.pixels.size(), 160u * 100u * 4u);
  for (auto [x, y] : {std::pair{0, 0}, std::pair{159, 0}, std::pair{0, 99}, std::pair{159, 99}}) {
    expect_near(rgb(image, x, y), background_pixel(settings), 1.0f,
                "corner " + std::to_string(x) + "," + std::to_string(y));
    EXPECT_EQ(image.at(x, y)[3], 255);
  }
  EXPECT_FALSE(is_background(image, 80, 50, settings)) << "the box fills the centre";
}

TEST_F(RenderTest, EmptySceneIsAllBackground) {
  const PreviewSettings settings = small(View::Top, 32, 32);
  const ImageRGBA8 image = render_preview(Scene{}, {}, glm::vec4(1.0f), settings);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) ASSERT_TRUE(is_background(image, x, y, settings));
  }
}

TEST_F(RenderTest, TopViewLitColourMatchesShadingContract) {
  Scene scene;
  const glm::vec3 albedo(0.8f, 0.2f, 0.1f);
  add_floor(scene, "floor", add_material(scene, glm::vec4(albedo, 1.0f)), -2, 2, -2, 2, 0);
  for (int samples : {1, 4}) {
    PreviewSettings settings = small(View::Top, 64, 64);
    settings.samples = samples;
    const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), settings);
    const glm::vec3 want = expected_pixel(albedo, {0, 1, 0}, settings);
    expect_near(rgb(image, 32, 32), want, 2.0f, "samples " + std::to_string(samples));
    expect_near(rgb(image, 10, 50), want, 2.0f, "samples " + std::to_string(samples));
    // The floor fills the square image up to the margin.
    EXPECT_TRUE(is_background(image, 0, 0, settings));
  }
}

TEST_F(RenderTest, MultisamplingSmoothsEdges) {
  // A triangle with slanted edges: with 1 sample every pixel is either the
  // object or the background; with 4 some edge pixels lie in between.
  Scene scene;
  begin_object(scene, "slanted", add_material(scene, glm::vec4(0.1f, 0.1f, 0.1f, 1)));
  add_triangle(scene, {-1, 0, -1}, {-0.3f, 0, 1}, {1, 0, 0.2f}, {0, 1, 0});
  end_object(scene);
  auto count_mixed = [&](int samples) {
    PreviewSettings settings = small(View::Top, 64, 64);
    settings.samples = samples;
    const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), settings);
    const glm::vec3 object = expected_pixel(glm::vec3(0.1f), {0, 1, 0}, settings);
    int mixed = 0;
    for (int y = 0; y < 64; ++y) {
      for (int x = 0; x < 64; ++x) {
        const glm::vec3 p = rgb(image, x, y);
        if (glm::length(p - object) > 4.0f && !is_background(image, x, y, settings)) ++mixed;
      }
    }
    return mixed;
  };
  EXPECT_EQ(count_mixed(1), 0);
  EXPECT_GT(count_mixed(4), 20);
}

TEST_F(RenderTest, GammaCorrectOutput) {
  // A mid-grey albedo lit to a linear 0.2 must come out near sRGB 124, not 51.
  Scene scene;
  add_floor(scene, "floor", add_material(scene, glm::vec4(1.0f)), -1, 1, -1, 1, 0);
  PreviewSettings settings = small(View::Top, 32, 32);
  settings.sun_radiance = glm::vec3(0.0f);
  settings.sky_ambient = glm::vec3(0.2f);
  const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), settings);
  EXPECT_NEAR(rgb(image, 16, 16).g, 255.0f * srgb_encode(0.2f), 2.0f);
  EXPECT_NEAR(srgb_encode(0.2f) * 255.0f, 124.0f, 1.0f);
  EXPECT_NEAR(srgb_decode(srgb_encode(0.37f)), 0.37f, 1e-5f);
}

TEST_F(RenderTest, FlippedNormalsAreStillLit) {
  Scene good, flipped;
  add_floor(good, "floor", add_material(good, glm::vec4(0.6f, 0.6f, 0.6f, 1)), -1, 1, -1, 1, 0);
  add_floor(flipped, "floor", add_material(flipped, glm::vec4(0.6f, 0.6f, 0.6f, 1)), -1, 1, -1, 1,
            0, {0, -1, 0});
  const PreviewSettings settings = small(View::Top, 32, 32);
  const ImageRGBA8 a = render_preview(good, {}, glm::vec4(1.0f), settings);
  const ImageRGBA8 b = render_preview(flipped, {}, glm::vec4(1.0f), settings);
  expect_near(rgb(b, 16, 16), rgb(a, 16, 16), 1.0f, "centre");
}

TEST_F(RenderTest, TopViewPutsObjectsWhereExpected) {
  // Grey ground 10 m x 10 m, a red box in the north-east (+X, -Z).
  Scene scene;
  add_floor(scene, "ground", add_material(scene, {0.5f, 0.5f, 0.5f, 1}), -5, 5, -5, 5, 0);
  const glm::vec3 red(0.9f, 0.05f, 0.05f);
  add_box(scene, "box", add_material(scene, glm::vec4(red, 1)), {2.5f, 0, -3.5f}, {3.5f, 1, -2.5f});
  PreviewSettings settings = small(View::Top, 100, 100);
  const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), settings);

  // The 10 m square (plus margin) maps onto 100 pixels; north is up.
  const float half = 5.0f / (1.0f - 2.0f * settings.margin);
  const auto pixel_of = [&](float x, float z) {
    return glm::ivec2(int((x / half * 0.5f + 0.5f) * 100), int((z / half * 0.5f + 0.5f) * 100));
  };
  const glm::ivec2 box = pixel_of(3.0f, -3.0f);
  EXPECT_GT(box.x, 70);
  EXPECT_LT(box.y, 30);
  const glm::vec3 box_pixel = expected_pixel(red, {0, 1, 0}, settings);
  const glm::vec3 ground_pixel = expected_pixel(glm::vec3(0.5f), {0, 1, 0}, settings);
  expect_near(rgb(image, box.x, box.y), box_pixel, 2.0f, "box top");
  const glm::ivec2 mirrors[3] = {pixel_of(-3, -3), pixel_of(3, 3), pixel_of(-3, 3)};
  for (const glm::ivec2& p : mirrors) {
    expect_near(rgb(image, p.x, p.y), ground_pixel, 2.0f,
                "ground at " + std::to_string(p.x) + "," + std::to_string(p.y));
  }
  // The box's pixel centroid is where the camera maths puts it.
  const glm::vec2 c = centroid_of(image, box_pixel, 6.0f);
  EXPECT_NEAR(c.x, (3.0f / half * 0.5f + 0.5f) * 100.0f, 1.5f);
  EXPECT_NEAR(c.y, (-3.0f / half * 0.5f + 0.5f) * 100.0f, 1.5f);
}

TEST_F(RenderTest, ThreeQuarterViewIsFromTheSouthEastAndFramesTheBounds) {
  Scene scene;
  add_floor(scene, "ground", add_material(scene, {0.5f, 0.5f, 0.5f, 1}), -5, 5, -5, 5, 0);
  const int red = add_material(scene, {0.9f, 0.05f, 0.05f, 1});
  const int blue = add_material(scene, {0.05f, 0.05f, 0.9f, 1});
  const int green = add_material(scene, {0.05f, 0.9f, 0.05f, 1});
  add_box(scene, "north-east", red, {3, 0, -4}, {4, 1, -3});
  add_box(scene, "south-west", blue, {-4, 0, 3}, {-3, 1, 4});
  add_box(scene, "south-east", green, {3, 0, 3}, {4, 1, 4});
  PreviewSettings settings = small(View::ThreeQuarter, 200, 150);
  const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), settings);

  // Box tops: pure hue tests (the channel far above the others).
  auto centroid_where = [&](int channel) {
    glm::dvec2 sum(0.0);
    int n = 0;
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        const glm::vec3 p = rgb(image, x, y);
        const float other = channel == 0   ? std::max(p.g, p.b)
                            : channel == 1 ? std::max(p.r, p.b)
                                           : std::max(p.r, p.g);
        if (p[channel] > other + 60.0f) {
          sum += glm::dvec2(x, y);
          ++n;
        }
      }
    }
    EXPECT_GT(n, 10) << "channel " << channel;
    return n ? glm::vec2(sum / double(n)) : glm::vec2(-1.0f);
  };
  const glm::vec2 north_east = centroid_where(0);
  const glm::vec2 south_east = centroid_where(1);
  const glm::vec2 south_west = centroid_where(2);
  // Looking north-west: north-east on the right, south-west on the left, the
  // south-east box nearest (lowest in the image) and centred.
  EXPECT_GT(north_east.x, south_west.x + 60.0f);
  EXPECT_GT(south_east.y, north_east.y + 15.0f);
  EXPECT_GT(south_east.y, south_west.y + 15.0f);
  EXPECT_NEAR(south_east.x, image.width * 0.5f, 10.0f);

  // Framing: the border is background, the drawn area spans most of the image.
  int min_x = image.width, max_x = -1, min_y = image.height, max_y = -1;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (is_background(image, x, y, settings)) continue;
      min_x = std::min(min_x, x);
      max_x = std::max(max_x, x);
      min_y = std::min(min_y, y);
      max_y = std::max(max_y, y);
    }
  }
  EXPECT_GT(min_x, 0);
  EXPECT_GT(min_y, 0);
  EXPECT_LT(max_x, image.width - 1);
  EXPECT_LT(max_y, image.height - 1);
  EXPECT_TRUE(max_x - min_x > 0.85f * image.width || max_y - min_y > 0.85f * image.height)
      << min_x << ".." << max_x << " x " << min_y << ".." << max_y;
}

TEST_F(RenderTest, CamerasFrameAllCorners) {
  Bounds b;
  b.extend({-3, 0, -1});
  b.extend({5, 2, 7});
  for (float aspect : {0.5f, 1.0f, 2.0f}) {
    const PreviewCamera cams[2] = {orbit_camera(b, 45, 35, aspect), top_camera(b, aspect)};
    for (const PreviewCamera& cam : cams) {
      for (int i = 0; i < 8; ++i) {
        const glm::vec3 corner(i & 1 ? b.max.x : b.min.x, i & 2 ? b.max.y : b.min.y,
                               i & 4 ? b.max.z : b.min.z);
        const glm::vec4 clip = cam.view_projection() * glm::vec4(corner, 1.0f);
        const glm::vec3 ndc = glm::vec3(clip) / clip.w;
        EXPECT_LE(std::abs(ndc.x), 1.0f - 0.05f * 2 + 1e-3f) << "aspect " << aspect;
        EXPECT_LE(std::abs(ndc.y), 1.0f - 0.05f * 2 + 1e-3f) << "aspect " << aspect;
        EXPECT_GT(ndc.z, -1.0f);
        EXPECT_LT(ndc.z, 1.0f);
      }
    }
  }
  const PreviewCamera top = top_camera(b, 1.0f);
  EXPECT_TRUE(top.orthographic);
  EXPECT_NEAR(top.forward.y, -1.0f, 1e-6f);
  const PreviewCamera orbit = orbit_camera(b, 45, 35, 1.0f);
  EXPECT_GT(orbit.eye.x, b.center().x);  // east
  EXPECT_GT(orbit.eye.z, b.center().z);  // south
  EXPECT_GT(orbit.eye.y, b.max.y);       // above
}

TEST_F(RenderTest, FitCameraFramesThePointsTightly) {
  // A flat 10 m cloth with a small box on it; the bounds reach 3 m up only
  // at one corner (a pole), so box-corner framing leaves much empty image.
  std::vector<glm::vec3> points;
  for (int i = 0; i <= 10; ++i) {
    for (int j = 0; j <= 10; ++j) points.push_back({i - 5.0f, 0.0f, j - 5.0f});
  }
  points.push_back({-5, 3, -5});
  Bounds b;
  for (const glm::vec3& p : points) b.extend(p);
  const float margin = 0.05f;
  const PreviewCamera loose = orbit_camera(b, 45, 35, 1.6f, 35, margin);
  const PreviewCamera tight = orbit_camera_fit(b, {&points}, 45, 35, 1.6f, 35, margin);
  auto extent = [&](const PreviewCamera& cam) {
    glm::vec2 lo(10.0f), hi(-10.0f);
    for (const glm::vec3& p : points) {
      const glm::vec4 clip = cam.view_projection() * glm::vec4(p, 1.0f);
      const glm::vec3 ndc = glm::vec3(clip) / clip.w;
      EXPECT_GT(ndc.z, -1.0f);
      EXPECT_LT(ndc.z, 1.0f);
      lo = glm::min(lo, glm::vec2(ndc));
      hi = glm::max(hi, glm::vec2(ndc));
    }
    return std::pair{lo, hi};
  };
  const auto [tlo, thi] = extent(tight);
  const float limit = 1.0f - 2.0f * margin + 1e-3f;
  EXPECT_GE(tlo.x, -limit);
  EXPECT_GE(tlo.y, -limit);
  EXPECT_LE(thi.x, limit);
  EXPECT_LE(thi.y, limit);
  // Tight: touches the margin on one axis, centred on both.
  EXPECT_TRUE(thi.x - tlo.x > 2.0f * limit - 0.02f || thi.y - tlo.y > 2.0f * limit - 0.02f);
  EXPECT_NEAR(tlo.x + thi.x, 0.0f, 0.05f);
  EXPECT_NEAR(tlo.y + thi.y, 0.0f, 0.05f);
  const auto [llo, lhi] = extent(loose);
  EXPECT_GT((thi.x - tlo.x) * (thi.y - tlo.y), (lhi.x - llo.x) * (lhi.y - llo.y));
}

TEST_F(RenderTest, ExtraMeshesDrawOnTopWithDepth) {
  Scene scene;
  const glm::vec3 ground(0.3f, 0.5f, 0.3f);
  add_floor(scene, "ground", add_material(scene, glm::vec4(ground, 1)), -2, 2, -2, 2, 0);
  // Snow over the west half, slightly above; a hidden sheet below the ground.
  const std::vector<TriMesh> extra = {quad_mesh("snow", -2, 0, -2, 2, 0.05f),
                                      quad_mesh("buried", 0, 2, -2, 2, -0.5f)};
  PreviewSettings settings = small(View::Top, 64, 64);
  const glm::vec4 white(1.0f);
  const ImageRGBA8 image = render_preview(scene, extra, white, settings);
  expect_near(rgb(image, 16, 32), expected_pixel(glm::vec3(1.0f), {0, 1, 0}, settings), 2.0f,
              "snow");
  expect_near(rgb(image, 48, 32), expected_pixel(ground, {0, 1, 0}, settings), 2.0f, "ground");

  // One colour per mesh.
  const std::vector<glm::vec4> colors = {{0.9f, 0.1f, 0.1f, 1.0f}, white};
  const ImageRGBA8 per_mesh = render_preview(scene, extra, colors, settings);
  expect_near(rgb(per_mesh, 16, 32),
              expected_pixel(glm::vec3(0.9f, 0.1f, 0.1f), {0, 1, 0}, settings), 2.0f, "red");

  EXPECT_THROW(render_preview(scene, extra, std::vector<glm::vec4>(3, white), settings),
               InputError);
  TriMesh broken = quad_mesh("broken", 0, 1, 0, 1, 0);
  broken.indices.push_back(9);
  broken.indices.push_back(0);
  broken.indices.push_back(1);
  EXPECT_THROW(render_preview(scene, {broken}, white, settings), InputError);
}

TEST_F(RenderTest, BaseColorTextureTimesFactor) {
  // 2x2 texture: red, green (top row), blue, white (bottom row), on a quad
  // with uv (0,0) at the north-west corner, so the top view shows it upright.
  Scene scene;
  Image image;
  image.name = "checker";
  image.width = 2;
  image.height = 2;
  image.rgba = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255};
  scene.images.push_back(image);
  const glm::vec4 factor(1.0f, 1.0f, 0.5f, 1.0f);
  add_floor(scene, "floor", add_material(scene, factor, 0), -1, 1, -1, 1, 0);
  // 102 pixels: pixels 25 and 76 sample uv 0.25 and 0.75, the texel centres
  // (linear filtering would blend neighbours elsewhere).
  PreviewSettings settings = small(View::Top, 102, 102);
  settings.margin = 0.0f;
  const ImageRGBA8 out = render_preview(scene, {}, glm::vec4(1.0f), settings);
  const glm::vec3 f(factor);
  const glm::vec3 n(0, 1, 0);
  expect_near(rgb(out, 25, 25), expected_pixel(f * glm::vec3(1, 0, 0), n, settings), 3.0f, "NW");
  expect_near(rgb(out, 76, 25), expected_pixel(f * glm::vec3(0, 1, 0), n, settings), 3.0f, "NE");
  expect_near(rgb(out, 25, 76), expected_pixel(f * glm::vec3(0, 0, 1), n, settings), 3.0f, "SW");
  expect_near(rgb(out, 76, 76), expected_pixel(f * glm::vec3(1, 1, 1), n, settings), 3.0f, "SE");
}

TEST_F(RenderTest, BadTextureIsSkippedWithWarning) {
  Scene scene;
  Image image;
  image.name = "truncated";
  image.width = 4;
  image.height = 4;
  image.rgba.assign(10, 0);
  scene.images.push_back(image);
  add_floor(scene, "floor", add_material(scene, glm::vec4(0.5f, 0.5f, 0.5f, 1), 0), -1, 1, -1, 1,
            0);
  clear_warnings();
  const PreviewSettings settings = small(View::Top, 32, 32);
  const ImageRGBA8 out = render_preview(scene, {}, glm::vec4(1.0f), settings);
  ASSERT_FALSE(recorded_warnings().empty());
  EXPECT_NE(recorded_warnings().back().find("truncated"), std::string::npos);
  expect_near(rgb(out, 16, 16), expected_pixel(glm::vec3(0.5f), {0, 1, 0}, settings), 2.0f,
              "untextured");
}

TEST_F(RenderTest, BadSizesAreErrors) {
  Scene scene;
  add_floor(scene, "floor", -1, -1, 1, -1, 1, 0);
  PreviewSettings settings = small(View::Top, 0, 10);
  EXPECT_THROW(render_preview(scene, {}, glm::vec4(1.0f), settings), InputError);
  settings = small(View::Top, 1 << 20, 10);
  EXPECT_THROW(render_preview(scene, {}, glm::vec4(1.0f), settings), GLError);
}

TEST_F(RenderTest, WritePngRoundTrips) {
  Scene scene;
  add_box(scene, "box", add_material(scene, {0.2f, 0.4f, 0.9f, 1}), {-1, 0, -1}, {1, 2, 1});
  const ImageRGBA8 image = render_preview(scene, {}, glm::vec4(1.0f), small(View::ThreeQuarter));
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("snow_test_render_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path path = dir / "preview.png";
  write_png(image, path);
  int w = 0, h = 0, n = 0;
  uint8_t* data = stbi_load(path.c_str(), &w, &h, &n, 4);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(w, image.width);
  EXPECT_EQ(h, image.height);
  EXPECT_TRUE(std::equal(image.pixels.begin(), image.pixels.end(), data));
  stbi_image_free(data);
  EXPECT_THROW(write_png(image, dir / "missing_folder" / "x.png"), IOError);
  ImageRGBA8 wrong = image;
  wrong.pixels.resize(7);
  EXPECT_THROW(write_png(wrong, dir / "wrong.png"), InputError);
  EXPECT_FALSE(std::filesystem::exists(dir / "wrong.png"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace snow::render

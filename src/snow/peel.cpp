// Stage 1: snow amount maps by depth peeling from straight above.
// Tokoi, "A Shadow Buffer Technique for Simulating Snow-Covered Shapes"
// (2006), section 3; depth peeling after Everitt, "Interactive
// Order-Independent Transparency" (2001); one surface per layer, top down,
// as the height spans of Onoue and Nishita (2004).
#include "snow/peel.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "plan/rules.h"
#include "shaders/bindings.h"
#include "snow/gpu_scene.h"
#include "snow/reference/peel_ref.h"

namespace snow {
namespace {

constexpr double kPiDouble = 3.14159265358979323846;
constexpr double kMaxSide = double(1 << 30);  // texels; beyond this a grid is absurd
constexpr float kEmptyHeight = -3.0e38f;      // "no surface" in the peel targets

std::string format_gib(double bytes) {
  char text[64];
  const double gib = bytes / double(1ull << 30);
  if (gib >= 1e5) {
    std::snprintf(text, sizeof text, "%.3g GiB", gib);
  } else if (gib == std::floor(gib)) {
    std::snprintf(text, sizeof text, "%.0f GiB", gib);
  } else {
    std::snprintf(text, sizeof text, "%.1f GiB", gib);
  }
  return text;
}

std::string format_metres(double m) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", m);
  return text;
}

// The smallest 1, 2 or 5 times a power of ten that is >= x.
double nice_ceil(double x) {
  if (!(x > 0) || !std::isfinite(x)) return x;
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= x * (1 - 1e-9)) return m * p;
  }
  return 10 * p;
}

// Bytes per unit, see estimate_memory's contract.
constexpr double kMapsPerLayerTexel = 24 + 4;              // SnowMaps + coverage
constexpr double kPeelPerTexel = 2 * 20 + 4 + 16;          // ping-pong targets, depth, readback
constexpr double kCoveragePerLayerTexel = 16 + 4 + 8 + 8;  // receivers, counts, snow, queue
constexpr double kPerTriangle = 140;        // GPU copies, BVH nodes and build scratch
constexpr double kLaterPerLayerTexel = 48;  // stabilizer, depth, polygonize scratch

SnowMaps peel_checked(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                      std::optional<plan::GlFacts> gl);

void validate_peel_settings(const PeelSettings& s) {
  if (s.layers < 1 || s.layers > 64) {
    throw InputError("layers must be in 1..64, got " + std::to_string(s.layers));
  }
  if (!(s.merge_distance >= 0.0f) || !std::isfinite(s.merge_distance)) {
    throw InputError("merge distance must be a finite number >= 0 m, got " +
                     format_metres(s.merge_distance));
  }
  if (s.device != "auto" && s.device != "gpu" && s.device != "cpu") {
    throw InputError("peel device must be auto, gpu or cpu, got '" + s.device + "'");
  }
}

// Texel centres that the triangles' xz boxes hold, summed (at most `cap`):
// a bound on the hits the CPU peel stores.
size_t box_texels(const Scene& scene, const MapGrid& grid, size_t cap) {
  size_t sum = 0;
  for (size_t t = 0; t < scene.triangle_count() && sum <= cap; ++t) {
    const glm::vec3* c = &scene.positions[3 * t];
    const double lo_x = std::min({c[0].x, c[1].x, c[2].x}),
                 hi_x = std::max({c[0].x, c[1].x, c[2].x});
    const double lo_z = std::min({c[0].z, c[1].z, c[2].z}),
                 hi_z = std::max({c[0].z, c[1].z, c[2].z});
    const double w = std::min(double(grid.width), (hi_x - lo_x) / grid.texel + 1.0);
    const double h = std::min(double(grid.height), (hi_z - lo_z) / grid.texel + 1.0);
    if (w > 0.0 && h > 0.0) sum += size_t(w * h);  // NaN boxes add nothing
  }
  return sum;
}

void warn_overflow(const SnowMaps& maps, int layers) {
  if (maps.overflow_columns > 0) {
    log_warn(std::to_string(maps.overflow_columns) + " map columns hold more than " +
             std::to_string(layers) +
             " surfaces; the lowest ones are dropped (raise --layers to keep them)");
  }
}

}  // namespace

MapGrid make_grid(const Bounds& bounds, const PeelSettings& settings) {
  validate_peel_settings(settings);
  if (bounds.empty()) throw InputError("the scene is empty: there is nothing to make maps of");
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(bounds.min[a]) || !std::isfinite(bounds.max[a])) {
      throw InputError("the scene's bounds are not finite (a vertex is NaN or infinite)");
    }
  }
  if (!(settings.texel >= 0.0f) || !std::isfinite(settings.texel)) {
    throw InputError("texel size must be a finite number > 0 m (or 0 for automatic), got " +
                     format_metres(settings.texel));
  }
  if (!std::isfinite(settings.margin)) throw InputError("margin must be finite");
  const double ex = double(bounds.max.x) - bounds.min.x;
  const double ez = double(bounds.max.z) - bounds.min.z;
  double longest = std::max(ex, ez);
  if (!(longest > 0)) longest = 1.0;  // a scene with no horizontal extent: 1 m around it
  double texel = settings.texel;
  double margin = settings.margin;
  if (texel == 0) {
    if (settings.max_side < 1 || settings.max_side > 65536) {
      throw InputError("maximum map side must be in 1..65536 texels, got " +
                       std::to_string(settings.max_side));
    }
    if (margin < 0) margin = 0.02 * longest;
    texel = (longest + 2 * margin) / settings.max_side;
    if (!(texel > 0)) texel = 1e-3;
  } else if (margin < 0) {
    margin = std::max(0.02 * longest, 2 * texel);
  }
  const double w = std::ceil((ex + 2 * margin) / texel * (1 - 1e-6));
  const double h = std::ceil((ez + 2 * margin) / texel * (1 - 1e-6));
  if (!(w <= kMaxSide) || !(h <= kMaxSide)) {
    throw InputError("a map of " + format_metres(ex + 2 * margin) + " x " +
                     format_metres(ez + 2 * margin) + " m at texel " + format_metres(texel) +
                     " m is absurdly large; use a coarser texel size");
  }
  MapGrid grid;
  grid.texel = float(texel);
  grid.width = std::max(1, int(w));
  grid.height = std::max(1, int(h));
  const double cx = 0.5 * (double(bounds.min.x) + bounds.max.x);
  const double cz = 0.5 * (double(bounds.min.z) + bounds.max.z);
  grid.origin =
      glm::vec2(float(cx - 0.5 * grid.width * texel), float(cz - 0.5 * grid.height * texel));
  return grid;
}

plan::SceneStats scene_stats(const Scene& scene, const PeelSettings& settings,
                             const plan::Settings& wanted, uint64_t input_bytes) {
  plan::SceneStats stats;
  stats.input_bytes = input_bytes;
  stats.triangles = scene.triangle_count();
  PeelSettings asked = settings;
  if (asked.texel <= 0.0f && asked.max_side == 0) asked.max_side = plan::kAutoMaxSide;
  MapGrid grid = make_grid(scene.bounds, asked);
  stats.asked_grid_side = std::max(grid.width, grid.height);
  stats.asked_grid_texel = grid.texel;
  const plan::MapPlan maps = plan::plan_maps(wanted, stats.asked_grid_side, grid.texel);
  if (maps.max_side != asked.max_side) {
    asked.max_side = maps.max_side;
    grid = make_grid(scene.bounds, asked);
  }
  stats.grid_columns = grid.texels();
  return stats;
}

uint64_t estimate_memory(const MapGrid& grid, int layers, const CoverageSettings& coverage,
                         float scene_height, uint64_t triangles) {
  const double texels = double(std::max(grid.width, 0)) * double(std::max(grid.height, 0));
  const double layer_texels = texels * std::max(layers, 1);
  // Shadow map: the grid grown by the shear of the steepest direction.
  const double angle = std::min(
      double(kMaxFallAngleDeg),
      std::atan2(double(glm::length(coverage.wind)), std::max(1e-6f, coverage.fall_speed)) * 180.0 /
              kPiDouble +
          std::max(0.0f, coverage.flutter_deg));
  const double grow = grid.texel > 0 ? std::max(0.0f, scene_height) *
                                           std::tan(angle * kPiDouble / 180.0) / grid.texel
                                     : 0.0;
  const double shadow_texels =
      (double(grid.width) + 2 * grow + 2) * (double(grid.height) + 2 * grow + 2);
  const double batch = shadow_batch(coverage, shadow_texels);
  const double bytes =
      layer_texels * (kMapsPerLayerTexel + kCoveragePerLayerTexel + kLaterPerLayerTexel) +
      texels * kPeelPerTexel + batch * shadow_texels * 4 + double(triangles) * kPerTriangle;
  if (!(bytes < 1.8e19)) return std::numeric_limits<uint64_t>::max();
  return uint64_t(bytes);
}

void check_memory_budget(const MapGrid& grid, int layers, const CoverageSettings& coverage,
                         uint64_t budget, float scene_height, uint64_t triangles) {
  const uint64_t need = estimate_memory(grid, layers, coverage, scene_height, triangles);
  if (need <= budget) return;
  // Memory grows with 1 / texel^2: suggest a texel that fits.
  const double ratio = double(need) / double(std::max<uint64_t>(budget, 1));
  const double suggest = nice_ceil(grid.texel * std::sqrt(ratio) * 1.05);
  throw InputError("maps of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                   " texels x " + std::to_string(layers) + " layers need " +
                   format_gib(double(need)) + ", over the " + format_gib(double(budget)) +
                   " budget; use a coarser texel size, e.g. --texel " + format_metres(suggest));
}

bool peels_on_cpu(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                  std::optional<plan::GlFacts> gl) {
  validate_peel_settings(settings);
  if (settings.device == "auto" && !gl) gl = plan::current_gl();
  const plan::PeelChoice choice = plan::choose_peel(
      settings.device, gl.value_or(plan::GlFacts{}), grid.texels() * size_t(settings.layers));
  if (choice.always_cpu || choice.cpu_box_texels == 0) return choice.always_cpu;
  return box_texels(scene, grid, choice.cpu_box_texels) <= choice.cpu_box_texels;
}

SnowMaps peel_layers(const Scene& scene, const PeelSettings& settings,
                     std::optional<plan::GlFacts> gl) {
  return peel_layers(scene, make_grid(scene.bounds, settings), settings, gl);
}

SnowMaps peel_layers(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                     std::optional<plan::GlFacts> gl) {
  try {
    return peel_checked(scene, grid, settings, gl);
  } catch (const std::bad_alloc&) {
    throw InputError("peel: out of memory for maps of " + std::to_string(grid.width) + " x " +
                     std::to_string(grid.height) + " texels x " + std::to_string(settings.layers) +
                     " layers; use a coarser texel size");
  }
}

namespace {

// The height of triangle `tri` at texel t's centre, worked out as the CPU
// peel's ray does (snow::reference::ColumnWeights), in place of `drawn`, the
// height the GPU interpolated there. A GPU snaps the corners to its
// sub-pixel grid before it interpolates: on an NVIDIA H100 the interpolated
// heights left 3 times the receivers of a 20k-triangle terrain at 256 texels
// shaded by their own surface (more than 0.1 mm above them), which the sky
// cull then could not settle (tools/RESULTS.md). llvmpipe's heights were
// the CPU's already. Clamped to the triangle's heights, for a centre the
// fill rule gave the triangle though the ray misses it by a rounding.
float exact_height(const Scene& scene, const MapGrid& grid, size_t t, uint32_t tri, float drawn) {
  const glm::dvec3 a(scene.positions[3 * size_t(tri)]);
  const glm::dvec3 b(scene.positions[3 * size_t(tri) + 1]);
  const glm::dvec3 c(scene.positions[3 * size_t(tri) + 2]);
  const double area = reference::ColumnWeights::area(a, b, c);
  if (area == 0.0) return drawn;
  const size_t width = size_t(grid.width);
  const double px = double(grid.origin.x) + (double(t % width) + 0.5) * double(grid.texel);
  const double pz = double(grid.origin.y) + (double(t / width) + 0.5) * double(grid.texel);
  const double y = reference::ColumnWeights(a, b, c, px, pz).height(a, b, c, area);
  return float(std::clamp(y, std::min({a.y, b.y, c.y}), std::max({a.y, b.y, c.y})));
}

SnowMaps peel_checked(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                      std::optional<plan::GlFacts> gl) {
  validate_peel_settings(settings);
  if (grid.width < 1 || grid.height < 1 || !(grid.texel > 0.0f)) {
    throw InputError("peel: empty map grid");
  }
  const float scene_height = scene.bounds.empty() ? 0.0f : scene.bounds.size().y;
  check_memory_budget(grid, settings.layers, CoverageSettings{}, settings.memory_budget,
                      scene_height, scene.triangle_count());
  if (peels_on_cpu(scene, grid, settings, gl)) {
    log_debug("peel: a vertical ray per texel on the CPU");
    Progress progress("peel", 1);
    SnowMaps maps = reference::peel_layers(scene, grid, settings.layers, settings.merge_distance);
    progress.finish();
    warn_overflow(maps, settings.layers);
    return maps;
  }
  gl::require_context();
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (max_size > 0 && (grid.width > max_size || grid.height > max_size)) {
    const double suggest =
        nice_ceil(grid.texel * double(std::max(grid.width, grid.height)) / max_size * 1.05);
    throw InputError("maps of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                     " texels exceed this GL's largest texture (" + std::to_string(max_size) +
                     "); use a coarser texel size, e.g. --texel " + format_metres(suggest));
  }

  SnowMaps maps;
  std::vector<glm::uvec2> surface;  // readback: (height bits, triangle)
  TriangleAttributes triangles;     // normal and object, as written into the maps
  try {
    // Layers are added as passes find surfaces, in capacity reserved for
    // all L: the layers a scene does not fill are never touched (8 layers of
    // 2048 x 2048 texels: 800 MB to fill and, after, to drop).
    maps.allocate(grid, 0);
    maps.reserve_layers(settings.layers);
    surface.resize(grid.texels());
    triangles = triangle_attributes(scene);
  } catch (const std::bad_alloc&) {
    throw InputError("out of memory allocating maps of " + std::to_string(grid.width) + " x " +
                     std::to_string(grid.height) + " texels x " + std::to_string(settings.layers) +
                     " layers; use a coarser texel size");
  }
  if (scene.triangle_count() == 0 || scene.bounds.empty()) {
    maps.add_layer();
    return maps;
  }
  // Each read-back layer's texels are written on all cores.
  constexpr size_t kChunk = 1 << 14;

  GlStateGuard state;
  GpuScene gpu(scene);
  gl::Program program({"peel.vert", "peel.frag"});

  // Ping-pong targets: RG32UI (height bits, triangle); the previous layer is
  // read from the other one.
  gl::Texture surface_tex[2];
  gl::Framebuffer fbo[2];
  gl::Renderbuffer depth = gl::create_renderbuffer();
  glNamedRenderbufferStorage(depth.id(), GL_DEPTH_COMPONENT32F, grid.width, grid.height);
  gl::check_error("peel depth buffer");
  for (int s = 0; s < 2; ++s) {
    surface_tex[s] = gl::create_texture_2d(GL_RG32UI, grid.width, grid.height, "peel surface");
    fbo[s] = gl::create_framebuffer();
    glNamedFramebufferTexture(fbo[s].id(), GL_COLOR_ATTACHMENT0, surface_tex[s].id(), 0);
    glNamedFramebufferRenderbuffer(fbo[s].id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth.id());
    glNamedFramebufferDrawBuffer(fbo[s].id(), GL_COLOR_ATTACHMENT0);
    gl::check_framebuffer(fbo[s], "peel framebuffer");
  }
  gl::Query query = gl::create_query(GL_ANY_SAMPLES_PASSED);

  const double pad = 1e-3 * std::max(1.0f, scene.bounds.size().y) + 1e-3;
  const float y_top = float(scene.bounds.max.y + pad);
  const float y_range = float(double(scene.bounds.max.y) - scene.bounds.min.y + 2 * pad);
  program.set("grid_origin", grid.origin);
  program.set("grid_extent", glm::vec2(grid.width * grid.texel, grid.height * grid.texel));
  program.set("y_top", y_top);
  program.set("y_range", y_range);
  program.set("merge_distance", settings.merge_distance);

  glViewport(0, 0, grid.width, grid.height);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  program.use();

  Progress progress("peel", settings.layers);
  const size_t texels = grid.texels();
  if (texels * sizeof(glm::uvec2) > size_t(0x7fffffff)) {
    throw InputError("maps of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                     " texels are too large to read back; use a coarser texel size");
  }
  const GLsizei surface_bytes = GLsizei(texels * sizeof(glm::uvec2));
  uint32_t empty_bits;
  std::memcpy(&empty_bits, &kEmptyHeight, sizeof empty_bits);
  const auto height_of = [](uint32_t bits) {
    float h;
    std::memcpy(&h, &bits, sizeof h);
    return h;
  };
  for (int l = 0; l <= settings.layers; ++l) {
    const int cur = l % 2;
    glBindFramebuffer(GL_FRAMEBUFFER, fbo[cur].id());
    const GLuint clear_surface[4] = {empty_bits, 0u, 0u, 0u};
    const GLfloat clear_depth = 1.0f;
    glClearBufferuiv(GL_COLOR, 0, clear_surface);
    glClearBufferfv(GL_DEPTH, 0, &clear_depth);
    glBindTextureUnit(SNOW_PEEL_PREV_TEXTURE, surface_tex[1 - cur].id());
    program.set("first_layer", l == 0 ? 1 : 0);
    glBeginQuery(GL_ANY_SAMPLES_PASSED, query.id());
    gpu.draw();
    glEndQuery(GL_ANY_SAMPLES_PASSED);
    gl::check_error("peel pass");
    GLuint any = 0;
    glGetQueryObjectuiv(query.id(), GL_QUERY_RESULT, &any);
    if (!any) break;  // this and every lower layer is empty

    glGetTextureImage(surface_tex[cur].id(), 0, GL_RG_INTEGER, GL_UNSIGNED_INT, surface_bytes,
                      surface.data());
    gl::check_error("peel readback");
    if (l == settings.layers) {
      // One layer too many: count the columns that hold it.
      for (const glm::uvec2& s : surface) maps.overflow_columns += s.x != empty_bits;
      break;
    }
    maps.add_layer();
    const size_t base = size_t(l) * texels;
    parallel_for_ranges(texels, kChunk, [&](size_t begin, size_t end) {
      for (size_t t = begin; t < end; ++t) {
        const glm::uvec2& s = surface[t];
        const uint32_t tri = s.y;
        if (s.x == empty_bits || tri >= triangles.normal.size()) continue;
        maps.ground[base + t] = exact_height(scene, grid, t, tri, height_of(s.x));
        maps.normal[base + t] = triangles.normal[tri];
        maps.object[base + t] = triangles.object[tri];
        if (l > 0) maps.ceiling[base + t] = maps.ground[base - texels + t];
      }
    });
    progress.update(l + 1);
  }
  progress.finish();
  glBindTextureUnit(SNOW_PEEL_PREV_TEXTURE, 0);
  if (maps.layers == 0) maps.add_layer();
  maps.drop_empty_layers();  // a pass can find only triangles out of range
  warn_overflow(maps, settings.layers);
  return maps;
}

}  // namespace

double time_depth_passes(const Scene& scene, int width, int height, int passes, bool indexed) {
  if (width < 1 || height < 1 || passes < 1 || scene.bounds.empty()) return 0.0;
  GlStateGuard state;
  GpuScene gpu(scene, indexed);
  gl::Program program({"shadow.vert", "depth_only.frag"});
  gl::Renderbuffer depth = gl::create_renderbuffer();
  glNamedRenderbufferStorage(depth.id(), GL_DEPTH_COMPONENT32F, width, height);
  gl::check_error("depth pass buffer");
  gl::Framebuffer fbo = gl::create_framebuffer();
  glNamedFramebufferRenderbuffer(fbo.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth.id());
  glNamedFramebufferDrawBuffer(fbo.id(), GL_NONE);
  gl::check_framebuffer(fbo, "depth pass framebuffer");
  const Bounds& b = scene.bounds;
  program.set("shear_origin", glm::vec4(0.0f, 0.0f, b.min.x, b.min.z));
  program.set("map_extent", glm::vec2(std::max(1e-6f, b.size().x), std::max(1e-6f, b.size().z)));
  program.set("y_top", b.max.y + 1e-3f);
  program.set("y_range", b.size().y + 2e-3f);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo.id());
  glViewport(0, 0, width, height);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  program.use();
  glFinish();
  const double start = now_seconds();
  for (int p = 0; p < passes; ++p) {
    const GLfloat clear_depth = 1.0f;
    glClearBufferfv(GL_DEPTH, 0, &clear_depth);
    gpu.draw();
  }
  glFinish();
  const double seconds = now_seconds() - start;
  gl::check_error("depth passes");
  return seconds;
}

}  // namespace snow

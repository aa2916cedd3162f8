// The peel stage's GPU backend: depth peeling from straight above.
// Tokoi, "A Shadow Buffer Technique for Simulating Snow-Covered Shapes"
// (2006), section 3; depth peeling after Everitt, "Interactive
// Order-Independent Transparency" (2001); one surface per layer, top down,
// as the height spans of Onoue and Nishita (2004).
#include "snow/peel.h"

#include <algorithm>
#include <cmath>
#include <cstring>
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
#include "shaders/bindings.h"
#include "snow/gpu_scene.h"
#include "snow/peel/internal.h"
#include "snow/reference/peel_ref.h"

namespace snow {
namespace {

constexpr float kEmptyHeight = -3.0e38f;  // "no surface" in the peel targets
constexpr size_t kChunk = 1 << 14;        // texels per task of a layer's copy into the maps

// The height of triangle `tri` at texel t's centre, worked out as the CPU
// peel's ray does (snow::reference::ColumnWeights), in place of `drawn`, the
// height the GPU interpolated there. A GPU may snap the corners to its
// sub-pixel grid before it interpolates; its heights would then leave
// receivers shaded by their own surface, which the sky cull could not
// settle. This makes the maps of every GPU those of the CPU's rays, up to
// ties on triangle edges. Clamped to the triangle's heights, for a centre
// the fill rule gave the triangle though the ray misses it by a rounding.
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

// Throws InputError where a side of the grid exceeds GL_MAX_TEXTURE_SIZE.
void check_texture_size(const MapGrid& grid) {
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (max_size > 0 && (grid.width > max_size || grid.height > max_size)) {
    const double suggest =
        peel::nice_ceil(grid.texel * double(std::max(grid.width, grid.height)) / max_size * 1.05);
    throw InputError("maps of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                     " texels exceed this GL's largest texture (" + std::to_string(max_size) +
                     "); use a coarser texel size, e.g. --texel " + peel::format_metres(suggest));
  }
}

// What the passes write on the CPU side: the maps (no layers yet, capacity
// for all L), the readback of one pass and the triangles' attributes.
struct PeelOutput {
  SnowMaps maps;
  std::vector<glm::uvec2> surface;  // readback: (height bits, triangle)
  TriangleAttributes triangles;     // normal and object, as written into the maps
};

// Layers are added as passes find surfaces, in capacity reserved for all L:
// the layers a scene does not fill are never touched. Throws InputError when
// memory runs out.
PeelOutput allocate_output(const Scene& scene, const MapGrid& grid, int layers) {
  PeelOutput out;
  try {
    out.maps.allocate(grid, 0);
    out.maps.reserve_layers(layers);
    out.surface.resize(grid.texels());
    out.triangles = triangle_attributes(scene);
  } catch (const std::bad_alloc&) {
    throw InputError("out of memory allocating maps of " + std::to_string(grid.width) + " x " +
                     std::to_string(grid.height) + " texels x " + std::to_string(layers) +
                     " layers; use a coarser texel size");
  }
  return out;
}

// The passes' render targets: two ping-pong RG32UI surfaces (height bits,
// triangle; a pass reads the previous layer from the other one) sharing one
// depth buffer, and the query that tells whether a pass drew anything.
struct PeelTargets {
  gl::Texture surface[2];
  gl::Framebuffer fbo[2];
  gl::Renderbuffer depth;
  gl::Query query;

  explicit PeelTargets(const MapGrid& grid) : depth(gl::create_renderbuffer()) {
    glNamedRenderbufferStorage(depth.id(), GL_DEPTH_COMPONENT32F, grid.width, grid.height);
    gl::check_error("peel depth buffer");
    for (int s = 0; s < 2; ++s) {
      surface[s] = gl::create_texture_2d(GL_RG32UI, grid.width, grid.height, "peel surface");
      fbo[s] = gl::create_framebuffer();
      glNamedFramebufferTexture(fbo[s].id(), GL_COLOR_ATTACHMENT0, surface[s].id(), 0);
      glNamedFramebufferRenderbuffer(fbo[s].id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth.id());
      glNamedFramebufferDrawBuffer(fbo[s].id(), GL_COLOR_ATTACHMENT0);
      gl::check_framebuffer(fbo[s], "peel framebuffer");
    }
    query = gl::create_query(GL_ANY_SAMPLES_PASSED);
  }
};

// The uniforms and fixed state of the passes: the scene's heights map to
// depth 0..1 from a little above its top, every triangle counts whatever its
// winding; `program` is left in use.
void set_pass_state(const gl::Program& program, const Scene& scene, const MapGrid& grid,
                    float merge_distance) {
  const double pad = 1e-3 * std::max(1.0f, scene.bounds.size().y) + 1e-3;
  const float y_top = float(scene.bounds.max.y + pad);
  const float y_range = float(double(scene.bounds.max.y) - scene.bounds.min.y + 2 * pad);
  program.set("grid_origin", grid.origin);
  program.set("grid_extent", glm::vec2(grid.width * grid.texel, grid.height * grid.texel));
  program.set("y_top", y_top);
  program.set("y_range", y_range);
  program.set("merge_distance", merge_distance);

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
}

uint32_t float_bits(float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  return bits;
}

float bits_float(uint32_t bits) {
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

// Pass l into targets.surface[l % 2], keeping per texel the highest surface
// more than merge_distance below layer l-1; returns whether it drew any
// sample (else this and every lower layer are empty).
bool draw_pass(const GpuScene& gpu, const gl::Program& program, const PeelTargets& targets, int l) {
  const int cur = l % 2;
  glBindFramebuffer(GL_FRAMEBUFFER, targets.fbo[cur].id());
  const GLuint clear_surface[4] = {float_bits(kEmptyHeight), 0u, 0u, 0u};
  const GLfloat clear_depth = 1.0f;
  glClearBufferuiv(GL_COLOR, 0, clear_surface);
  glClearBufferfv(GL_DEPTH, 0, &clear_depth);
  glBindTextureUnit(SNOW_PEEL_PREV_TEXTURE, targets.surface[1 - cur].id());
  program.set("first_layer", l == 0 ? 1 : 0);
  glBeginQuery(GL_ANY_SAMPLES_PASSED, targets.query.id());
  gpu.draw();
  glEndQuery(GL_ANY_SAMPLES_PASSED);
  gl::check_error("peel pass");
  GLuint any = 0;
  glGetQueryObjectuiv(targets.query.id(), GL_QUERY_RESULT, &any);
  return any != 0;
}

// Layer l of the maps from the read-back surface, on all cores: the exact
// height, the normal and the object of each texel's triangle, and the
// ceiling (layer l-1's ground).
void copy_layer(const Scene& scene, const MapGrid& grid, PeelOutput& out, int l) {
  SnowMaps& maps = out.maps;
  const size_t texels = grid.texels();
  const uint32_t empty_bits = float_bits(kEmptyHeight);
  maps.add_layer();
  const size_t base = size_t(l) * texels;
  parallel_for_ranges(texels, kChunk, [&](size_t begin, size_t end) {
    for (size_t t = begin; t < end; ++t) {
      const glm::uvec2& s = out.surface[t];
      const uint32_t tri = s.y;
      if (s.x == empty_bits || tri >= out.triangles.normal.size()) continue;
      maps.ground[base + t] = exact_height(scene, grid, t, tri, bits_float(s.x));
      maps.normal[base + t] = out.triangles.normal[tri];
      maps.object[base + t] = out.triangles.object[tri];
      if (l > 0) maps.ceiling[base + t] = maps.ground[base - texels + t];
    }
  });
}

// Passes 0..L until one draws nothing: each read back into the maps, the
// pass after the last layer only counting the columns that hold one surface
// more. Reports progress.
void run_passes(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                const GpuScene& gpu, const gl::Program& program, const PeelTargets& targets,
                PeelOutput& out) {
  Progress progress("peel", settings.layers);
  const size_t texels = grid.texels();
  if (texels * sizeof(glm::uvec2) > size_t(0x7fffffff)) {
    throw InputError("maps of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                     " texels are too large to read back; use a coarser texel size");
  }
  const GLsizei surface_bytes = GLsizei(texels * sizeof(glm::uvec2));
  const uint32_t empty_bits = float_bits(kEmptyHeight);
  for (int l = 0; l <= settings.layers; ++l) {
    if (!draw_pass(gpu, program, targets, l)) break;  // this and every lower layer is empty
    glGetTextureImage(targets.surface[l % 2].id(), 0, GL_RG_INTEGER, GL_UNSIGNED_INT, surface_bytes,
                      out.surface.data());
    gl::check_error("peel readback");
    if (l == settings.layers) {
      // One layer too many: count the columns that hold it.
      for (const glm::uvec2& s : out.surface) out.maps.overflow_columns += s.x != empty_bits;
      break;
    }
    copy_layer(scene, grid, out, l);
    progress.update(l + 1);
  }
  progress.finish();
  glBindTextureUnit(SNOW_PEEL_PREV_TEXTURE, 0);
}

}  // namespace

namespace peel {

SnowMaps peel_on_gpu(const Scene& scene, const MapGrid& grid, const PeelSettings& settings) {
  gl::require_context();
  check_texture_size(grid);
  PeelOutput out = allocate_output(scene, grid, settings.layers);
  if (scene.triangle_count() == 0 || scene.bounds.empty()) {
    out.maps.add_layer();
    return std::move(out.maps);
  }
  GlStateGuard state;
  GpuScene gpu(scene);
  gl::Program program({"peel.vert", "peel.frag"});
  PeelTargets targets(grid);
  set_pass_state(program, scene, grid, settings.merge_distance);
  run_passes(scene, grid, settings, gpu, program, targets, out);
  SnowMaps& maps = out.maps;
  if (maps.layers == 0) maps.add_layer();
  maps.drop_empty_layers();  // a pass can find only triangles out of range
  return std::move(maps);
}

}  // namespace peel

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

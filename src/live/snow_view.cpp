// Live snow surface: a displaced grid per snow amount map layer (Tokoi 2006,
// section 3: the maps are heightfields over the ground), read from the
// stabilizer's depth texture every frame; falling flakes as points.
#include "live/snow_view.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "shaders/live_bindings.h"
#include "snow/coverage.h"

namespace snow::live {

int auto_stride(int width, int height, int max_drawn) {
  const int side = std::max({width, height, 1});
  max_drawn = std::max(max_drawn, 1);
  return std::max(1, (side + max_drawn - 1) / max_drawn);
}

namespace {

/// Levels of detail of the grid: strides stride, 2 stride, ..., 2^(kLevels-1)
/// stride; a chunk is kChunkQuads quads of the coarsest level on a side, so
/// every level's quads tile it.
constexpr int kLevels = 5;
constexpr int kChunkQuads = 2;
/// Skirts: a chunk's border edges hang this many of their level's strides
/// (in texels) down, covering the cracks where a finer chunk meets a
/// coarser one (a coarse edge skips the fine vertices between its ends).
constexpr float kSkirtStrides = 2.0f;

/// The quads (two triangles each) of `level` in the chunk whose first
/// texel is (i0, j0) of layer l, plus skirts on its border edges, appended
/// to `out`. Vertex ids: the maps' index; skirt vertices add
/// (level + 1) x texels.
void append_chunk(const SnowMaps& maps, int l, int i0, int j0, int side, int stride, int level,
                  std::vector<uint32_t>& out) {
  const int w = maps.grid.width, h = maps.grid.height;
  const float cut = kSnowSurfaceCutTexels * maps.grid.texel * float(stride);
  const size_t skirt = size_t(level + 1) * maps.grid.texels() * size_t(maps.layers);
  for (int j = j0; j < j0 + side && j + stride < h; j += stride) {
    for (int i = i0; i < i0 + side && i + stride < w; i += stride) {
      const size_t a = maps.index(l, i, j), b = maps.index(l, i + stride, j),
                   c = maps.index(l, i, j + stride), d = maps.index(l, i + stride, j + stride);
      const float ya = maps.ground[a], yb = maps.ground[b], yc = maps.ground[c],
                  yd = maps.ground[d];
      if (std::isnan(ya) || std::isnan(yb) || std::isnan(yc) || std::isnan(yd)) continue;
      const float lo = std::min({ya, yb, yc, yd}), hi = std::max({ya, yb, yc, yd});
      if (hi - lo > cut) continue;
      for (size_t v : {a, b, c, c, b, d}) out.push_back(uint32_t(v));
      // Border edges (u, v) get a wall down to (u', v').
      auto wall = [&](size_t u, size_t v) {
        for (size_t x : {u, v, u + skirt, u + skirt, v, v + skirt}) out.push_back(uint32_t(x));
      };
      if (i == i0) wall(a, c);
      if (i + stride >= i0 + side) wall(b, d);
      if (j == j0) wall(a, b);
      if (j + stride >= j0 + side) wall(c, d);
    }
  }
}

}  // namespace

struct SnowView::Gpu {
  gl::Program snow{"live_snow.vert", "live_snow.frag"};
  gl::Program flakes{"live_flakes.vert", "live_flakes.frag"};
  gl::VertexArray vao = gl::create_vertex_array();  // no attributes: gl_VertexID only
  gl::Texture ground, coverage;
  gl::Buffer indices;
  /// A chunk of one layer: its ground's box and its index ranges per level.
  struct Chunk {
    glm::vec3 lo, hi;                       // metres, the ground's (snow adds above hi)
    std::array<size_t, kLevels + 1> first;  // indices of level k: first[k] .. first[k + 1]
  };
  std::vector<Chunk> chunks;
  MapGrid grid;
  int layers = 0;
  int stride = 1;
  float lift = 0.002f;  // metres
  mutable size_t drawn = 0;
  // The last draw's chunk index ranges (kept to spare an allocation a frame).
  mutable std::vector<GLsizei> counts;
  mutable std::vector<const void*> offsets;
};

SnowView::SnowView() : gpu_(std::make_unique<Gpu>()) {}
SnowView::~SnowView() = default;

void SnowView::set_maps(const SnowMaps& maps, int stride) {
  Gpu& g = *gpu_;
  if (stride < 1) throw InputError("snow grid stride must be at least 1 texel");
  const int w = maps.grid.width, h = maps.grid.height, layers = maps.layers;
  const size_t texels = size_t(layers) * maps.grid.texels();
  if (texels * size_t(kLevels + 1) >= (size_t(1) << 31) || w < 1 || h < 1 || layers < 1)
    throw InputError("maps of " + std::to_string(w) + " x " + std::to_string(h) + " x " +
                     std::to_string(layers) + " texels are too large for the live view");
  if (maps.ground.size() != texels) throw InputError("live view: maps' ground has a wrong size");

  std::vector<glm::vec2> ground(texels);
  for (size_t k = 0; k < texels; ++k) {
    const float y = maps.ground[k];
    ground[k] = std::isnan(y) ? glm::vec2(0.0f) : glm::vec2(y, 1.0f);
  }
  g.ground = gl::create_texture_2d_array(GL_RG32F, w, h, layers, "live view ground");
  glTextureSubImage3D(g.ground.id(), 0, 0, 0, 0, w, h, layers, GL_RG, GL_FLOAT, ground.data());
  g.coverage = gl::create_texture_2d_array(GL_R32F, w, h, layers, "live view coverage");

  // Chunks of side texels per layer, each with its quads at every level.
  const int side = stride * kChunkQuads << (kLevels - 1);
  std::vector<uint32_t> indices;
  g.chunks.clear();
  for (int l = 0; l < layers; ++l) {
    for (int j0 = 0; j0 < h; j0 += side) {
      for (int i0 = 0; i0 < w; i0 += side) {
        Gpu::Chunk chunk;
        chunk.lo = glm::vec3(std::numeric_limits<float>::max());
        chunk.hi = glm::vec3(-std::numeric_limits<float>::max());
        for (int j = j0; j < std::min(j0 + side + 1, h); ++j) {
          for (int i = i0; i < std::min(i0 + side + 1, w); ++i) {
            const float y = maps.ground[maps.index(l, i, j)];
            if (std::isnan(y)) continue;
            const glm::vec2 xz = maps.grid.center(i, j);
            chunk.lo = glm::min(chunk.lo, glm::vec3(xz.x, y, xz.y));
            chunk.hi = glm::max(chunk.hi, glm::vec3(xz.x, y, xz.y));
          }
        }
        if (chunk.lo.x > chunk.hi.x) continue;  // no surface
        const size_t before = indices.size();
        for (int level = 0; level < kLevels; ++level) {
          chunk.first[size_t(level)] = indices.size();
          append_chunk(maps, l, i0, j0, side, stride << level, level, indices);
        }
        chunk.first[kLevels] = indices.size();
        if (indices.size() == before) continue;
        g.chunks.push_back(chunk);
      }
    }
  }
  g.indices = gl::create_buffer();
  glNamedBufferStorage(g.indices.id(), GLsizeiptr(std::max<size_t>(indices.size(), 1) * 4),
                       indices.empty() ? nullptr : indices.data(), 0);
  glVertexArrayElementBuffer(g.vao.id(), g.indices.id());
  g.grid = maps.grid;
  g.layers = layers;
  g.stride = stride;
  g.lift = std::max(1e-4f, 0.02f * maps.grid.texel);
  gl::check_error("live view: uploading the maps");
}

void SnowView::set_coverage(const std::vector<float>& coverage) {
  Gpu& g = *gpu_;
  if (!g.coverage || coverage.size() != size_t(g.layers) * g.grid.texels())
    throw InputError("live view: coverage has " + std::to_string(coverage.size()) +
                     " values, not one per layer texel");
  glTextureSubImage3D(g.coverage.id(), 0, 0, 0, 0, g.grid.width, g.grid.height, g.layers, GL_RED,
                      GL_FLOAT, coverage.data());
  gl::check_error("live view: uploading the coverage");
}

size_t SnowView::triangle_count() const {
  size_t indices = 0;
  for (const Gpu::Chunk& c : gpu_->chunks) indices += c.first[1] - c.first[0];
  return indices / 3;
}

size_t SnowView::drawn_triangles() const { return gpu_->drawn; }

namespace {

/// Corner k (0..7) of the box [lo, hi].
glm::vec3 corner(const glm::vec3& lo, const glm::vec3& hi, int k) {
  return glm::vec3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
}

/// Whether the box [lo, hi] lies wholly outside one plane of the view
/// volume of `view_projection`.
bool outside_view(const glm::mat4& view_projection, const glm::vec3& lo, const glm::vec3& hi) {
  int out[6] = {0, 0, 0, 0, 0, 0};
  for (int k = 0; k < 8; ++k) {
    const glm::vec4 p = view_projection * glm::vec4(corner(lo, hi, k), 1.0f);
    out[0] += p.x < -p.w;
    out[1] += p.x > p.w;
    out[2] += p.y < -p.w;
    out[3] += p.y > p.w;
    out[4] += p.z < -p.w;
    out[5] += p.z > p.w;
  }
  return std::any_of(out, out + 6, [](int n) { return n == 8; });
}

/// The coarsest level (0..kLevels-1) whose quads, `stride` << level texels
/// of `texel` metres, span at most `quad_pixels` on screen at the box's
/// nearest point; 0 where even the finest spans more.
int level_for(const render::PreviewCamera& camera, int viewport_height, const glm::vec3& lo,
              const glm::vec3& hi, float texel, int stride, float quad_pixels) {
  // Pixels per metre at eye depth z: projection[1][1] x height / 2 / z
  // (orthographic: without the division).
  float z = 1.0f;
  if (!camera.orthographic) {
    z = std::numeric_limits<float>::max();
    for (int k = 0; k < 8; ++k)
      z = std::min(z, glm::dot(corner(lo, hi, k) - camera.eye, camera.forward));
    if (!(z > 1e-3f)) return 0;
  }
  const float pixels = camera.projection[1][1] * 0.5f * float(viewport_height) / z * texel;
  int level = 0;
  while (level + 1 < kLevels && float(stride << (level + 1)) * pixels <= quad_pixels) ++level;
  return level;
}

}  // namespace

void SnowView::draw(const render::PreviewCamera& camera, int viewport_height,
                    const render::PreviewSettings& shading, unsigned depth_texture, float max_snow,
                    const SnowViewSettings& settings) const {
  const Gpu& g = *gpu_;
  g.drawn = 0;
  if (g.chunks.empty()) return;
  const gl::Program& p = g.snow;
  p.use();
  p.set("u_view_projection", camera.view_projection());
  p.set("u_size", glm::ivec2(g.grid.width, g.grid.height));
  p.set("u_origin", g.grid.origin);
  p.set("u_texel", g.grid.texel);
  p.set("u_min_depth", std::min(settings.min_depth, 0.05f * g.grid.texel));
  p.set("u_lift", g.lift);
  const int overlay = int(settings.overlay);
  p.set("u_overlay", overlay);
  p.set("u_overlay_max", settings.overlay == Overlay::Depth ? settings.depth_ramp_max : 1.0f);
  p.set("u_eye", camera.eye);
  p.set("u_forward", camera.forward);
  p.set("u_orthographic", camera.orthographic ? 1 : 0);
  p.set("u_sun_direction", glm::normalize(shading.sun_direction));
  p.set("u_sun_radiance", shading.sun_radiance);
  p.set("u_sky_ambient", shading.sky_ambient);
  p.set("u_snow_color", settings.snow_color);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glBindTextureUnit(SNOW_LIVE_GROUND, g.ground.id());
  glBindTextureUnit(SNOW_LIVE_DEPTH, depth_texture);
  glBindTextureUnit(SNOW_LIVE_COVERAGE, g.coverage.id());
  p.set("u_texels", int(size_t(g.layers) * g.grid.texels()));
  p.set("u_skirt_drop", kSkirtStrides * g.grid.texel * float(g.stride));

  // Chunks in view, each at its level of detail.
  const glm::mat4 view_projection = camera.view_projection();
  std::vector<GLsizei>& counts = g.counts;
  std::vector<const void*>& offsets = g.offsets;
  counts.clear();
  offsets.clear();
  g.drawn = 0;
  for (const Gpu::Chunk& c : g.chunks) {
    const glm::vec3 hi = c.hi + glm::vec3(0.0f, std::max(max_snow, 0.0f), 0.0f);
    const glm::vec3 lo =
        c.lo -
        glm::vec3(0.0f, kSkirtStrides * g.grid.texel * float(g.stride << (kLevels - 1)), 0.0f);
    if (outside_view(view_projection, lo, hi)) continue;
    // The level from the ground's box: the snow on it is near enough.
    const int level = level_for(camera, viewport_height, c.lo, c.hi, g.grid.texel, g.stride,
                                settings.quad_pixels);
    const size_t first = c.first[size_t(level)], count = c.first[size_t(level) + 1] - first;
    if (count == 0) continue;
    counts.push_back(GLsizei(count));
    offsets.push_back(reinterpret_cast<const void*>(first * sizeof(uint32_t)));
    g.drawn += count / 3;
  }
  glBindVertexArray(g.vao.id());
  glMultiDrawElements(GL_TRIANGLES, counts.data(), GL_UNSIGNED_INT, offsets.data(),
                      GLsizei(counts.size()));
  glBindVertexArray(0);
  for (GLuint unit : {SNOW_LIVE_GROUND, SNOW_LIVE_DEPTH, SNOW_LIVE_COVERAGE})
    glBindTextureUnit(unit, 0);
  gl::check_error("live view: drawing the snow");
}

void SnowView::draw_flakes(const render::PreviewCamera& camera, const Bounds& box, float time,
                           float fall_speed, const glm::vec2& wind,
                           const SnowViewSettings& settings) const {
  const Gpu& g = *gpu_;
  if (settings.flakes <= 0 || box.empty()) return;
  const gl::Program& p = g.flakes;
  p.use();
  p.set("u_view_projection", camera.view_projection());
  p.set("u_box_min", box.min);
  p.set("u_box_max", box.max);
  p.set("u_time", time);
  p.set("u_fall_speed", std::max(fall_speed, 0.05f));
  p.set("u_wind", wind);
  p.set("u_flutter", 0.01f * glm::length(box.size()));
  p.set("u_point_size", settings.flake_size);
  glEnable(GL_DEPTH_TEST);
  glEnable(GL_PROGRAM_POINT_SIZE);
  glBindVertexArray(g.vao.id());
  glDrawArrays(GL_POINTS, 0, settings.flakes);
  glBindVertexArray(0);
  glDisable(GL_PROGRAM_POINT_SIZE);
  gl::check_error("live view: drawing the flakes");
}

}  // namespace snow::live

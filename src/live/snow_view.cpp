// Live snow surface: a displaced grid per snow amount map layer (Tokoi 2006,
// section 3: the maps are heightfields over the ground), read from the
// stabilizer's depth texture every frame; falling flakes as points.
#include "live/snow_view.h"

#include <algorithm>
#include <cmath>
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

struct SnowView::Gpu {
  gl::Program snow{"live_snow.vert", "live_snow.frag"};
  gl::Program flakes{"live_flakes.vert", "live_flakes.frag"};
  gl::VertexArray vao = gl::create_vertex_array();  // no attributes: gl_VertexID only
  gl::Texture ground, coverage;
  gl::Buffer indices;
  size_t index_count = 0;
  MapGrid grid;
  int layers = 0;
  float lift = 0.002f;  // metres
};

SnowView::SnowView() : gpu_(std::make_unique<Gpu>()) {}
SnowView::~SnowView() = default;

void SnowView::set_maps(const SnowMaps& maps, int stride) {
  Gpu& g = *gpu_;
  if (stride < 1) throw InputError("snow grid stride must be at least 1 texel");
  const int w = maps.grid.width, h = maps.grid.height, layers = maps.layers;
  const size_t texels = size_t(layers) * maps.grid.texels();
  if (texels >= (size_t(1) << 31) || w < 1 || h < 1 || layers < 1)
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

  // Quads between texel centres `stride` apart, within one layer.
  const float cut = kSnowSurfaceCutTexels * maps.grid.texel * float(stride);
  std::vector<uint32_t> indices;
  for (int l = 0; l < layers; ++l) {
    for (int j = 0; j + stride < h; j += stride) {
      for (int i = 0; i + stride < w; i += stride) {
        const size_t a = maps.index(l, i, j), b = maps.index(l, i + stride, j),
                     c = maps.index(l, i, j + stride), d = maps.index(l, i + stride, j + stride);
        const float ya = maps.ground[a], yb = maps.ground[b], yc = maps.ground[c],
                    yd = maps.ground[d];
        if (std::isnan(ya) || std::isnan(yb) || std::isnan(yc) || std::isnan(yd)) continue;
        const float lo = std::min({ya, yb, yc, yd}), hi = std::max({ya, yb, yc, yd});
        if (hi - lo > cut) continue;
        for (size_t v : {a, b, c, c, b, d}) indices.push_back(uint32_t(v));
      }
    }
  }
  g.indices = gl::create_buffer();
  glNamedBufferStorage(g.indices.id(), GLsizeiptr(std::max<size_t>(indices.size(), 1) * 4),
                       indices.empty() ? nullptr : indices.data(), 0);
  glVertexArrayElementBuffer(g.vao.id(), g.indices.id());
  g.index_count = indices.size();
  g.grid = maps.grid;
  g.layers = layers;
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

size_t SnowView::triangle_count() const { return gpu_->index_count / 3; }

void SnowView::draw(const render::PreviewCamera& camera, const render::PreviewSettings& shading,
                    unsigned depth_texture, const SnowViewSettings& settings) const {
  const Gpu& g = *gpu_;
  if (g.index_count == 0) return;
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
  glBindVertexArray(g.vao.id());
  glDrawElements(GL_TRIANGLES, GLsizei(g.index_count), GL_UNSIGNED_INT, nullptr);
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

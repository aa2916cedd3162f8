#pragma once
// Drawing the live snow straight from the GPU maps: per map layer a grid
// through the texel centres, displaced to the snow surface ground + depth
// read from the stabilizer's depth texture in the vertex shader (no
// readback), with the preview's shading (render/preview.h) or a coverage or
// depth overlay; and falling flakes as points (a visual cue only).
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "render/camera.h"
#include "render/preview.h"
#include "scene/scene.h"
#include "snow/maps.h"

namespace snow::live {

enum class Overlay { None, Coverage, Depth };

struct SnowViewSettings {
  Overlay overlay = Overlay::None;
  float depth_ramp_max = 0.5f;  // metres of depth at the top of the depth overlay's colour ramp
  float min_depth = 0.002f;     // metres: thinner snow is drawn as bare (at most 5 % of a texel)
  glm::vec3 snow_color{0.92f, 0.94f, 0.97f};  // linear albedo of snow
  float quad_pixels = 4.0f;  // level of detail: the grid's quads span about this many pixels
                             // (no finer than the grid's stride; plan::preview_quad_pixels)
  int flakes = 3000;         // falling flakes drawn (0 = none)
  float flake_size = 2.0f;   // pixels
};

/// The texels between drawn grid vertices for a map of `width` x `height`
/// texels when the stride is automatic: the smallest s >= 1 with
/// max(width, height) / s <= max_drawn.
int auto_stride(int width, int height, int max_drawn = 768);

/// GPU snow surface and flakes. Construct, use and destroy with the same GL
/// context current.
class SnowView {
 public:
  SnowView();
  ~SnowView();
  SnowView(const SnowView&) = delete;
  SnowView& operator=(const SnowView&) = delete;

  /// Uploads the maps' ground heights and builds the grid's index buffer:
  /// per layer, square chunks of quads of one layer whose four corners have
  /// a surface with heights within kSnowSurfaceCutTexels texels (of the
  /// quad's stride) of each other, at levels of detail of vertices every
  /// `stride` (>= 1), 2 stride, ... 16 stride texels, the border of each
  /// chunk hanging a skirt (a short wall down) over the cracks where levels
  /// meet. Throws InputError for a stride below 1 or maps over 2^31 / 6
  /// layer texels, GLError on GL trouble.
  void set_maps(const SnowMaps& maps, int stride);
  /// Uploads the coverage (maps' layout) for the coverage overlay. Throws
  /// InputError for a wrong size.
  void set_coverage(const std::vector<float>& coverage);
  /// Triangles of the grid at its finest level (snowy or not, skirts
  /// included).
  size_t triangle_count() const;
  /// Triangles the last draw() drew.
  size_t drawn_triangles() const;

  /// Draws the snow surface from `depth_texture` (the stabilizer's RG32F
  /// array, depth in r) into the bound framebuffer (`viewport_height`
  /// pixels high) with depth test on: the chunks in view, each at the
  /// coarsest level whose quads span at most settings.quad_pixels at its
  /// nearest point. `max_snow`: metres the snow may stand above the ground
  /// (the chunks' boxes for culling).
  void draw(const render::PreviewCamera& camera, int viewport_height,
            const render::PreviewSettings& shading, unsigned depth_texture, float max_snow,
            const SnowViewSettings& settings) const;
  /// Draws settings.flakes points falling through `box` at `fall_speed`
  /// (m/s), drifting with `wind` (m/s, x and z), at simulated `time` (s).
  void draw_flakes(const render::PreviewCamera& camera, const Bounds& box, float time,
                   float fall_speed, const glm::vec2& wind, const SnowViewSettings& settings) const;

 private:
  struct Gpu;
  std::unique_ptr<Gpu> gpu_;
};

}  // namespace snow::live

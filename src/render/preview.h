#pragma once
// Headless preview images of a scene, optionally with extra meshes (snow) on
// top: Lambert shading with one sun plus sky ambient, glTF baseColorFactor
// times the baseColor texture, gamma-correct (sRGB) output, rendered into a
// multisampled framebuffer object. Needs a current GL context
// (snow::gl::create_context).
#include <filesystem>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "core/trimesh.h"
#include "render/camera.h"
#include "render/image.h"
#include "scene/scene.h"

namespace snow::render {

/// Auto MSAA (PreviewSettings::samples = 0) renders scenes with more
/// triangles than this with 1 sample on a software renderer.
constexpr size_t kSoftwareMsaaTriangleLimit = 500000;

struct PreviewSettings {
  int width = 1280;                // image width, pixels
  int height = 800;                // image height, pixels
  View view = View::ThreeQuarter;  // camera
  glm::vec3 background{0.80f, 0.85f,
                       0.90f};  // sRGB colour (0..1) where nothing is drawn; darker than lit snow
  // MSAA samples per pixel, clamped to GL_MAX_SAMPLES; 1 = off; 0 = auto: 4,
  // but 1 on a software renderer (llvmpipe) for more than
  // kSoftwareMsaaTriangleLimit triangles, where each sample costs as much
  // as a pixel.
  int samples = 0;
  float fov = 35.0f;        // vertical field of view of ThreeQuarter, degrees
  float azimuth = 45.0f;    // ThreeQuarter camera: degrees from south (+Z) towards east (+X)
  float elevation = 35.0f;  // ThreeQuarter camera: degrees above the horizon
  float margin = 0.04f;     // free border around the framed bounds, fraction of the image
  glm::vec3 sun_direction{-0.45f, 0.8f, 0.4f};  // towards the sun (world; normalised here)
  glm::vec3 sun_radiance{0.66f, 0.64f, 0.6f};   // linear RGB light of the sun on a facing surface
  glm::vec3 sky_ambient{0.28f, 0.31f, 0.36f};   // linear RGB sky light on an upward surface
  glm::vec4 default_color{0.7f, 0.7f, 0.7f, 1.0f};  // linear base colour of unmaterialed objects
};

/// The shading contract, also used by tests as the CPU reference: linear RGB
/// of a surface with linear `albedo` and unit `normal` (facing the viewer):
///   albedo * (sun_radiance * max(0, n . sun) + sky_ambient * (0.65 + 0.35 n.y))
glm::vec3 shade_linear(const glm::vec3& albedo, const glm::vec3& normal,
                       const PreviewSettings& settings);
/// sRGB transfer function (IEC 61966-2-1) of one channel, 0..1 in and out.
float srgb_encode(float linear);
float srgb_decode(float encoded);

/// The camera of settings.view for `bounds`: ThreeQuarter is
/// orbit_camera_fit() on `points` (orbit_camera() when there are none),
/// Top is top_camera().
PreviewCamera preview_camera(const Bounds& bounds, const PreviewSettings& settings,
                             const PointSets& points = {});

/// GPU copy of a scene (and extra meshes) that draws with any camera: the
/// one-off render_preview uses it, the live viewer keeps one between frames.
/// Construct, use and destroy with the same context current.
class PreviewRenderer {
 public:
  /// Uploads the scene's triangles and the baseColor textures its materials
  /// use. Throws GLError (GL_OUT_OF_MEMORY included) on GL trouble. Skips
  /// (with a warning naming it) a texture whose image is empty or missing.
  explicit PreviewRenderer(const Scene& scene);
  ~PreviewRenderer();
  PreviewRenderer(PreviewRenderer&&) noexcept;
  PreviewRenderer& operator=(PreviewRenderer&&) noexcept;
  PreviewRenderer(const PreviewRenderer&) = delete;
  PreviewRenderer& operator=(const PreviewRenderer&) = delete;

  /// Replaces the extra meshes (e.g. snow), drawn with `colors[i]` (linear
  /// RGBA base colour; alpha ignored) or, when `colors` has one entry,
  /// that colour for all. Meshes without normals get smooth ones. Throws
  /// InputError if `colors` is empty while meshes are not, or has another
  /// size than 1 or meshes.size(), or if a mesh has an index out of range.
  void set_extra_meshes(const std::vector<TriMesh>& meshes, const std::vector<glm::vec4>& colors);

  /// Triangles of the extra meshes.
  size_t extra_triangle_count() const;

  /// Bounds of the scene and the extra meshes.
  Bounds bounds() const;

  /// Draws scene and extra meshes into the bound draw framebuffer (the
  /// caller sets viewport, clears colour and depth). Depth test on, no
  /// culling (both sides lit, normals turned towards the viewer).
  void draw(const PreviewCamera& camera, const PreviewSettings& settings) const;

 private:
  struct Gpu;
  std::unique_ptr<Gpu> gpu_;
};

/// The colour buffer of framebuffer `fbo` (0: the window's back buffer),
/// width x height pixels from the origin, as an image (rows top to bottom).
/// Needs a current context; throws GLError on GL trouble.
ImageRGBA8 read_framebuffer(unsigned fbo, int width, int height);

/// Renders `scene` plus `extra` meshes (each in `extra_color`, linear RGBA;
/// e.g. white for snow) into a settings.width x settings.height image with
/// the camera of settings.view framing the bounds of both. Needs a current
/// context. Throws InputError for a size below 1 pixel and GLError on GL
/// trouble (e.g. a size above GL_MAX_RENDERBUFFER_SIZE).
ImageRGBA8 render_preview(const Scene& scene, const std::vector<TriMesh>& extra,
                          const glm::vec4& extra_color, PreviewSettings settings);
/// Same with one colour per extra mesh (or one for all).
ImageRGBA8 render_preview(const Scene& scene, const std::vector<TriMesh>& extra,
                          const std::vector<glm::vec4>& extra_colors, PreviewSettings settings);

}  // namespace snow::render

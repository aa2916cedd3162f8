// Preview renderer: the scene's world-space triangles drawn once into a
// multisampled framebuffer object with Lambert shading (one sun plus sky
// ambient) and glTF base colours, resolved and read back as sRGB pixels.
#include "render/preview.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "shaders/bindings.h"

namespace snow::render {
namespace {

struct SceneRange {
  GLint first = 0;    // first vertex
  GLsizei count = 0;  // vertices
  glm::vec4 color{1.0f};
  GLuint texture = 0;  // 0: none
};

struct ExtraRange {
  GLsizei index_count = 0;
  size_t index_offset = 0;  // bytes
  GLint base_vertex = 0;
  glm::vec4 color{1.0f};
};

// Flat normals for a triangle soup (3 vertices per triangle).
std::vector<glm::vec3> flat_normals(const std::vector<glm::vec3>& positions) {
  std::vector<glm::vec3> normals(positions.size());
  for (size_t i = 0; i + 2 < positions.size(); i += 3) {
    glm::vec3 n = glm::cross(positions[i + 1] - positions[i], positions[i + 2] - positions[i]);
    const float len = glm::length(n);
    n = len > 0.0f ? n / len : glm::vec3(0, 1, 0);
    normals[i] = normals[i + 1] = normals[i + 2] = n;
  }
  return normals;
}

// Area-weighted smooth normals of an indexed mesh.
std::vector<glm::vec3> smooth_normals(const TriMesh& mesh) {
  std::vector<glm::vec3> normals(mesh.positions.size(), glm::vec3(0.0f));
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
    const glm::vec3 n =
        glm::cross(mesh.positions[b] - mesh.positions[a], mesh.positions[c] - mesh.positions[a]);
    normals[a] += n;
    normals[b] += n;
    normals[c] += n;
  }
  for (glm::vec3& n : normals) {
    const float len = glm::length(n);
    n = len > 0.0f ? n / len : glm::vec3(0, 1, 0);
  }
  return normals;
}

template <typename T>
gl::Buffer upload(const std::vector<T>& data, const char* what) {
  gl::Buffer buffer = gl::create_buffer();
  const size_t bytes = std::max<size_t>(data.size() * sizeof(T), 4);
  glNamedBufferStorage(buffer.id(), static_cast<GLsizeiptr>(bytes),
                       data.empty() ? nullptr : data.data(), 0);
  gl::check_error(what);
  return buffer;
}

void attach(GLuint vao, GLuint attr, const gl::Buffer& buffer, int components) {
  glVertexArrayVertexBuffer(vao, attr, buffer.id(), 0,
                            static_cast<GLsizei>(components * sizeof(float)));
  glEnableVertexArrayAttrib(vao, attr);
  glVertexArrayAttribFormat(vao, attr, components, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao, attr, attr);
}

gl::Texture upload_image(const Image& image, int index) {
  const std::string name = "image " + std::to_string(index) +
                           (image.name.empty() ? std::string() : " '" + image.name + "'");
  const size_t expected = static_cast<size_t>(std::max(image.width, 0)) *
                          static_cast<size_t>(std::max(image.height, 0)) * 4;
  if (image.width < 1 || image.height < 1 || image.rgba.size() != expected) {
    log_warn("preview: ignoring base colour texture " + name + " (" + std::to_string(image.width) +
             "x" + std::to_string(image.height) + ", " + std::to_string(image.rgba.size()) +
             " bytes)");
    return {};
  }
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (image.width > max_size || image.height > max_size) {
    log_warn("preview: ignoring base colour texture " + name + ": larger than " +
             std::to_string(max_size) + " pixels");
    return {};
  }
  const int levels = 1 + static_cast<int>(std::floor(
                             std::log2(static_cast<double>(std::max(image.width, image.height)))));
  gl::Texture texture = gl::create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(texture.id(), levels, GL_SRGB8_ALPHA8, image.width, image.height);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  // Rows top to bottom: row 0 lands at t = 0, which is glTF's v = 0 (top).
  glTextureSubImage2D(texture.id(), 0, 0, 0, image.width, image.height, GL_RGBA, GL_UNSIGNED_BYTE,
                      image.rgba.data());
  glGenerateTextureMipmap(texture.id());
  glTextureParameteri(texture.id(), GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTextureParameteri(texture.id(), GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTextureParameteri(texture.id(), GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTextureParameteri(texture.id(), GL_TEXTURE_WRAP_T, GL_REPEAT);
  gl::check_error(("preview: uploading " + name).c_str());
  return texture;
}

bool is_software_renderer() {
  const GLubyte* renderer = glGetString(GL_RENDERER);
  if (!renderer) return false;
  const std::string name = reinterpret_cast<const char*>(renderer);
  for (const char* software : {"llvmpipe", "softpipe", "swrast", "SwiftShader"}) {
    if (name.find(software) != std::string::npos) return true;
  }
  return false;
}

}  // namespace

float srgb_encode(float linear) {
  const float c = std::clamp(linear, 0.0f, 1.0f);
  return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

float srgb_decode(float encoded) {
  const float c = std::clamp(encoded, 0.0f, 1.0f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

glm::vec3 shade_linear(const glm::vec3& albedo, const glm::vec3& normal,
                       const PreviewSettings& settings) {
  const glm::vec3 sun = glm::normalize(settings.sun_direction);
  return albedo * (settings.sun_radiance * std::max(glm::dot(normal, sun), 0.0f) +
                   settings.sky_ambient * (0.65f + 0.35f * normal.y));
}

PreviewCamera preview_camera(const Bounds& bounds, const PreviewSettings& settings,
                             const PointSets& points) {
  const float aspect = static_cast<float>(std::max(settings.width, 1)) /
                       static_cast<float>(std::max(settings.height, 1));
  if (settings.view == View::Top) return top_camera(bounds, aspect, settings.margin);
  return orbit_camera_fit(bounds, points, settings.azimuth, settings.elevation, aspect,
                          settings.fov, settings.margin);
}

struct PreviewRenderer::Gpu {
  gl::Program program{"preview.vert", "preview.frag"};
  gl::VertexArray scene_vao;
  gl::Buffer positions, normals, uvs;
  std::vector<gl::Texture> textures;  // one per scene image; empty when unused
  std::vector<SceneRange> ranges;
  bool has_uvs = false;
  Bounds scene_bounds;

  gl::VertexArray extra_vao;
  gl::Buffer extra_positions, extra_normals, extra_indices;
  std::vector<ExtraRange> extras;
  Bounds extra_bounds;
};

PreviewRenderer::PreviewRenderer(const Scene& scene) : gpu_(std::make_unique<Gpu>()) {
  Gpu& g = *gpu_;
  const size_t vertex_count = scene.triangle_count() * 3;
  if (vertex_count > static_cast<size_t>(std::numeric_limits<GLint>::max())) {
    throw InputError("preview: scene has too many triangles (" +
                     std::to_string(scene.triangle_count()) + ")");
  }

  g.scene_bounds = scene.bounds;
  if (g.scene_bounds.empty()) {
    for (size_t i = 0; i < vertex_count; ++i) g.scene_bounds.extend(scene.positions[i]);
  }

  g.scene_vao = gl::create_vertex_array();
  if (vertex_count > 0) {
    g.positions = upload(scene.positions, "preview: uploading positions");
    g.normals = scene.normals.size() == scene.positions.size()
                    ? upload(scene.normals, "preview: uploading normals")
                    : upload(flat_normals(scene.positions), "preview: uploading normals");
    attach(g.scene_vao.id(), SNOW_ATTR_POSITION, g.positions, 3);
    attach(g.scene_vao.id(), SNOW_ATTR_NORMAL, g.normals, 3);
    g.has_uvs = scene.uvs.size() == scene.positions.size();
    if (g.has_uvs) {
      g.uvs = upload(scene.uvs, "preview: uploading uvs");
      attach(g.scene_vao.id(), SNOW_ATTR_UV, g.uvs, 2);
    }
  }

  // Textures of the images that materials use.
  g.textures.resize(scene.images.size());
  std::vector<bool> tried(scene.images.size(), false);
  auto texture_of = [&](int material) -> GLuint {
    if (!g.has_uvs || material < 0 || material >= static_cast<int>(scene.materials.size())) {
      return 0;
    }
    const int image = scene.materials[material].base_color_image;
    if (image < 0 || image >= static_cast<int>(scene.images.size())) return 0;
    if (!tried[image]) {
      tried[image] = true;
      g.textures[image] = upload_image(scene.images[image], image);
    }
    return g.textures[image].id();
  };
  auto color_of = [&](int material) -> glm::vec4 {
    if (material < 0 || material >= static_cast<int>(scene.materials.size())) {
      return glm::vec4(-1.0f);  // the settings' default colour, chosen at draw time
    }
    return scene.materials[material].base_color;
  };

  // One draw per run of consecutive objects with the same material.
  auto add_range = [&](size_t first_triangle, size_t count, int material) {
    if (count == 0) return;
    const GLint first = static_cast<GLint>(first_triangle * 3);
    if (!g.ranges.empty()) {
      SceneRange& last = g.ranges.back();
      if (last.first + last.count == first && last.color == color_of(material) &&
          last.texture == texture_of(material)) {
        last.count += static_cast<GLsizei>(count * 3);
        return;
      }
    }
    g.ranges.push_back(SceneRange{first, static_cast<GLsizei>(count * 3), color_of(material),
                                  texture_of(material)});
  };
  size_t covered = 0;
  for (const SceneObject& object : scene.objects) {
    const size_t first = std::min<size_t>(object.first_triangle, scene.triangle_count());
    const size_t end = std::min<size_t>(first + object.triangle_count, scene.triangle_count());
    if (first > covered) add_range(covered, first - covered, -1);
    add_range(first, end - first, object.material);
    covered = std::max(covered, end);
  }
  if (covered < scene.triangle_count()) {
    add_range(covered, scene.triangle_count() - covered, -1);
  }
  g.extra_vao = gl::create_vertex_array();
  gl::check_error("preview: uploading the scene");
}

PreviewRenderer::~PreviewRenderer() = default;
PreviewRenderer::PreviewRenderer(PreviewRenderer&&) noexcept = default;
PreviewRenderer& PreviewRenderer::operator=(PreviewRenderer&&) noexcept = default;

void PreviewRenderer::set_extra_meshes(const std::vector<TriMesh>& meshes,
                                       const std::vector<glm::vec4>& colors) {
  Gpu& g = *gpu_;
  if (!meshes.empty() && colors.size() != 1 && colors.size() != meshes.size()) {
    throw InputError("preview: " + std::to_string(colors.size()) + " colours for " +
                     std::to_string(meshes.size()) + " extra meshes (need 1 or one each)");
  }
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<uint32_t> indices;
  std::vector<ExtraRange> extras;
  Bounds bounds;
  for (size_t m = 0; m < meshes.size(); ++m) {
    const TriMesh& mesh = meshes[m];
    const size_t n = mesh.positions.size();
    if (mesh.indices.size() % 3 != 0) {
      throw InputError("preview: extra mesh '" + mesh.name + "' has " +
                       std::to_string(mesh.indices.size()) + " indices, not a multiple of 3");
    }
    for (uint32_t index : mesh.indices) {
      if (index >= n) {
        throw InputError("preview: extra mesh '" + mesh.name + "' has index " +
                         std::to_string(index) + " but " + std::to_string(n) + " positions");
      }
    }
    if (mesh.indices.empty()) continue;
    ExtraRange range;
    range.index_count = static_cast<GLsizei>(mesh.indices.size());
    range.index_offset = indices.size() * sizeof(uint32_t);
    range.base_vertex = static_cast<GLint>(positions.size());
    range.color = colors.size() == 1 ? colors[0] : colors[m];
    extras.push_back(range);
    positions.insert(positions.end(), mesh.positions.begin(), mesh.positions.end());
    if (mesh.normals.size() == n) {
      normals.insert(normals.end(), mesh.normals.begin(), mesh.normals.end());
    } else {
      const std::vector<glm::vec3> smooth = smooth_normals(mesh);
      normals.insert(normals.end(), smooth.begin(), smooth.end());
    }
    indices.insert(indices.end(), mesh.indices.begin(), mesh.indices.end());
    for (uint32_t index : mesh.indices) bounds.extend(mesh.positions[index]);
  }

  g.extras.clear();
  g.extra_bounds = Bounds();
  g.extra_vao = gl::create_vertex_array();
  g.extra_positions.reset();
  g.extra_normals.reset();
  g.extra_indices.reset();
  if (extras.empty()) return;
  g.extra_positions = upload(positions, "preview: uploading extra meshes");
  g.extra_normals = upload(normals, "preview: uploading extra meshes");
  g.extra_indices = upload(indices, "preview: uploading extra meshes");
  attach(g.extra_vao.id(), SNOW_ATTR_POSITION, g.extra_positions, 3);
  attach(g.extra_vao.id(), SNOW_ATTR_NORMAL, g.extra_normals, 3);
  glVertexArrayElementBuffer(g.extra_vao.id(), g.extra_indices.id());
  gl::check_error("preview: uploading extra meshes");
  g.extras = std::move(extras);
  g.extra_bounds = bounds;
}

size_t PreviewRenderer::extra_triangle_count() const {
  size_t count = 0;
  for (const ExtraRange& r : gpu_->extras) count += static_cast<size_t>(r.index_count) / 3;
  return count;
}

Bounds PreviewRenderer::bounds() const {
  Bounds b = gpu_->scene_bounds;
  if (!gpu_->extra_bounds.empty()) {
    b.extend(gpu_->extra_bounds.min);
    b.extend(gpu_->extra_bounds.max);
  }
  return b;
}

void PreviewRenderer::draw(const PreviewCamera& camera, const PreviewSettings& settings) const {
  const Gpu& g = *gpu_;
  const gl::Program& p = g.program;
  p.use();
  p.set("u_view_projection", camera.view_projection());
  p.set("u_eye", camera.eye);
  p.set("u_forward", camera.forward);
  p.set("u_orthographic", camera.orthographic ? 1 : 0);
  p.set("u_sun_direction", glm::normalize(settings.sun_direction));
  p.set("u_sun_radiance", settings.sun_radiance);
  p.set("u_sky_ambient", settings.sky_ambient);

  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);

  glBindVertexArray(g.scene_vao.id());
  if (!g.has_uvs) glVertexAttrib2f(SNOW_ATTR_UV, 0.0f, 0.0f);
  for (const SceneRange& r : g.ranges) {
    p.set("u_base_color", r.color.x < 0.0f ? settings.default_color : r.color);
    p.set("u_has_texture", r.texture ? 1 : 0);
    glBindTextureUnit(SNOW_PREVIEW_BASE_COLOR_TEXTURE, r.texture);
    glDrawArrays(GL_TRIANGLES, r.first, r.count);
  }

  glBindVertexArray(g.extra_vao.id());
  glVertexAttrib2f(SNOW_ATTR_UV, 0.0f, 0.0f);
  p.set("u_has_texture", 0);
  for (const ExtraRange& r : g.extras) {
    p.set("u_base_color", r.color);
    glDrawElementsBaseVertex(GL_TRIANGLES, r.index_count, GL_UNSIGNED_INT,
                             reinterpret_cast<const void*>(r.index_offset), r.base_vertex);
  }
  glBindVertexArray(0);
  glBindTextureUnit(SNOW_PREVIEW_BASE_COLOR_TEXTURE, 0);
  gl::check_error("preview: drawing");
}

ImageRGBA8 read_framebuffer(unsigned fbo, int width, int height) {
  ImageRGBA8 image;
  image.width = width;
  image.height = height;
  image.pixels.resize(size_t(width) * size_t(height) * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
  glReadBuffer(fbo ? GL_COLOR_ATTACHMENT0 : GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, image.pixels.data());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  gl::check_error("reading the image back");
  // GL rows run bottom to top; images top to bottom.
  const size_t row = size_t(width) * 4;
  for (int y = 0; y < height / 2; ++y) {
    std::swap_ranges(image.pixels.begin() + y * row, image.pixels.begin() + (y + 1) * row,
                     image.pixels.begin() + (height - 1 - y) * row);
  }
  return image;
}

ImageRGBA8 render_preview(const Scene& scene, const std::vector<TriMesh>& extra,
                          const glm::vec4& extra_color, PreviewSettings settings) {
  return render_preview(scene, extra, std::vector<glm::vec4>{extra_color}, settings);
}

ImageRGBA8 render_preview(const Scene& scene, const std::vector<TriMesh>& extra,
                          const std::vector<glm::vec4>& extra_colors, PreviewSettings settings) {
  if (settings.width < 1 || settings.height < 1) {
    throw InputError("preview: image size " + std::to_string(settings.width) + "x" +
                     std::to_string(settings.height) + " is empty");
  }
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
  if (settings.width > max_size || settings.height > max_size) {
    throw GLError("preview: image size " + std::to_string(settings.width) + "x" +
                  std::to_string(settings.height) + " exceeds GL_MAX_RENDERBUFFER_SIZE " +
                  std::to_string(max_size));
  }

  PreviewRenderer renderer(scene);
  renderer.set_extra_meshes(extra, extra_colors);
  PointSets points = {&scene.positions};
  for (const TriMesh& mesh : extra) points.push_back(&mesh.positions);
  const PreviewCamera camera = preview_camera(renderer.bounds(), settings, points);

  const int w = settings.width;
  const int h = settings.height;
  GLint max_samples = 1;
  glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
  int wanted = settings.samples;
  if (wanted <= 0) {
    const size_t triangles = scene.triangle_count() + renderer.extra_triangle_count();
    wanted = is_software_renderer() && triangles > kSoftwareMsaaTriangleLimit ? 1 : 4;
  }
  const int samples = std::clamp(wanted, 1, std::max(max_samples, 1));
  log_debug("preview: " + std::to_string(w) + "x" + std::to_string(h) + ", " +
            std::to_string(samples) + " sample(s)");

  // Draw target (multisampled when samples > 1) and a plain resolve target.
  const gl::RenderTarget target =
      gl::create_render_target(w, h, samples, true, "preview framebuffer");
  const gl::Framebuffer& fbo = target.fbo;
  gl::RenderTarget resolved;
  if (samples > 1)
    resolved = gl::create_render_target(w, h, 1, false, "preview resolve framebuffer");

  // The target stores sRGB-encoded values, so the background goes in as is.
  const GLfloat background[4] = {settings.background.r, settings.background.g,
                                 settings.background.b, 1.0f};
  const GLfloat far_depth = 1.0f;
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_FRAMEBUFFER_SRGB);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthMask(GL_TRUE);
  glClearNamedFramebufferfv(fbo.id(), GL_COLOR, 0, background);
  glClearNamedFramebufferfv(fbo.id(), GL_DEPTH, 0, &far_depth);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo.id());
  glViewport(0, 0, w, h);
  renderer.draw(camera, settings);

  GLuint read_fbo = fbo.id();
  if (samples > 1) {
    glBlitNamedFramebuffer(fbo.id(), resolved.fbo.id(), 0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT,
                           GL_NEAREST);
    read_fbo = resolved.fbo.id();
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return read_framebuffer(read_fbo, w, h);
}

}  // namespace snow::render

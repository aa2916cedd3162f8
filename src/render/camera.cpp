// Cameras framing a bounding box: a perspective orbit camera (the 3/4 view)
// and an orthographic top view.
#include "render/camera.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

namespace snow::render {
namespace {

// Non-empty bounds with a positive size on the largest axis.
Bounds usable(const Bounds& bounds) {
  if (bounds.empty()) {
    Bounds unit;
    unit.extend(glm::vec3(-0.5f));
    unit.extend(glm::vec3(0.5f));
    return unit;
  }
  const glm::vec3 size = bounds.size();
  const float largest = std::max({size.x, size.y, size.z});
  if (largest > 0.0f) return bounds;
  Bounds grown = bounds;
  grown.extend(bounds.min - glm::vec3(0.5f));
  grown.extend(bounds.max + glm::vec3(0.5f));
  return grown;
}

std::array<glm::vec3, 8> corners(const Bounds& b) {
  std::array<glm::vec3, 8> out;
  for (int i = 0; i < 8; ++i) {
    out[i] =
        glm::vec3(i & 1 ? b.max.x : b.min.x, i & 2 ? b.max.y : b.min.y, i & 4 ? b.max.z : b.min.z);
  }
  return out;
}

float fill_fraction(float margin) { return std::clamp(1.0f - 2.0f * margin, 0.05f, 1.0f); }

}  // namespace

PreviewCamera orbit_camera(const Bounds& input, float azimuth, float elevation, float aspect,
                           float fov, float margin, float zoom_out) {
  const Bounds bounds = usable(input);
  const glm::vec3 center = bounds.center();
  aspect = aspect > 0.0f ? aspect : 1.0f;
  fov = std::clamp(fov, 1.0f, 170.0f);
  elevation = std::clamp(elevation, -89.9f, 89.9f);
  const float az = glm::radians(azimuth);
  const float el = glm::radians(elevation);
  const glm::vec3 to_eye(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  const glm::vec3 forward = -to_eye;
  const glm::vec3 right = glm::normalize(glm::cross(forward, glm::vec3(0, 1, 0)));
  const glm::vec3 up = glm::cross(right, forward);

  const float tan_v = std::tan(glm::radians(fov) * 0.5f) * fill_fraction(margin);
  const float tan_h = std::tan(glm::radians(fov) * 0.5f) * aspect * fill_fraction(margin);
  float distance = 0.0f;
  for (const glm::vec3& c : corners(bounds)) {
    const glm::vec3 p = c - center;
    const float z = glm::dot(p, to_eye);
    distance = std::max(distance, z + std::abs(glm::dot(p, right)) / tan_h);
    distance = std::max(distance, z + std::abs(glm::dot(p, up)) / tan_v);
  }
  distance *= std::max(zoom_out, 1e-3f);

  float nearest = std::numeric_limits<float>::max();
  float farthest = 0.0f;
  for (const glm::vec3& c : corners(bounds)) {
    const float depth = distance - glm::dot(c - center, to_eye);
    nearest = std::min(nearest, depth);
    farthest = std::max(farthest, depth);
  }
  farthest = std::max(farthest * 1.05f, 1e-3f);
  const float near_plane = std::max(nearest * 0.95f, farthest * 1e-4f);

  PreviewCamera camera;
  camera.eye = center + to_eye * distance;
  camera.forward = forward;
  camera.view = glm::lookAt(camera.eye, center, up);
  camera.projection = glm::perspective(glm::radians(fov), aspect, near_plane, farthest);
  camera.orthographic = false;
  return camera;
}

PreviewCamera top_camera(const Bounds& input, float aspect, float margin) {
  const Bounds bounds = usable(input);
  const glm::vec3 center = bounds.center();
  const glm::vec3 size = bounds.size();
  aspect = aspect > 0.0f ? aspect : 1.0f;
  float half_w = std::max(size.x, 1e-6f) * 0.5f;
  float half_h = std::max(size.z, 1e-6f) * 0.5f;
  if (half_w / half_h < aspect) {
    half_w = half_h * aspect;
  } else {
    half_h = half_w / aspect;
  }
  half_w /= fill_fraction(margin);
  half_h /= fill_fraction(margin);

  const float pad = 0.05f * std::max({size.x, size.y, size.z}) + 1e-3f;
  PreviewCamera camera;
  camera.eye = glm::vec3(center.x, bounds.max.y + pad, center.z);
  camera.forward = glm::vec3(0, -1, 0);
  camera.view =
      glm::lookAt(camera.eye, glm::vec3(center.x, bounds.min.y, center.z), glm::vec3(0, 0, -1));
  camera.projection = glm::ortho(-half_w, half_w, -half_h, half_h, pad * 0.5f, size.y + pad * 2.0f);
  camera.orthographic = true;
  return camera;
}

}  // namespace snow::render

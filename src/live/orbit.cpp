// Orbit camera of the preview window (render/camera.h's conventions).
#include "live/orbit.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/gtc/matrix_transform.hpp>

namespace snow::live {
namespace {

glm::vec3 to_eye_of(float azimuth, float elevation) {
  const float az = glm::radians(azimuth), el = glm::radians(elevation);
  return glm::vec3(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
}

}  // namespace

void OrbitView::frame(const Bounds& bounds, float aspect) {
  const render::PreviewCamera c =
      render::orbit_camera(bounds, azimuth, elevation, aspect, fov, margin);
  target = bounds.empty() ? glm::vec3(0.0f) : bounds.center();
  distance = std::max(glm::length(c.eye - target), 1e-4f);
}

void OrbitView::orbit(float dx, float dy) {
  top = false;
  azimuth = std::fmod(azimuth - 0.3f * dx, 360.0f);
  elevation = std::clamp(elevation + 0.3f * dy, -89.0f, 89.0f);
}

void OrbitView::pan(float dx, float dy, float height) {
  top = false;
  const glm::vec3 to_eye = to_eye_of(azimuth, elevation);
  const glm::vec3 right = glm::normalize(glm::cross(-to_eye, glm::vec3(0, 1, 0)));
  const glm::vec3 up = glm::cross(right, -to_eye);
  const float metres_per_pixel =
      2.0f * distance * std::tan(glm::radians(fov) * 0.5f) / std::max(height, 1.0f);
  target += (-dx * right + dy * up) * metres_per_pixel;
}

void OrbitView::zoom(float steps) {
  top = false;
  distance = std::max(distance * std::pow(0.9f, steps), 1e-3f);
}

render::PreviewCamera OrbitView::camera(const Bounds& bounds, float aspect) const {
  aspect = aspect > 0.0f ? aspect : 1.0f;
  if (top) return render::top_camera(bounds, aspect, margin);
  const float el = std::clamp(elevation, -89.9f, 89.9f);
  const glm::vec3 to_eye = to_eye_of(azimuth, el);
  const glm::vec3 right = glm::normalize(glm::cross(-to_eye, glm::vec3(0, 1, 0)));
  const glm::vec3 up = glm::cross(right, -to_eye);
  const glm::vec3 eye = target + to_eye * distance;
  float nearest = std::numeric_limits<float>::max(), farthest = 0.0f;
  if (!bounds.empty()) {
    for (int k = 0; k < 8; ++k) {
      const glm::vec3 c(k & 1 ? bounds.max.x : bounds.min.x, k & 2 ? bounds.max.y : bounds.min.y,
                        k & 4 ? bounds.max.z : bounds.min.z);
      const float depth = glm::dot(eye - c, to_eye);
      nearest = std::min(nearest, depth);
      farthest = std::max(farthest, depth);
    }
  } else {
    nearest = distance * 0.5f;
    farthest = distance * 2.0f;
  }
  farthest = std::max(farthest * 1.05f, 1e-3f);
  const float near_plane = std::max(nearest * 0.95f, farthest * 1e-4f);
  render::PreviewCamera camera;
  camera.eye = eye;
  camera.forward = -to_eye;
  camera.view = glm::lookAt(eye, target, up);
  camera.projection =
      glm::perspective(glm::radians(std::clamp(fov, 1.0f, 170.0f)), aspect, near_plane, farthest);
  camera.orthographic = false;
  return camera;
}

}  // namespace snow::live

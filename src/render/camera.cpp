// Cameras framing a bounding box: a perspective orbit camera (the 3/4 view)
// and an orthographic top view.
#include "render/camera.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

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

namespace {

struct Orbit {
  glm::vec3 to_eye, right, up;  // unit; to_eye points from the target to the eye
  float tan_h, tan_v;           // half-extents of the usable image at unit distance
  float fov, aspect;
};

Orbit make_orbit(float azimuth, float elevation, float aspect, float fov, float margin) {
  Orbit o;
  o.aspect = aspect > 0.0f ? aspect : 1.0f;
  o.fov = std::clamp(fov, 1.0f, 170.0f);
  elevation = std::clamp(elevation, -89.9f, 89.9f);
  const float az = glm::radians(azimuth);
  const float el = glm::radians(elevation);
  o.to_eye = glm::vec3(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  o.right = glm::normalize(glm::cross(-o.to_eye, glm::vec3(0, 1, 0)));
  o.up = glm::cross(o.right, -o.to_eye);
  o.tan_v = std::tan(glm::radians(o.fov) * 0.5f) * fill_fraction(margin);
  o.tan_h = o.tan_v * o.aspect;
  return o;
}

// Smallest eye distance from `target` at which `p` fits into the image.
float distance_for(const Orbit& o, const glm::vec3& target, const glm::vec3& point) {
  const glm::vec3 p = point - target;
  const float z = glm::dot(p, o.to_eye);
  return std::max(z + std::abs(glm::dot(p, o.right)) / o.tan_h,
                  z + std::abs(glm::dot(p, o.up)) / o.tan_v);
}

// The camera at `distance` from `target`, near/far planes around `bounds`.
PreviewCamera finish_orbit(const Orbit& o, const Bounds& bounds, const glm::vec3& target,
                           float distance) {
  const glm::vec3 eye = target + o.to_eye * distance;
  float nearest = std::numeric_limits<float>::max();
  float farthest = 0.0f;
  for (const glm::vec3& c : corners(bounds)) {
    const float depth = glm::dot(eye - c, o.to_eye);
    nearest = std::min(nearest, depth);
    farthest = std::max(farthest, depth);
  }
  farthest = std::max(farthest * 1.05f, 1e-3f);
  const float near_plane = std::max(nearest * 0.95f, farthest * 1e-4f);

  PreviewCamera camera;
  camera.eye = eye;
  camera.forward = -o.to_eye;
  camera.view = glm::lookAt(eye, target, o.up);
  camera.projection = glm::perspective(glm::radians(o.fov), o.aspect, near_plane, farthest);
  camera.orthographic = false;
  return camera;
}

}  // namespace

PreviewCamera orbit_camera(const Bounds& input, float azimuth, float elevation, float aspect,
                           float fov, float margin, float zoom_out) {
  const Bounds bounds = usable(input);
  const Orbit o = make_orbit(azimuth, elevation, aspect, fov, margin);
  const glm::vec3 target = bounds.center();
  float distance = 0.0f;
  for (const glm::vec3& c : corners(bounds)) {
    distance = std::max(distance, distance_for(o, target, c));
  }
  return finish_orbit(o, bounds, target, distance * std::max(zoom_out, 1e-3f));
}

PreviewCamera orbit_camera_fit(const Bounds& input, const PointSets& points, float azimuth,
                               float elevation, float aspect, float fov, float margin) {
  size_t count = 0;
  for (const auto* set : points) count += set ? set->size() : 0;
  if (count == 0 || input.empty()) {
    return orbit_camera(input, azimuth, elevation, aspect, fov, margin);
  }
  const Bounds bounds = usable(input);
  const Orbit o = make_orbit(azimuth, elevation, aspect, fov, margin);

  // With the eye at c + a right + b up + d to_eye (c the bounds' centre), a
  // point at lateral (x, y) and height z along to_eye fits when
  // |x - a| <= (d - z) tan_h and |y - b| <= (d - z) tan_v. The smallest d
  // and its a, b follow from four maxima over the points, in one pass.
  const glm::vec3 c = bounds.center();
  float ax = -std::numeric_limits<float>::max(), bx = ax, ay = ax, by = ax;
  for (const auto* set : points) {
    if (!set) continue;
    for (const glm::vec3& point : *set) {
      const glm::vec3 p = point - c;
      const float x = glm::dot(p, o.right);
      const float y = glm::dot(p, o.up);
      const float z = glm::dot(p, o.to_eye);
      ax = std::max(ax, x + z * o.tan_h);
      bx = std::max(bx, -x + z * o.tan_h);
      ay = std::max(ay, y + z * o.tan_v);
      by = std::max(by, -y + z * o.tan_v);
    }
  }
  const float size = std::max(glm::length(bounds.size()), 1e-6f);
  const float distance =
      std::max({(ax + bx) / (2.0f * o.tan_h), (ay + by) / (2.0f * o.tan_v), 1e-4f * size});
  const glm::vec3 target = c + o.right * ((ax - bx) * 0.5f) + o.up * ((ay - by) * 0.5f);
  return finish_orbit(o, bounds, target, distance);
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

#pragma once
// The preview window's camera: orbit around a target, pan, zoom, frame the
// scene. Starts as render::orbit_camera (same eye, same view matrix) or as
// render::top_camera, so scripted screenshots match what tests compute.
#include <glm/glm.hpp>

#include "render/camera.h"
#include "scene/scene.h"

namespace snow::live {

struct OrbitView {
  glm::vec3 target{0.0f};   // metres, the point orbited around
  float azimuth = 45.0f;    // degrees from south (+Z) towards east (+X)
  float elevation = 35.0f;  // degrees above the horizon (-89..89)
  float distance = 10.0f;   // metres from target to eye
  float fov = 35.0f;        // vertical field of view, degrees
  float margin = 0.04f;     // free border when framing, fraction of the image
  bool top = false;         // orthographic top view (render::top_camera) until orbited

  /// Frames `bounds` from the current direction: the eye of
  /// render::orbit_camera(bounds, azimuth, elevation, aspect, fov, margin).
  void frame(const Bounds& bounds, float aspect);
  /// Turns by pixels dragged (0.3 degrees per pixel); leaves the top view.
  void orbit(float dx, float dy);
  /// Moves the target by pixels dragged in an image `height` pixels high.
  void pan(float dx, float dy, float height);
  /// Moves the eye towards the target by 10 % per step (negative: away).
  void zoom(float steps);
  /// The camera for an image of `aspect` (width / height); near and far
  /// planes enclose `bounds`.
  render::PreviewCamera camera(const Bounds& bounds, float aspect) const;
};

}  // namespace snow::live

#pragma once
// Cameras that frame a scene's bounds for the preview renderer and viewer.
// World frame: metres, +Y up, north = -Z, east = +X (so "from the
// south-east" is from +X, +Z).
#include <vector>

#include <glm/glm.hpp>

#include "scene/scene.h"

namespace snow::render {

enum class View {
  ThreeQuarter,  // perspective, from the south-east and above, whole bounds in view
  Top,           // orthographic, straight down; north (-Z) up, east (+X) right
};

struct PreviewCamera {
  glm::mat4 view{1.0f};                  // world -> eye
  glm::mat4 projection{1.0f};            // eye -> clip (OpenGL, depth -1..1)
  glm::vec3 eye{0.0f};                   // position, metres (ortho: above the bounds)
  glm::vec3 forward{0.0f, 0.0f, -1.0f};  // unit view direction
  bool orthographic = false;

  glm::mat4 view_projection() const { return projection * view; }
};

/// Perspective camera looking at the centre of `bounds` from the direction
/// given by `azimuth` (degrees; 0 = from the south (+Z), 90 = from the east
/// (+X)) and `elevation` (degrees above the horizon), placed at the
/// smallest distance at which all 8 corners of the bounds fit into the
/// image with `margin` (fraction of the width/height) free on each side,
/// times `zoom_out` (>= 1 moves back). `aspect` = width / height,
/// `fov` = vertical field of view in degrees. Empty bounds frame a unit box
/// at the origin.
PreviewCamera orbit_camera(const Bounds& bounds, float azimuth, float elevation, float aspect,
                           float fov = 35.0f, float margin = 0.05f, float zoom_out = 1.0f);

/// Sets of points (e.g. &Scene::positions and each extra mesh's positions).
using PointSets = std::vector<const std::vector<glm::vec3>*>;

/// Like orbit_camera(), but framed on the points themselves (all of which
/// must lie in `bounds`): it aims at the middle of the points' image and
/// backs off just far enough that every point fits with `margin`. Tighter
/// than the bounds' corners when the geometry does not fill its box (a
/// small car on a wide cloth). Same as orbit_camera() without points.
PreviewCamera orbit_camera_fit(const Bounds& bounds, const PointSets& points, float azimuth,
                               float elevation, float aspect, float fov = 35.0f,
                               float margin = 0.05f);

/// Orthographic camera looking straight down (-Y) at `bounds`, north (-Z)
/// up and east (+X) right, the X/Z extent fit into the image with `margin`
/// free on each side (the shorter side is widened to the image's aspect).
PreviewCamera top_camera(const Bounds& bounds, float aspect, float margin = 0.05f);

}  // namespace snow::render

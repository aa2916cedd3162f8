#pragma once
// The live accumulation preview window (`snowmodel preview`): a GLFW window
// in which snow falls, piles up, slides off roofs and drops to the ground
// while the user orbits and tweaks the settings in a Dear ImGui panel, and
// exports what they see with the batch job's exporters.
#include <cstdint>
#include <string>
#include <vector>

#include "live/live_sim.h"
#include "live/snow_view.h"
#include "mesh/polygonize.h"
#include "scene/frame.h"
#include "scene/scene.h"
#include "snow/tracks.h"

namespace snow::live {

struct ViewerOptions {
  std::string input;                // the glTF file shown (the export checks its path against it)
  LiveSettings sim;                 // the snowfall
  PolygonizeSettings mesh;          // export
  SnowViewSettings view;            // drawing the snow
  int snow_stride = 0;              // texels between drawn snow grid vertices; 0 = automatic
  int width = 1280;                 // window width, pixels
  int height = 800;                 // window height, pixels
  bool top_view = false;            // start in the orthographic top view
  float azimuth = 45.0f;            // degrees from south (+Z) towards east (+X), start camera
  float elevation = 30.0f;          // degrees above the horizon, start camera
  float fov = 35.0f;                // vertical field of view, degrees
  float zoom = 1.0f;                // start camera: the framed eye distance divided by this (> 0)
  bool panel = true;                // show the ImGui panel (H toggles)
  bool paused = false;              // start paused
  int frames = 0;                   // > 0: quit after this many frames (scripts, tests)
  bool headless = false;            // draw off-screen (an EGL or OSMesa context, no window and no
                                    // display): same frame loop, no input; needs frames > 0
  std::string gl_backend = "auto";  // headless: the context's backend (gl::parse_backend)
  std::string screenshot;           // PNG of the last frame (scene and snow, no panel) at exit
  bool screenshot_panel = false;    // the screenshot at exit shows the panel too
  std::string export_path;          // snow meshes (.glb/.gltf with the scene, .obj/.ply) at exit
  std::string maps_path;            // the maps with coverage and depth (mesh/write_maps.h) at exit
  bool snow_only = false;           // export the snow only, also to .glb/.gltf
  FileFrame frame;                  // the file's frame: the export goes back to it
  std::vector<uint8_t> receives;    // per scene object: 0 = no fresh snow (may be empty)
  // Tracks (snow/tracks.h): pressed once the snowfall ended and the snow
  // rests, or at the last of --frames (again after a reset, or from the
  // panel); the brush (Ctrl+drag presses, Alt+drag clears) uses the same
  // settings.
  std::vector<TrackSource> tracks;
  TrackSettings track_settings;
  float brush_radius = 0.3f;  // m
};

/// What a run measured.
struct ViewerReport {
  int64_t frames = 0;         // frames drawn
  double seconds = 0;         // wall seconds of those frames (first frame included)
  double fps = 0;             // frames per second after the first 5 frames
  double stabilize_ms = 0;    // mean per frame: adding snow plus stabilizer passes
  double scene_ms = 0;        // mean per frame: drawing the scene
  double snow_ms = 0;         // mean per frame: drawing the snow (and flakes)
  double volume = 0;          // m^3 of snow lying at the end
  double fallen = 0;          // m^3 of snow fallen
  size_t snow_triangles = 0;  // triangles of the snow grid drawn in the last frame
  // A weather series' (LiveSettings::weather) at the end: its clock
  // (hours) and water balance (m^3 of water, snow/snowpack.h).
  double hour = 0;
  double water_fallen = 0, water_melted = 0, water_lost = 0, water_lying = 0;
};

/// Opens the window (GLFW backend; needs a display), or with
/// options.headless an off-screen framebuffer of options.width x height on a
/// headless context, and runs until it is closed, Escape is pressed or
/// options.frames frames have been drawn; then writes options.screenshot and
/// options.export_path if given. Throws GLError when no window or context
/// can be made, InputError for bad settings (headless without frames, or
/// with the glfw backend), IOError when an output cannot be written.
ViewerReport run_viewer(const Scene& scene, const ViewerOptions& options);

}  // namespace snow::live

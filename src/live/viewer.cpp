// The live preview window: GLFW input, the frame loop (simulate, draw scene
// and snow, panel), screenshots and exports; headless, the same loop draws
// into an off-screen framebuffer. The physics is LiveSim's (the
// batch stages); the drawing is PreviewRenderer's and SnowView's.
#include "live/viewer.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>

#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <optional>

#include "core/error.h"
#include "core/log.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "live/orbit.h"
#include "live/surface.h"
#include "mesh/export.h"
#include "mesh/output_policy.h"
#include "mesh/write_maps.h"
#include "plan/rules.h"
#include "render/image.h"
#include "render/preview.h"
#include "snow/accumulate.h"

namespace snow::live {
namespace {

using Clock = std::chrono::steady_clock;

/// Frames between the panel's snow volumes (each a full readback of the depth).
constexpr int64_t kPanelVolumesEvery = 15;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// The frame drawn into `fbo` (0: the window's back buffer) as an opaque
/// image (a window's alpha is undefined).
render::ImageRGBA8 read_frame(unsigned fbo, int width, int height) {
  render::ImageRGBA8 image = render::read_framebuffer(fbo, width, height);
  for (size_t k = 3; k < image.pixels.size(); k += 4) image.pixels[k] = 255;
  return image;
}

/// Polygonizes the current snow and writes it like the batch job does.
std::string export_snow(const Scene& scene, const LiveSim& sim, const ViewerOptions& options,
                        const std::string& path, bool snow_only) {
  const MeshFormat format = format_from_path(path);
  check_output_paths(options.input, {{"export", path, OutputKind::Mesh, format, {}}});
  std::vector<SnowPatch> patches = polygonize(sim.maps(), sim.depth(), scene, options.mesh);
  for (SnowPatch& p : patches) to_file_frame(p.mesh, options.frame);
  const bool combined = !snow_only && (format == MeshFormat::Glb || format == MeshFormat::Gltf);
  if (combined && scene.source) {
    write_combined_gltf(*scene.source, patches, path);
  } else {
    write_snow_meshes(patches, path, format);
  }
  size_t triangles = 0;
  for (const SnowPatch& p : patches) triangles += p.mesh.indices.size() / 3;
  return "wrote " + path + " (" + std::to_string(patches.size()) + " patches, " +
         std::to_string(triangles) + " triangles)";
}

/// Metres the snow can rise above its ground: the deepest drift (the
/// planner's cap on drifts, times the fall) and a centimetre.
float snow_rise(float total_depth) {
  return std::max(total_depth, 0.0f) * float(plan::kDriftMaxCoefficient) + 0.01f;
}

/// Writes the maps with the coverage and the current snow like the batch
/// job's --maps.
/// With a weather series, the snowpack too (what `snow --resume` continues
/// from).
std::string export_maps(LiveSim& sim, const ViewerOptions& options, const std::string& path) {
  check_output_paths(options.input, {{"maps", path, OutputKind::Maps, {}, {}}});
  std::vector<std::vector<float>> storage;
  std::optional<MapsSnowpack> pack;
  std::vector<float> depth;
  if (sim.snowpack()) {
    sim.sync_snowpack();  // reads the depth back into the pack
    pack = maps_snowpack(*sim.snowpack(), sim.snowpack_hour(), storage);
  } else {
    depth = sim.depth();
  }
  write_maps(path, sim.maps(), &sim.coverage(), pack ? &sim.snowpack()->depth : &depth,
             pack ? &*pack : nullptr);
  return "wrote maps to " + path;
}

/// Scene bounds grown upwards by the snow that can pile up.
Bounds with_snow(const Bounds& scene_bounds, float total_depth) {
  Bounds b = scene_bounds;
  if (!b.empty()) b.extend(b.max + glm::vec3(0.0f, snow_rise(total_depth), 0.0f));
  return b;
}

class Viewer {
 public:
  Viewer(const Scene& scene, const ViewerOptions& options)
      : scene_(scene), options_(options), pending_(options.sim), view_settings_(options.view) {
    paused_ = options.paused;
    tracks_due_ = !options.tracks.empty();
    brush_radius_ = options.brush_radius;
    stride_setting_ = options.snow_stride;
    panel_ = options.panel;
    std::snprintf(export_path_, sizeof export_path_, "%s",
                  options.export_path.empty() ? "snow_preview.glb" : options.export_path.c_str());
    std::snprintf(screenshot_path_, sizeof screenshot_path_, "%s",
                  options.screenshot.empty() ? "snow_preview.png" : options.screenshot.c_str());
    std::snprintf(maps_path_, sizeof maps_path_, "%s",
                  options.maps_path.empty() ? "snow_maps" : options.maps_path.c_str());
  }

  ViewerReport run();

 private:
  void sync_view();
  /// The output policy for the screenshot's path (mesh/output_policy.h).
  void check_screenshot_path() const {
    check_output_paths(options_.input,
                       {{"screenshot", screenshot_path_, OutputKind::File, {}, {}}});
  }
  void handle_input(GLFWwindow* window, int fb_height);
  void draw_panel(double frame_ms);
  /// The weather series' lines and its time slider (drag to an hour: later
  /// plays forward to it, earlier replays from the start).
  void draw_weather_panel();
  /// The panel's export, maps and screenshot buttons and the status line.
  void draw_outputs();
  // Draws the scene, the snow and the panel into the window's back buffer,
  // and writes the screenshots due (`last`: the run's last frame).
  void draw_frame(int fb_w, int fb_h, bool last, double frame_ms);
  void apply_pending();
  /// Presses options_.tracks into the snow (LiveSim::make_tracks).
  void press_tracks();
  /// The brush at the cursor (x, y in window pixels; `fb` the window's
  /// size): a disc of brush_radius_ pressed (or cleared) where the view ray
  /// meets the snow.
  void brush(double x, double y, glm::ivec2 fb, TrackMode mode);
  void set_status(const std::string& message) {
    status_ = message;
    log_info(message);
  }

  const Scene& scene_;
  const ViewerOptions& options_;
  unsigned target_ = 0;  // the framebuffer drawn into: 0 (the window's) or the off-screen one
  std::unique_ptr<LiveSim> sim_;
  std::unique_ptr<SnowView> snow_;
  std::unique_ptr<render::PreviewRenderer> scene_renderer_;
  render::PreviewSettings shading_;
  OrbitView orbit_;
  Input input_;
  LiveSettings pending_;           // edited by the panel, applied on release
  float wind_heading_deg_ = 0.0f;  // the panel's wind heading, kept while the speed is 0
  SnowViewSettings view_settings_;
  int stride_ = 1;          // texels between drawn snow grid vertices, in use
  int stride_setting_ = 0;  // the panel's (0 = automatic)
  plan::GlFacts gl_;        // the window's renderer, for the planner's automatic stride
  uint64_t maps_version_ = 0, coverage_version_ = 0;
  bool paused_ = false, step_once_ = false, panel_ = true;
  bool ui_ = false;  // Dear ImGui runs (the window, or a headless --screenshot-panel)
  bool want_screenshot_ = false, want_frame_ = false;
  double last_x_ = 0, last_y_ = 0;
  double scene_ms_ = 0, snow_ms_ = 0;
  float aspect_ = 1.6f;
  char export_path_[512] = {};
  char screenshot_path_[512] = {};
  char maps_path_[512] = {};
  bool export_snow_only_ = false;
  float scrub_hour_ = 0.0f;                        // the time slider's hour while it is dragged
  double lying_volume_ = 0.0, lost_volume_ = 0.0;  // m^3, as of volumes_frame_
  int64_t volumes_frame_ = -1;
  double lying_ = 0.0, lying_hour_ = NAN;  // m^3 of water lying, as of the snowpack's hour
  std::string status_;
  bool tracks_due_ = false;    // options_.tracks wait to be pressed
  float brush_radius_ = 0.3f;  // m
};

void Viewer::sync_view() {
  if (sim_->maps_version() != maps_version_) {
    stride_ = stride_setting_ > 0 ? stride_setting_
                                  : auto_stride(sim_->maps().grid.width, sim_->maps().grid.height,
                                                plan::preview_grid_side(gl_));
    snow_->set_maps(sim_->maps(), stride_);
    maps_version_ = sim_->maps_version();
    coverage_version_ = 0;
  }
  if (sim_->coverage_version() != coverage_version_) {
    snow_->set_coverage(sim_->coverage());
    coverage_version_ = sim_->coverage_version();
  }
}

void Viewer::apply_pending() {
  try {
    sim_->apply(pending_);
    sync_view();
  } catch (const Error& e) {
    pending_ = sim_->settings();
    set_status(std::string("not applied: ") + e.what());
  }
}

void Viewer::handle_input(GLFWwindow* window, int fb_height) {
  const ImGuiIO& io = ImGui::GetIO();
  double x = 0, y = 0;
  glfwGetCursorPos(window, &x, &y);
  const float dx = float(x - last_x_), dy = float(y - last_y_);
  last_x_ = x;
  last_y_ = y;
  if (!io.WantCaptureMouse) {
    const bool left = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    const bool right = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                       glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
    const bool shift = glfwGetKey(window, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS;
    const bool ctrl = glfwGetKey(window, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS;
    const bool alt = glfwGetKey(window, GLFW_KEY_LEFT_ALT) == GLFW_PRESS;
    if (left && (ctrl || alt)) {
      int w = 0, h = 0;
      glfwGetWindowSize(window, &w, &h);
      brush(x, y, {w, h}, ctrl ? TrackMode::Press : TrackMode::Clear);
    } else if ((dx != 0 || dy != 0) && (left || right)) {
      if (right || shift) {
        orbit_.pan(dx, dy, float(fb_height));
      } else {
        orbit_.orbit(dx, dy);
      }
    }
    if (input_.scroll != 0) orbit_.zoom(float(input_.scroll));
  }
  input_.scroll = 0;
  if (!io.WantCaptureKeyboard) {
    for (int key : input_.keys) {
      switch (key) {
        case GLFW_KEY_F:
          want_frame_ = true;
          break;
        case GLFW_KEY_SPACE:
          paused_ = !paused_;
          break;
        case GLFW_KEY_S:
          step_once_ = true;
          break;
        case GLFW_KEY_R:
          sim_->reset();
          tracks_due_ = !options_.tracks.empty();
          break;
        case GLFW_KEY_P:
          want_screenshot_ = true;
          break;
        case GLFW_KEY_H:
          panel_ = !panel_;
          break;
        case GLFW_KEY_T:
          orbit_.top = !orbit_.top;
          break;
        case GLFW_KEY_ESCAPE:
          glfwSetWindowShouldClose(window, GLFW_TRUE);
          break;
        default:
          break;
      }
    }
  }
  input_.keys.clear();
}

void Viewer::press_tracks() {
  tracks_due_ = false;
  const TrackResult r = sim_->make_tracks(options_.tracks, options_.track_settings);
  char line[200];
  std::snprintf(line, sizeof line, "tracks: %zu texels pressed, %zu cleared", r.pressed, r.cleared);
  set_status(line);
}

void Viewer::brush(double x, double y, glm::ivec2 fb, TrackMode mode) {
  const render::PreviewCamera camera =
      orbit_.camera(with_snow(scene_.bounds, sim_->settings().total_depth), aspect_);
  const glm::mat4 inverse = glm::inverse(camera.view_projection());
  const glm::vec2 ndc(2.0f * float(x) / float(std::max(fb.x, 1)) - 1.0f,
                      1.0f - 2.0f * float(y) / float(std::max(fb.y, 1)));
  const glm::vec4 near = inverse * glm::vec4(ndc, -1.0f, 1.0f);
  const glm::vec4 far = inverse * glm::vec4(ndc, 1.0f, 1.0f);
  const glm::vec3 from = glm::vec3(near) / near.w, to = glm::vec3(far) / far.w;
  sim_->brush(from, to - from, brush_radius_, mode, options_.track_settings);
}

void Viewer::draw_panel(double frame_ms) {
  ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSize(ImVec2(440, 0), ImGuiCond_FirstUseEver);
  ImGui::Begin("snowmodel preview");
  ImGui::PushItemWidth(-170.0f);
  LiveSim& sim = *sim_;
  const SnowMaps& maps = sim.maps();
  const bool weather = sim.snowpack() != nullptr;
  ImGui::Text("%.1f fps (%.1f ms per frame)", frame_ms > 0 ? 1000.0 / frame_ms : 0.0, frame_ms);
  ImGui::Text("stabilize %.1f ms  add %.1f ms", sim.timings().stabilize * 1e3,
              sim.timings().add * 1e3);
  ImGui::Text("scene %.1f ms  snow %.1f ms", scene_ms_, snow_ms_);
  ImGui::Text("peel %.2f s  coverage %.2f s (last)", sim.timings().peel,
              sim.timings().last_coverage);
  ImGui::Text("maps %d x %d x %d, texel %.3f m, grid stride %d", maps.grid.width, maps.grid.height,
              maps.layers, maps.grid.texel, stride_);
  if (weather) {
    ImGui::Text("frame %lld, residual %.2g m", static_cast<long long>(sim.frame()),
                sim.last_result().residual);
  } else {
    // Volumes need a full readback: a few times a second of frames.
    if (sim.frame() != volumes_frame_ && sim.frame() % kPanelVolumesEvery == 0) {
      lying_volume_ = snow_volume(maps, sim.depth());
      lost_volume_ = sim.lost_volume();
      volumes_frame_ = sim.frame();
    }
    ImGui::Text("snow %.3f m^3 lying, %.3f fallen, %.3f lost", lying_volume_, sim.fallen_volume(),
                lost_volume_);
    ImGui::Text("fallen %.3f of %.3f m, frame %lld, residual %.2g m", sim.fallen_depth(),
                sim.settings().total_depth, static_cast<long long>(sim.frame()),
                sim.last_result().residual);
  }

  ImGui::Separator();
  if (ImGui::Button(paused_ ? "Resume" : "Pause")) paused_ = !paused_;
  ImGui::SameLine();
  if (ImGui::Button("Step")) step_once_ = true;
  ImGui::SameLine();
  if (ImGui::Button("Reset")) {
    sim_->reset();
    tracks_due_ = !options_.tracks.empty();
  }
  if (!options_.tracks.empty()) {
    ImGui::SameLine();
    if (ImGui::Button("Tracks")) press_tracks();
  }
  ImGui::SliderFloat("brush radius (m)", &brush_radius_, 0.05f, 5.0f, "%.2f",
                     ImGuiSliderFlags_Logarithmic);
  ImGui::TextDisabled("Ctrl+drag presses tracks, Alt+drag clears");
  ImGui::SameLine();
  if (ImGui::Button("Frame (F)")) want_frame_ = true;

  // Cheap settings apply at once; the others when the widget is released.
  bool cheap = false;
  if (weather) {
    draw_weather_panel();
    cheap |= ImGui::SliderFloat("speed h/s", &pending_.weather_speed, 0.0f, 100.0f, "%.2f",
                                ImGuiSliderFlags_Logarithmic);
  } else {
    cheap |= ImGui::SliderFloat("fall rate m/s", &pending_.fall_rate, 0.0f, 0.5f, "%.3f");
    cheap |= ImGui::SliderFloat("total depth m", &pending_.total_depth, 0.0f, 2.0f, "%.2f");
  }
  cheap |= ImGui::SliderInt("passes/frame", &pending_.passes_per_frame, 0, 256);
  if (!weather) {
    cheap |= ImGui::SliderInt("add snow every (0 auto)", &pending_.add_every, 0, 60);
    cheap |= ImGui::SliderInt("snow on snow every", &pending_.snow_on_snow_every, 0, 300);
  }
  if (cheap) apply_pending();

  ImGui::Separator();
  bool release = false;
  ImGui::SliderFloat("flutter deg", &pending_.coverage.flutter_deg, 0.0f, 60.0f, "%.1f");
  release |= ImGui::IsItemDeactivatedAfterEdit();
  // The wind as speed and heading (degrees from +x towards +z, where it
  // blows to); the heading is kept while the speed is 0.
  glm::vec2& wind = pending_.coverage.wind;
  float speed = glm::length(wind);
  if (speed > 0.0f) wind_heading_deg_ = glm::degrees(std::atan2(wind.y, wind.x));
  bool wind_changed = false;
  if (!weather) {  // the weather's wind is each step's
    wind_changed |= ImGui::SliderFloat("wind m/s", &speed, 0.0f, kMaxWind, "%.1f");
    release |= ImGui::IsItemDeactivatedAfterEdit();
    wind_changed |=
        ImGui::SliderFloat("wind towards deg", &wind_heading_deg_, -180.0f, 180.0f, "%.0f");
    release |= ImGui::IsItemDeactivatedAfterEdit();
  }
  if (wind_changed) {
    const float a = glm::radians(wind_heading_deg_);
    wind = std::min(speed, kMaxWind) * glm::vec2(std::cos(a), std::sin(a));
  }
  ImGui::SliderInt("directions", &pending_.coverage.directions, 1, 256);
  release |= ImGui::IsItemDeactivatedAfterEdit();
  ImGui::SliderFloat("repose deg", &pending_.stabilize.repose_deg, 5.0f, 85.0f, "%.1f");
  release |= ImGui::IsItemDeactivatedAfterEdit();
  ImGui::InputFloat("texel m (0 auto)", &pending_.peel.texel, 0.0f, 0.0f, "%.4f");
  release |= ImGui::IsItemDeactivatedAfterEdit();
  ImGui::InputInt("max side", &pending_.peel.max_side);
  release |= ImGui::IsItemDeactivatedAfterEdit();
  ImGui::SliderInt("layers", &pending_.peel.layers, 1, 16);
  release |= ImGui::IsItemDeactivatedAfterEdit();
  if (release) apply_pending();
  ImGui::TextDisabled("texel, max side, layers: re-peel and restart the snow");

  ImGui::Separator();
  int overlay = int(view_settings_.overlay);
  ImGui::RadioButton("snow", &overlay, 0);
  ImGui::SameLine();
  ImGui::RadioButton("coverage", &overlay, 1);
  ImGui::SameLine();
  ImGui::RadioButton("depth", &overlay, 2);
  view_settings_.overlay = Overlay(overlay);
  if (view_settings_.overlay == Overlay::Depth)
    ImGui::SliderFloat("depth ramp max m", &view_settings_.depth_ramp_max, 0.01f, 3.0f, "%.2f");
  ImGui::SliderInt("flakes", &view_settings_.flakes, 0, 50000);
  ImGui::SliderInt("snow grid stride (0 auto)", &stride_setting_, 0, 8);
  if (ImGui::IsItemDeactivatedAfterEdit()) {
    maps_version_ = 0;  // rebuild the grid
    sync_view();
  }

  draw_outputs();
  ImGui::TextDisabled(
      "drag: orbit, right/shift-drag: pan, wheel: zoom, F frame, T top,"
      " space pause, S step, R reset, H panel");
  ImGui::PopItemWidth();
  ImGui::End();
}

void Viewer::draw_outputs() {
  ImGui::Separator();
  ImGui::InputText("##export", export_path_, sizeof export_path_);
  ImGui::SameLine();
  if (ImGui::Button("Export")) {
    try {
      set_status(export_snow(scene_, *sim_, options_, export_path_, export_snow_only_));
    } catch (const Error& e) {
      set_status(std::string("export failed: ") + e.what());
    }
  }
  ImGui::Checkbox("snow only", &export_snow_only_);
  ImGui::InputText("##maps", maps_path_, sizeof maps_path_);
  ImGui::SameLine();
  if (ImGui::Button("Export maps")) {
    try {
      set_status(export_maps(*sim_, options_, maps_path_));
    } catch (const Error& e) {
      set_status(std::string("maps export failed: ") + e.what());
    }
  }
  ImGui::InputText("##shot", screenshot_path_, sizeof screenshot_path_);
  ImGui::SameLine();
  if (ImGui::Button("Screenshot (P)")) want_screenshot_ = true;
  if (!status_.empty()) ImGui::TextWrapped("%s", status_.c_str());
}

void Viewer::draw_weather_panel() {
  LiveSim& sim = *sim_;
  const WeatherRun& run = *sim.settings().weather;
  const double first = run.steps.front().hour;
  const double end = run.steps.back().hour + run.steps.back().hours;
  char when[64] = "";
  if (std::isfinite(run.start_unix)) {
    const std::time_t t = std::time_t(run.start_unix + sim.weather_hour() * 3600.0);
    std::tm utc{};
    gmtime_r(&t, &utc);
    std::strftime(when, sizeof when, ", %Y-%m-%d %H:%M UTC", &utc);
  }
  ImGui::Text("hour %.2f of %.6g..%.6g%s", sim.weather_hour(), first, end, when);
  if (const WeatherStep* now = sim.weather_now()) {
    const float share = snow_share(now->temp_c);
    const char* what = now->precip_mm <= 0.0f ? "dry" : share >= 0.5f ? "snow" : "rain";
    ImGui::Text("%+.1f C, %.1f mm/h %s, wind %.1f m/s from %.0f, cloud %.0f%%", double(now->temp_c),
                double(now->precip_mm) / now->hours, what, double(now->wind_ms),
                double(now->wind_from_deg), 100.0 * double(now->cloud));
  } else {
    ImGui::Text("the weather file has ended");
  }
  const SnowPack& pack = *sim.snowpack();
  if (sim.snowpack_hour() != lying_hour_) {
    lying_ = pack.lying(sim.maps());
    lying_hour_ = sim.snowpack_hour();
  }
  ImGui::Text("water m^3: fell %.3f, melted %.3f, left %.3f, lies %.3f", pack.fallen, pack.melted,
              pack.lost, lying_);
  if (!ImGui::IsAnyItemActive()) scrub_hour_ = float(sim.weather_hour());
  ImGui::SliderFloat("hour", &scrub_hour_, float(first), float(end), "%.2f");
  if (ImGui::IsItemDeactivatedAfterEdit()) {
    sim.seek(scrub_hour_);
    sync_view();
  }
}

void Viewer::draw_frame(int fb_w, int fb_h, bool last, double frame_ms) {
  // Draw scene and snow.
  const Bounds view_bounds = with_snow(scene_.bounds, sim_->settings().total_depth);
  const render::PreviewCamera camera = orbit_.camera(view_bounds, aspect_);
  glBindFramebuffer(GL_FRAMEBUFFER, target_);
  glViewport(0, 0, fb_w, fb_h);
  glClearColor(shading_.background.x, shading_.background.y, shading_.background.z, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  auto t = Clock::now();
  scene_renderer_->draw(camera, shading_);
  glFinish();
  scene_ms_ = ms_since(t);
  t = Clock::now();
  snow_->draw(camera, fb_h, shading_, sim_->depth_texture(),
              snow_rise(sim_->settings().total_depth), view_settings_);
  if (sim_->snowing()) {
    const float time = float(sim_->frame()) * sim_->settings().frame_time;
    snow_->draw_flakes(camera, view_bounds, time, sim_->settings().coverage.fall_speed,
                       sim_->fall_wind(), view_settings_);
  }
  glFinish();
  snow_ms_ = ms_since(t);

  const bool shot_at_exit = last && !options_.screenshot.empty();
  if (want_screenshot_ || (shot_at_exit && !options_.screenshot_panel)) {
    want_screenshot_ = false;
    try {
      check_screenshot_path();
      render::write_png(read_frame(target_, fb_w, fb_h), screenshot_path_);
      set_status(std::string("wrote ") + screenshot_path_);
    } catch (const Error& e) {
      if (last) throw;
      set_status(std::string("screenshot failed: ") + e.what());
    }
  }

  if (ui_) {
    if (panel_) draw_panel(frame_ms);
    ImGui::Render();
    glBindFramebuffer(GL_FRAMEBUFFER, target_);
    if (panel_) ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  }
  if (shot_at_exit && options_.screenshot_panel) {
    check_screenshot_path();
    render::write_png(read_frame(target_, fb_w, fb_h), screenshot_path_);
  }
}

ViewerReport Viewer::run() {
  Surface surface(options_, &input_);
  gl_ = plan::current_gl();
  view_settings_.quad_pixels = plan::preview_quad_pixels(gl_);
  target_ = surface.target();
  GLFWwindow* window = surface.window();
  // Headless, the surface sets up the UI for a --screenshot-panel only.
  ui_ = surface.has_ui();
  if (!window) panel_ = ui_;

  // GL objects go before the context, also when a frame throws.
  struct GlGuard {
    Viewer& v;
    ~GlGuard() {
      v.scene_renderer_.reset();
      v.snow_.reset();
      v.sim_.reset();
    }
  } gl_guard{*this};

  ViewerReport report;
  {
    sim_ = std::make_unique<LiveSim>(scene_, options_.sim, gl_, options_.receives);
    snow_ = std::make_unique<SnowView>();
    scene_renderer_ = std::make_unique<render::PreviewRenderer>(scene_);
    sync_view();
    log_info("live snow grid: " + std::to_string(snow_->triangle_count()) +
             " triangles at its finest level (stride " + std::to_string(stride_) + ")");

    glm::ivec2 size = surface.poll();
    aspect_ = float(std::max(size.x, 1)) / float(std::max(size.y, 1));
    orbit_.azimuth = options_.azimuth;
    orbit_.elevation = options_.elevation;
    orbit_.fov = options_.fov;
    orbit_.top = options_.top_view;
    orbit_.frame(scene_.bounds, aspect_);
    orbit_.distance /= options_.zoom;
    if (window) glfwGetCursorPos(window, &last_x_, &last_y_);

    const auto start = Clock::now();
    Clock::time_point steady_start = start;
    double sum_stabilize = 0, sum_scene = 0, sum_snow = 0;
    double frame_ms = 0;
    int64_t frames = 0;
    while (!surface.closed()) {
      const auto frame_start = Clock::now();
      size = surface.poll();
      if (size.x < 1 || size.y < 1) {  // minimised
        glfwWaitEvents();
        continue;
      }
      aspect_ = float(size.x) / float(size.y);
      surface.new_frame(frame_ms * 1e-3);
      if (window) handle_input(window, size.y);
      if (want_frame_) {
        orbit_.frame(scene_.bounds, aspect_);
        want_frame_ = false;
      }

      // Simulate.
      if (!paused_ || step_once_) {
        sim_->step();
        step_once_ = false;
      }
      const bool last = options_.frames > 0 && frames + 1 >= options_.frames;
      if (tracks_due_ && (last || (!sim_->snowing() && sim_->last_result().converged))) {
        press_tracks();
      }
      sync_view();

      draw_frame(size.x, size.y, last, frame_ms);
      surface.present();

      ++frames;
      frame_ms = ms_since(frame_start);
      if (frames == 5) steady_start = Clock::now();
      if (frames > 5) {
        sum_stabilize += (sim_->timings().add + sim_->timings().stabilize) * 1e3;
        sum_scene += scene_ms_;
        sum_snow += snow_ms_;
      }
      if (last) break;
    }
    report.frames = frames;
    report.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    const int64_t steady = frames - 5;
    if (steady > 0) {
      report.fps =
          double(steady) / std::chrono::duration<double>(Clock::now() - steady_start).count();
      report.stabilize_ms = sum_stabilize / double(steady);
      report.scene_ms = sum_scene / double(steady);
      report.snow_ms = sum_snow / double(steady);
    } else if (report.seconds > 0) {
      report.fps = double(frames) / report.seconds;
    }
    report.snow_triangles = snow_->drawn_triangles();
    report.volume = snow_volume(sim_->maps(), sim_->depth());
    report.fallen = sim_->fallen_volume();
    if (sim_->snowpack()) {
      sim_->sync_snowpack();
      const SnowPack& pack = *sim_->snowpack();
      report.hour = sim_->weather_hour();
      report.water_fallen = pack.fallen;
      report.water_melted = pack.melted;
      report.water_lost = pack.lost;
      report.water_lying = pack.lying(sim_->maps());
    }

    if (!options_.export_path.empty()) {
      log_info(export_snow(scene_, *sim_, options_, options_.export_path, options_.snow_only));
    }
    if (!options_.maps_path.empty()) log_info(export_maps(*sim_, options_, options_.maps_path));
  }
  return report;
}

}  // namespace

ViewerReport run_viewer(const Scene& scene, const ViewerOptions& options) {
  if (options.width < 1 || options.height < 1)
    throw InputError("window size " + std::to_string(options.width) + "x" +
                     std::to_string(options.height) + " is empty");
  if (!(options.zoom > 0.0f) || !std::isfinite(options.zoom))
    throw InputError("--zoom must be a positive number");
  if (options.frames < 0) throw InputError("--frames must be 0 (until closed) or more");
  if (options.headless && options.frames == 0)
    throw InputError("--headless needs --frames N (no window to close)");
  if (options.headless && gl::parse_backend(options.gl_backend) == gl::Backend::Glfw)
    throw InputError("--headless draws off-screen; --gl-backend glfw opens a window");
  Viewer viewer(scene, options);
  return viewer.run();
}

}  // namespace snow::live

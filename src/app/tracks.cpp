#include "app/tracks.h"

#include <cstdio>

#include "app/filters.h"
#include "core/error.h"
#include "core/log.h"
#include "plan/rules.h"
#include "snow/stabilize.h"

namespace snow::app {
namespace {

/// Press or Clear for a thing named `name` that `press` and `clear` say
/// match it; nothing where neither does.
std::optional<TrackMode> mode_of(bool press, bool clear, const std::string& name) {
  if (press && clear) throw InputError("--track and --clear both name '" + name + "'");
  if (press) return TrackMode::Press;
  if (clear) return TrackMode::Clear;
  return std::nullopt;
}

/// The box of a source's shape at rest (its lines without their width).
Bounds rest_bounds(const TrackSource& source) {
  Bounds rest;
  for (const glm::vec3& p : source.triangles) rest.extend(p);
  for (const glm::vec3& p : source.segments) rest.extend(p);
  return rest;
}

/// The poses of the thing at node `node` (none where it does not move).
std::vector<glm::mat4> poses_of(const Scene& scene, int node, const TrackSource& source,
                                float texel) {
  for (const NodeMotion& motion : scene.motions) {
    if (motion.node != node) continue;
    return track_poses(motion.moves, rest_bounds(source),
                       float(plan::kTrackPoseSpacingTexels) * texel, plan::kMaxTrackPoses,
                       source.name);
  }
  return {};
}

/// InputError where pressing `source` at its poses would take more than
/// plan::kMaxTrackWork.
void check_work(const TrackSource& source, float texel) {
  const glm::vec3 size = rest_bounds(source).size() + glm::vec3(source.width);
  const double texels = (double(size.x) / texel + 2.0) * (double(size.z) / texel + 2.0);
  const double shapes = double(source.triangles.size() / 3 + source.segments.size() / 2);
  const double work = double(std::max<size_t>(source.poses.size(), 1)) * (shapes + texels);
  if (work > plan::kMaxTrackWork) {
    char line[300];
    std::snprintf(line, sizeof line,
                  "tracks: '%s' would take %.3g triangle and texel visits (%zu poses), over %.3g: "
                  "press with a simpler shape, a shorter animation or coarser maps",
                  source.name.c_str(), work, source.poses.size(), plan::kMaxTrackWork);
    throw InputError(line);
  }
}

}  // namespace

std::vector<TrackSource> track_sources(const Scene& scene, const PipelineSettings& s, float texel) {
  warn_unmatched(scene, s.track, "--track", true);
  warn_unmatched(scene, s.clear, "--clear", true);
  std::vector<TrackSource> sources;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    const auto mode = mode_of(matches(s.track, o), matches(s.clear, o), o.name);
    if (!mode || o.triangle_count == 0) continue;
    TrackSource source;
    source.name = o.name;
    source.mode = *mode;
    source.object = int(i);
    const auto first = scene.positions.begin() + ptrdiff_t(size_t(o.first_triangle) * 3);
    source.triangles.assign(first, first + ptrdiff_t(size_t(o.triangle_count) * 3));
    source.poses = poses_of(scene, o.node, source, texel);
    check_work(source, texel);
    sources.push_back(std::move(source));
  }
  for (const SceneLines& l : scene.lines) {
    const auto mode = mode_of(matches(s.track, l), matches(s.clear, l), l.name);
    if (!mode || l.segments.empty()) continue;
    TrackSource source;
    source.name = l.name;
    source.mode = *mode;
    source.segments = l.segments;
    source.width = s.track_width;
    source.poses = poses_of(scene, l.node, source, texel);
    check_work(source, texel);
    sources.push_back(std::move(source));
  }
  return sources;
}

TrackSettings track_settings(const PipelineSettings& s) {
  TrackSettings t;
  t.pressure_kpa = s.track_load;
  t.repose_deg = s.stabilize.repose_deg;
  return t;
}

std::vector<float> press_tracks(const SnowMaps& maps, SnowPack& pack,
                                const std::vector<TrackSource>& sources,
                                const PipelineSettings& s) {
  std::vector<float> compaction;
  const TrackResult r = make_tracks(maps, pack, sources, track_settings(s), &compaction);
  char line[400];
  std::snprintf(line, sizeof line,
                "tracks: %zu source(s) at %zu pose(s): %zu texels pressed, %zu cleared; water "
                "equivalent %.4g m^3 kept in the tracks, %.4g moved into berms and piles",
                sources.size(), r.poses, r.pressed, r.cleared, r.compacted, r.moved);
  log_info(line);
  if (r.pressed + r.cleared == 0) {
    log_warn(
        "tracks: nothing was pressed or cleared: the sources touch no snow (a source's own "
        "surfaces are never pressed)");
  }
  return compaction;
}

std::vector<float> tracks_in_snow(SnowResult& snow, const SnowMaps& maps,
                                  const std::vector<TrackSource>& sources,
                                  const PipelineSettings& s) {
  SnowPack settled = settled_pack(maps, snow.depth);
  std::vector<float> compaction = press_tracks(maps, settled, sources, s);
  snow.depth = std::move(settled.depth);
  snow.volume = snow_volume(maps, snow.depth);
  return compaction;
}

void tracks_in_weather(WeatherRun& run, const SnowMaps& maps,
                       const std::vector<TrackSource>& sources, const PipelineSettings& s,
                       std::vector<float>& compaction) {
  const WeatherStep& last = run.steps.back();
  const double end = last.hour + last.hours;
  if (s.track_hour > end + 1e-9) {
    char line[200];
    std::snprintf(line, sizeof line, "--track-hour %.6g is after the weather's end (hour %.6g)",
                  s.track_hour, end);
    throw InputError(line);
  }
  run.tracks_hour = s.track_hour >= 0.0 ? s.track_hour : end;
  run.on_tracks = [&maps, &sources, &s, &compaction](SnowPack& now) {
    compaction = press_tracks(maps, now, sources, s);
  };
}

}  // namespace snow::app

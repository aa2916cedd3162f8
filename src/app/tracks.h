#pragma once
// Tracks in the snow for the snow command (snow/tracks.h): the sources that
// --track and --clear name in the scene, and the step that presses them.
#include <string>
#include <vector>

#include "app/settings.h"
#include "scene/scene.h"
#include "snow/accumulate.h"
#include "snow/maps.h"
#include "snow/snowpack.h"
#include "snow/tracks.h"

namespace snow::app {

/// Whether the settings ask for tracks.
inline bool wants_tracks(const PipelineSettings& s) { return !s.track.empty() || !s.clear.empty(); }

/// The sources of `scene` (metres, +Y up): every object and glTF line whose
/// name or node path matches a --track glob (pressing) or a --clear glob
/// (clearing; lines --track-width wide); an animated one goes through its
/// node's motion at poses plan::kTrackPoseSpacingTexels texels of `texel`
/// apart. Warns for a glob that matches nothing; throws InputError for a
/// thing both match, a motion of more than plan::kMaxTrackPoses poses, or a
/// source whose pressing would take more than plan::kMaxTrackWork visits.
std::vector<TrackSource> track_sources(const Scene& scene, const PipelineSettings& s, float texel);

/// The tracks' settings: --track-load, the stabilizer's angle of repose.
TrackSettings track_settings(const PipelineSettings& s);

/// Presses `sources` into `pack` (make_tracks), logs what it did and
/// returns the compaction per layer texel (make_tracks' `compaction`).
std::vector<float> press_tracks(const SnowMaps& maps, SnowPack& pack,
                                const std::vector<TrackSource>& sources, const PipelineSettings& s);

/// A run without weather: `sources` pressed into the snow of `snow` (taken
/// at kSettledSnowDensity); its depth and volume follow. Returns the
/// compaction as press_tracks.
std::vector<float> tracks_in_snow(SnowResult& snow, const SnowMaps& maps,
                                  const std::vector<TrackSource>& sources,
                                  const PipelineSettings& s);

/// A weather run: `sources` pressed at --track-hour (the end of the run
/// where it is negative) into the pack (WeatherRun::on_tracks), the
/// compaction into `compaction`. `maps`, `sources`, `s` and `compaction`
/// must outlive the run. Throws InputError for an hour after the run's end.
void tracks_in_weather(WeatherRun& run, const SnowMaps& maps,
                       const std::vector<TrackSource>& sources, const PipelineSettings& s,
                       std::vector<float>& compaction);

}  // namespace snow::app

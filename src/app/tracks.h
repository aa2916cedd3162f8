#pragma once
// Tracks in the snow for the snow command (snow/tracks.h): the sources that
// --track and --clear name in the scene, and the step that presses them.
#include <string>
#include <vector>

#include "app/settings.h"
#include "scene/scene.h"
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
/// thing both match, or a motion of more than plan::kMaxTrackPoses poses.
std::vector<TrackSource> track_sources(const Scene& scene, const PipelineSettings& s, float texel);

/// The tracks' settings: --track-load, the stabilizer's angle of repose.
TrackSettings track_settings(const PipelineSettings& s);

/// Presses `sources` into `pack` (make_tracks), logs what it did and
/// returns the compaction per layer texel (make_tracks' `compaction`).
std::vector<float> press_tracks(const SnowMaps& maps, SnowPack& pack,
                                const std::vector<TrackSource>& sources, const PipelineSettings& s);

}  // namespace snow::app

#pragma once
// The batch job's weather runs (`snowmodel snow --weather`): the run from the
// settings, the snowpack to start from (--resume), and the maps and
// sequence frames it writes (snow/accumulate.h, accumulate_weather).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "app/settings.h"
#include "mesh/write_maps.h"
#include "snow/accumulate.h"
#include "snow/snowpack.h"

namespace snow::app {

/// The weather run of the settings (none without --weather): the file read
/// and checked, the start time parsed, the compass from --north. Throws
/// InputError naming the problem (the file's line and column).
std::optional<WeatherRun> weather_run_of(const PipelineSettings& settings);

/// The deepest fresh snow the run can lay on open ground, metres: what the
/// planner sizes the maps for (plan::Settings::fall_depth).
float weather_fall_depth(const WeatherRun& run);

/// The pack to start from: empty, or read back from a maps folder written by
/// an earlier --weather run of the same scene and grid, whose hours of weather
/// end no later than `first_hour`, the file's first (InputError naming the
/// mismatch otherwise). `hour` receives the hours behind it.
SnowPack starting_pack(const std::string& resume_dir, const SnowMaps& maps, double first_hour,
                       double& hour);

}  // namespace snow::app

#pragma once
// The outputs of the commands that write snow (snowmodel snow, snowmodel
// merge): their options, their checks before the work starts, and their
// writing (meshes, maps and the settings beside them).
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mesh/export.h"
#include "mesh/output_policy.h"
#include "mesh/polygonize.h"
#include "mesh/write_maps.h"
#include "scene/frame.h"

namespace snow::app {

/// What a run writes.
struct MeshOutputs {
  std::string input;        // the scene (outputs never replace it or its files)
  std::string output;       // the input scene plus snow (glb/gltf), or snow only (obj/ply)
  std::string snow_output;  // the snow only
  std::string format;       // overrides the extension of `output`
  std::string maps_dir;     // the maps (mesh/write_maps.h)
  std::string preview;      // a before/after PNG (the snow command)
  bool snow_only = false;   // `output` holds the snow only, also as glb/gltf
};

/// Adds -o/--output, --snow-output, --format, --snow-only and --maps (and
/// --preview with `preview`) to `cmd`, bound to `o`.
void add_output_options(CLI::App& cmd, MeshOutputs& o, bool preview);

/// Where the settings of the run are written: beside the first output.
std::filesystem::path settings_path(const MeshOutputs& o);

/// The outputs for the output policy (mesh/output_policy.h); `format` is
/// that of `output`.
std::vector<OutputPath> output_paths(const MeshOutputs& o, MeshFormat format);

/// Checks the outputs before the work starts: something to write, the
/// format against the extension, the folders, the output policy. Returns
/// the format of `output`. Throws InputError or IOError naming the output.
MeshFormat check_outputs(const MeshOutputs& o);

/// Writes `output`, `snow_output`, `maps_dir` (with `coverage`, `depth` and
/// `snowpack` and `extra` where given) and the settings record (`settings`, as
/// settings_to_json writes them) beside the first output. The meshes go
/// back to the file's frame (`frame`); the maps stay in metres, +Y up.
/// `combined_input`: the scene for a glb/gltf `output` that is not snow
/// only (plan_combined_gltf), else null.
void write_outputs(const MeshOutputs& o, MeshFormat format, CombinedInputPtr combined_input,
                   const std::vector<SnowPatch>& metre_patches, const FileFrame& frame,
                   const SnowMaps& maps, const std::vector<float>* coverage,
                   const std::vector<float>* depth, const MapsSnowpack* snowpack,
                   const nlohmann::json& settings, const MapsExtra* extra = nullptr);

}  // namespace snow::app

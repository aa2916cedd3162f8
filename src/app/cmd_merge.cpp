// `snowmodel merge DIR [outputs]`: the tiles that `snowmodel snow --tiles`
// wrote into DIR joined into the untiled run's maps and meshed in one piece
// (app/tiles.h), written as `snowmodel snow` writes its outputs.
#include <cstdio>

#include "app/commands.h"
#include "app/filters.h"
#include "app/outputs.h"
#include "app/settings.h"
#include "app/tiles.h"
#include "core/error.h"
#include "core/log.h"
#include "scene/load_gltf.h"

namespace snow::app {
namespace {

struct MergeOptions {
  std::string dir;
  MeshOutputs out;
  double memory_budget_gib = PipelineSettings().memory_budget_gib;
};

void run_merge(MergeOptions o) {
  if (o.out.output.empty() && o.out.snow_output.empty() && o.out.maps_dir.empty()) {
    throw InputError("nothing to write: give -o OUT, --snow-output or --maps");
  }
  PipelineSettings budget;
  budget.memory_budget_gib = o.memory_budget_gib;
  check_settings(budget);  // its range
  MergedTiles tiles = read_tiles(o.dir, memory_budget_bytes(o.memory_budget_gib));
  o.out.input = tiles.input;
  const MeshFormat format = check_outputs(o.out);
  PipelineSettings s;
  settings_from_json(nlohmann::json::parse(tiles.settings), s);
  s.memory_budget_gib = o.memory_budget_gib;
  check_settings(s);
  resolve_snow_settings(s);
  s.load.limits.memory_budget = memory_budget_bytes(s.memory_budget_gib);

  // The scene as the tiles saw it: its objects name the patches, and a
  // glb/gltf output holds it with the snow.
  const bool combined = !o.out.output.empty() && !o.out.snow_only &&
                        (format == MeshFormat::Glb || format == MeshFormat::Gltf);
  s.load.keep_source = combined;
  Scene loaded = load_scene(tiles.input, s.load);
  CombinedInputPtr combined_input;
  if (combined) combined_input = plan_combined_gltf(*loaded.source);
  loaded.source.reset();
  const FileFrame frame = file_frame(s);
  to_metres_y_up(loaded, frame);
  const Scene scene =
      without_sky_enclosures(without_ignored(std::move(loaded), s.ignore), s.keep_enclosures);
  for (const int32_t object : tiles.maps.object) {
    if (object >= int32_t(scene.objects.size())) {
      throw InputError("merge: " + tiles.input +
                       " has fewer objects than the tiles saw: the scene changed since");
    }
  }
  log_info("merge: " + std::to_string(tiles.split.columns * tiles.split.rows) + " tiles, " +
           std::to_string(tiles.maps.grid.width) + " x " + std::to_string(tiles.maps.grid.height) +
           " texels of " + std::to_string(tiles.maps.grid.texel) + " m, " +
           std::to_string(tiles.maps.layers) + " layers");
  const std::vector<SnowPatch> patches = polygonize(tiles.maps, tiles.depth, scene, s.polygonize);
  write_outputs(o.out, format, std::move(combined_input), patches, frame, tiles.maps,
                &tiles.coverage, &tiles.depth, nullptr, nlohmann::json::parse(tiles.settings));
  size_t triangles = 0;
  for (const SnowPatch& p : patches) triangles += p.mesh.indices.size() / 3;
  char line[200];
  std::snprintf(line, sizeof line, "summary: snow out %zu in %zu patches; snow %.3f m^3", triangles,
                patches.size(), snow_volume(tiles.maps, tiles.depth));
  log_info(line);
}

}  // namespace

void register_merge(CLI::App& app, const GlobalOptions&) {
  auto o = std::make_shared<MergeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "merge", "Join the tiles of `snowmodel snow --tiles` into the outputs one run writes");
  cmd->add_option("dir", o->dir, "The --tile-dir the tiles were written to")->required();
  add_output_options(*cmd, o->out, false);
  cmd->add_option("--memory-budget", o->memory_budget_gib,
                  "Stop before the merged maps or the scene need more than this, GiB")
      ->capture_default_str();
  cmd->callback([o] { run_merge(*o); });
}

}  // namespace snow::app

// The outputs of the snow and merge commands (app/outputs.h).
#include "app/outputs.h"

#include "app/settings.h"
#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"

namespace snow::app {
namespace fs = std::filesystem;

void add_output_options(CLI::App& cmd, MeshOutputs& o, bool preview) {
  cmd.add_option("-o,--output", o.output,
                 "Output: the input scene plus snow (.glb, .gltf), or snow only (.obj, .ply)");
  cmd.add_option("--snow-output", o.snow_output,
                 "Also write the snow only (.glb, .gltf, .obj, .ply)");
  cmd.add_option("--format", o.format,
                 "Format of --output: obj or ply override its extension; glb and gltf must match "
                 "it")
      ->check(CLI::IsMember({"glb", "gltf", "obj", "ply"}));
  cmd.add_flag("--snow-only", o.snow_only, "Write only the snow to --output");
  cmd.add_option("--maps", o.maps_dir,
                 "Write height, coverage and depth maps (EXR, PNG, manifest.json) here");
  if (preview) {
    cmd.add_option("--preview", o.preview, "Write a before/after preview PNG (3/4 and top views)");
  }
}

fs::path settings_path(const MeshOutputs& o) {
  const fs::path first = !o.output.empty()        ? fs::path(o.output)
                         : !o.snow_output.empty() ? fs::path(o.snow_output)
                         : !o.maps_dir.empty()    ? fs::path(o.maps_dir) / "snow"
                                                  : fs::path(o.preview);
  return first.string() + ".settings.json";
}

std::vector<OutputPath> output_paths(const MeshOutputs& o, MeshFormat format) {
  std::vector<OutputPath> outputs;
  if (!o.output.empty()) outputs.push_back({"-o", o.output, OutputKind::Mesh, format, {}});
  if (!o.snow_output.empty()) {
    outputs.push_back(
        {"--snow-output", o.snow_output, OutputKind::Mesh, format_from_path(o.snow_output), {}});
  }
  if (!o.maps_dir.empty()) outputs.push_back({"--maps", o.maps_dir, OutputKind::Maps, {}, {}});
  if (!o.preview.empty()) outputs.push_back({"--preview", o.preview, OutputKind::File, {}, {}});
  // The settings file goes beside the first file output; in the maps
  // folder, it is written after the folder is in place.
  if (!outputs.empty() && outputs.front().kind != OutputKind::Maps) {
    outputs.front().beside.push_back(settings_path(o));
  }
  return outputs;
}

MeshFormat check_outputs(const MeshOutputs& o) {
  MeshFormat format = MeshFormat::Glb;
  if (!o.output.empty()) {
    format = o.format.empty() ? format_from_path(o.output) : format_from_path("x." + o.format);
    // glTF is written as binary or JSON by the file's extension (a .gltf
    // with its .bin beside it), so --format glb or gltf must agree with it.
    const std::string wanted = std::string(".") + format_name(format);
    if ((format == MeshFormat::Glb || format == MeshFormat::Gltf) &&
        lower_extension(o.output) != wanted) {
      throw InputError(o.output + ": a " + format_name(format) + " file needs the extension " +
                       wanted);
    }
  }
  for (const std::string& path : {o.output, o.snow_output, o.preview}) {
    if (path.empty()) continue;
    const fs::path folder =
        fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
    if (!fs::is_directory(folder))
      throw IOError("cannot write " + path + ": folder " + folder.string() + " does not exist");
  }
  check_output_paths(o.input, output_paths(o, format));
  return format;
}

void write_outputs(const MeshOutputs& o, MeshFormat format, CombinedInputPtr combined_input,
                   const std::vector<SnowPatch>& metre_patches, const FileFrame& frame,
                   const SnowMaps& maps, const std::vector<float>* coverage,
                   const std::vector<float>* depth, const MapsSnowpack* snowpack,
                   const nlohmann::json& settings, const MapsExtra* extra) {
  std::vector<SnowPatch> file_patches;
  if (!frame.is_identity()) {
    file_patches = metre_patches;
    for (SnowPatch& p : file_patches) to_file_frame(p.mesh, frame);
  }
  const std::vector<SnowPatch>& patches = frame.is_identity() ? metre_patches : file_patches;
  if (!o.output.empty()) {
    if (combined_input) {
      write_combined_gltf(std::move(combined_input), patches, o.output);
    } else {
      if (!o.snow_only) log_info(std::string(format_name(format)) + " holds the snow only");
      write_snow_meshes(patches, o.output, format);
    }
    log_info("wrote " + o.output);
  }
  if (!o.snow_output.empty()) {
    write_snow_meshes(patches, o.snow_output, format_from_path(o.snow_output));
    log_info("wrote " + o.snow_output);
  }
  if (!o.maps_dir.empty()) {
    write_maps(o.maps_dir, maps, coverage, depth, snowpack, extra);
    log_info("wrote maps to " + o.maps_dir);
  }
  nlohmann::json record;
  record["snowmodel"] = "0.1.0";
  record["input"] = o.input;
  record["settings"] = settings;
  write_text_atomically(settings_path(o), record.dump(2) + "\n");
}

}  // namespace snow::app

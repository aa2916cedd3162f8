// tools/gen_assets: remakes the scenes in assets/ from code.
//   snowmodel_gen_assets <out_dir>   writes <out_dir>/courtyard.glb
// The project's copy lives in assets/scenes/courtyard.glb; regenerate it with
//   build/<dir>/tools/snowmodel_gen_assets assets/scenes
// Output is deterministic: the same build writes byte-identical files.
#include <tiny_gltf.h>

#include <exception>
#include <filesystem>
#include <iostream>
#include <string>

#include "core/error.h"
#include "mesh/gltf_writer.h"
#include "scene/builder.h"

int main(int argc, char** argv) {
  if (argc != 2 || std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help") {
    std::cerr << "usage: snowmodel_gen_assets <out_dir>\n"
                 "writes <out_dir>/courtyard.glb (the demo courtyard scene)\n";
    return argc == 2 ? 0 : snow::kExitBadInput;
  }
  try {
    const std::filesystem::path out_dir = argv[1];
    std::error_code ec;
    std::filesystem::create_directories(out_dir, ec);
    if (ec) throw snow::IOError("cannot create folder " + out_dir.string() + ": " + ec.message());

    const snow::SceneBuilder courtyard = snow::make_courtyard();
    tinygltf::Model model;
    model.asset.generator = "snowmodel_gen_assets";
    snow::append_meshes(model, courtyard.meshes(), courtyard.materials(), "Courtyard");
    const std::filesystem::path path = out_dir / "courtyard.glb";
    snow::save_gltf(model, path);
    std::cout << "wrote " << path.string() << " (" << courtyard.objects().size() << " objects, "
              << courtyard.build().triangle_count() << " triangles)\n";
    return snow::kExitOk;
  } catch (const snow::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return e.exit_code();
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << e.what() << "\n";
    return snow::kExitInternal;
  }
}

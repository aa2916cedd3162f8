// tools/gen_assets: remakes the scenes in assets/ from code.
//   snowmodel_gen_assets <out_dir>   writes <out_dir>/courtyard.glb
//   snowmodel_gen_assets --terrain <triangles> <file.glb>
//                                     writes a benchmark terrain (snow::make_terrain)
//   snowmodel_gen_assets --truck <file.glb>
//                                     writes a delivery truck (snow::make_truck)
//   snowmodel_gen_assets --wind-yard <file.glb>
//                                     writes the wind's test yard (snow::make_wind_yard)
// The project's copy lives in assets/scenes/courtyard.glb; regenerate it with
//   build/<dir>/tools/snowmodel_gen_assets assets/scenes
// Output is deterministic: the same build writes byte-identical files.
#include <tiny_gltf.h>

#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>

#include "core/error.h"
#include "mesh/gltf_writer.h"
#include "scene/builder.h"

namespace {

void write(const snow::SceneBuilder& builder, const std::string& root,
           const std::filesystem::path& path) {
  tinygltf::Model model;
  model.asset.generator = "snowmodel_gen_assets";
  snow::append_meshes(model, builder.meshes(), builder.materials(), root);
  snow::save_gltf(model, path);
  std::cout << "wrote " << path.string() << " (" << builder.objects().size() << " objects, "
            << builder.build().triangle_count() << " triangles)\n";
}

}  // namespace

int main(int argc, char** argv) {
  const bool terrain = argc == 4 && std::string(argv[1]) == "--terrain";
  const bool truck = argc == 3 && std::string(argv[1]) == "--truck";
  const bool wind_yard = argc == 3 && std::string(argv[1]) == "--wind-yard";
  if (!(argc == 2 || terrain || truck || wind_yard) || std::string(argv[1]) == "-h" ||
      std::string(argv[1]) == "--help") {
    std::cerr << "usage: snowmodel_gen_assets <out_dir>\n"
                 "         writes <out_dir>/courtyard.glb (the demo courtyard scene)\n"
                 "       snowmodel_gen_assets --terrain <triangles> <file.glb>\n"
                 "         writes a benchmark terrain of about that many triangles\n"
                 "       snowmodel_gen_assets --truck <file.glb>\n"
                 "         writes a delivery truck on a ground (snow::make_truck)\n"
                 "       snowmodel_gen_assets --wind-yard <file.glb>\n"
                 "         writes a cube, a fence and a roof step (snow::make_wind_yard)\n";
    return argc == 2 ? 0 : snow::kExitBadInput;
  }
  try {
    if (truck || wind_yard) {
      write(truck ? snow::make_truck() : snow::make_wind_yard(), truck ? "Truck" : "WindYard",
            argv[2]);
      return snow::kExitOk;
    }
    if (terrain) {
      const long triangles = std::strtol(argv[2], nullptr, 10);
      if (triangles < 300 || triangles > 100000000) {
        throw snow::InputError("--terrain wants 300 to 100000000 triangles, got " +
                               std::string(argv[2]));
      }
      write(snow::make_terrain(int(triangles)), "Terrain", argv[3]);
      return snow::kExitOk;
    }
    const std::filesystem::path out_dir = argv[1];
    std::error_code ec;
    std::filesystem::create_directories(out_dir, ec);
    if (ec) throw snow::IOError("cannot create folder " + out_dir.string() + ": " + ec.message());
    write(snow::make_courtyard(), "Courtyard", out_dir / "courtyard.glb");
    return snow::kExitOk;
  } catch (const snow::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return e.exit_code();
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << e.what() << "\n";
    return snow::kExitInternal;
  }
}

// Snow mesh export, the pipeline's last stage (mesh/export.h;
// docs/ARCHITECTURE.md). glTF files follow the Khronos glTF 2.0
// specification (images in buffer views: section 3.8.2 "Images"); OBJ and
// PLY are written by obj_writer.cpp and ply_writer.cpp.
#include "mesh/export.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <system_error>

#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"
#include "mesh/glb_stream.h"
#include "mesh/gltf_writer.h"
#include "mesh/obj_writer.h"
#include "mesh/ply_writer.h"

namespace snow {
namespace fs = std::filesystem;

namespace {

std::vector<TriMesh> patch_meshes(const std::vector<SnowPatch>& patches) {
  std::vector<TriMesh> meshes;
  meshes.reserve(patches.size());
  for (const SnowPatch& p : patches) {
    if (p.mesh.indices.size() < 3) continue;
    meshes.push_back(p.mesh);
    meshes.back().material = 0;
  }
  return meshes;
}

/// Fails early, before any file (a .bin, a .mtl beside the target) is
/// written, when `path` cannot be the output.
void check_output_path(const fs::path& path) {
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw IOError("cannot write " + path.string() + ": folder " + folder.string() +
                  " does not exist");
  }
  if (fs::is_directory(path, ec))
    throw IOError("cannot write " + path.string() + ": it is a folder");
}

}  // namespace

MeshFormat format_from_path(const fs::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".glb") return MeshFormat::Glb;
  if (ext == ".gltf") return MeshFormat::Gltf;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".ply") return MeshFormat::Ply;
  throw InputError(path.string() + ": unknown mesh format '" + path.extension().string() +
                   "' (use .glb, .gltf, .obj or .ply)");
}

const char* format_name(MeshFormat format) {
  switch (format) {
    case MeshFormat::Glb:
      return "glb";
    case MeshFormat::Gltf:
      return "gltf";
    case MeshFormat::Obj:
      return "obj";
    case MeshFormat::Ply:
      return "ply";
  }
  return "?";
}

MeshMaterial snow_material() {
  MeshMaterial m;
  m.name = "snow";
  m.base_color = glm::vec4(0.9f, 0.9f, 0.9f, 1.0f);
  m.roughness = 0.8f;
  m.metallic = 0.0f;
  return m;
}

void write_snow_meshes(const std::vector<SnowPatch>& patches, const fs::path& path,
                       MeshFormat format) {
  check_output_path(path);
  const std::vector<TriMesh> meshes = patch_meshes(patches);
  switch (format) {
    case MeshFormat::Glb:
    case MeshFormat::Gltf: {
      if (lower_extension(path) != (format == MeshFormat::Glb ? ".glb" : ".gltf")) {
        throw InputError(path.string() + ": a " + format_name(format) +
                         " file needs the extension ." + format_name(format));
      }
      tinygltf::Model model;
      append_meshes(model, meshes, {snow_material()}, "Snow");
      save_gltf(std::move(model), path);
      break;
    }
    case MeshFormat::Obj:
      write_obj(meshes, snow_material(), path);
      break;
    case MeshFormat::Ply:
      write_ply(meshes, path);
      break;
  }
}

void CombinedInputDeleter::operator()(CombinedInput* input) const { delete input; }

namespace {

void check_combined_output(const fs::path& out) {
  const std::string out_ext = lower_extension(out);
  if (out_ext != ".glb" && out_ext != ".gltf") {
    throw InputError(out.string() + ": the scene plus snow is written as .glb or .gltf only");
  }
  check_output_path(out);
}

}  // namespace

CombinedInputPtr plan_combined_gltf(const SourceGltf& source) {
  return CombinedInputPtr(new CombinedInput(plan_combined(source)));
}

void write_combined_gltf(CombinedInputPtr input, const std::vector<SnowPatch>& patches,
                         const fs::path& out) {
  check_combined_output(out);
  write_combined(*input, patch_meshes(patches), out);
}

void write_combined_gltf(const SourceGltf& source, const std::vector<SnowPatch>& patches,
                         const fs::path& out) {
  check_combined_output(out);  // before planning
  CombinedInput plan = plan_combined(source);
  write_combined(plan, patch_meshes(patches), out);
}

}  // namespace snow

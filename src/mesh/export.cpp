// Snow mesh export, the pipeline's last stage (mesh/export.h;
// docs/ARCHITECTURE.md). glTF files follow the Khronos glTF 2.0
// specification (images in buffer views: section 3.8.2 "Images"); OBJ and
// PLY are written by obj_writer.cpp and ply_writer.cpp.
#include "mesh/export.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cctype>
#include <optional>
#include <sstream>
#include <system_error>

#include "core/error.h"
#include "core/fs.h"
#include "core/log.h"
#include "mesh/glb_stream.h"
#include "mesh/gltf_writer.h"
#include "mesh/obj_writer.h"
#include "mesh/ply_writer.h"
#include "mesh/tinygltf_input.h"
#include "scene/input_policy.h"
#include "scene/load_gltf.h"

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

/// tinygltf image callback that keeps the encoded bytes (in Image::image) of
/// images stored in files or data URIs instead of decoding them, so they can
/// be written back unchanged. Images in buffer views stay where they are.
bool keep_image_bytes(tinygltf::Image* image, const int /*index*/, std::string* /*err*/,
                      std::string* /*warn*/, int /*req_width*/, int /*req_height*/,
                      const unsigned char* bytes, int size, void* /*user_data*/) {
  image->image.clear();
  if (image->bufferView < 0 && bytes != nullptr && size > 0) {
    image->image.assign(bytes, bytes + size);
  }
  image->as_is = true;
  return true;
}

/// Moves every image held as bytes (from a file or a data URI) into buffer 0
/// as a new buffer view, with room for `then` more bytes after them.
void embed_images(tinygltf::Model& model, const fs::path& input, size_t then) {
  // What the images still to embed take (each padded to 4 bytes), and what
  // comes after them: buffer 0 grows once, not per image.
  size_t to_embed = then;
  for (const tinygltf::Image& image : model.images) {
    if (image.bufferView < 0) to_embed += image.image.size() + 3;
  }
  for (size_t i = 0; i < model.images.size(); ++i) {
    tinygltf::Image& image = model.images[i];
    if (image.bufferView >= 0) {
      image.image.clear();
      continue;
    }
    to_embed -= image.image.size() + 3;
    if (image.image.empty()) {
      log_warn(input.string() + ": image " + std::to_string(i) + " ('" + image.uri +
               "') could not be read; the output refers to it by its URI as it is");
      continue;
    }
    std::string mime = sniff_mime_type(image.image);
    if (mime.empty()) mime = image.mimeType;
    if (mime.empty()) {
      log_warn(input.string() + ": image " + std::to_string(i) + " ('" + image.uri +
               "') has an unknown format; the output refers to it by its URI as it is");
      image.image.clear();
      continue;
    }
    if (model.buffers.empty()) model.buffers.emplace_back();
    std::vector<unsigned char>& bytes = model.buffers[0].data;
    bytes.reserve(bytes.size() + image.image.size() + 3 + to_embed);
    bytes.resize((bytes.size() + 3) & ~size_t(3), 0);
    tinygltf::BufferView view;
    view.name = image.name.empty() ? "image" + std::to_string(i) : image.name;
    view.buffer = 0;
    view.byteOffset = bytes.size();
    view.byteLength = image.image.size();
    bytes.insert(bytes.end(), image.image.begin(), image.image.end());
    model.bufferViews.push_back(view);
    image.bufferView = int(model.bufferViews.size()) - 1;
    image.mimeType = mime;
    image.uri.clear();
    image.image.clear();
    image.as_is = false;
  }
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

/// True when `s` starts with `prefix` ignoring ASCII case; `prefix` is lower case.
bool starts_with_ci(const std::string& s, const char* prefix) {
  for (size_t i = 0; prefix[i]; ++i)
    if (i >= s.size() || std::tolower(static_cast<unsigned char>(s[i])) != prefix[i]) return false;
  return true;
}

/// First line of a tinygltf message.
std::string first_line(const std::string& text) {
  const size_t end = text.find('\n');
  return end == std::string::npos ? text : text.substr(0, end);
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

struct CombinedInput {
  fs::path path;
  std::optional<StreamPlan> plan;  // a GLB streamed from the input's files
  tinygltf::Model model;           // else the input as tinygltf reads it
  std::string warnings;            // tinygltf's, one per line
};

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

namespace {

/// The input policy (scene/input_policy.h) for the files tinygltf reads
/// (its FsCallbacks' user data): only regular files inside the scene's
/// folder, never the working folder tinygltf also searches.
struct TinyGltfFiles {
  fs::path folder;      // absolute
  std::string refused;  // the first file refused, why
  uint64_t max_file_bytes = LoadLimits{}.max_file_bytes;
};

bool policy_file_exists(const std::string& path, void* user) {
  auto& files = *static_cast<TinyGltfFiles*>(user);
  const fs::path file(path);
  std::error_code ec;
  // tinygltf's second guess is the working folder: "./<uri>".
  if (!file.is_absolute() || !fs::exists(file, ec)) return false;
  if (!inside_folder(files.folder, file)) {
    if (files.refused.empty()) files.refused = "'" + path + "' is outside the scene's folder";
    return false;
  }
  return true;
}

bool policy_read_file(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                      void* user) {
  auto& files = *static_cast<TinyGltfFiles*>(user);
  const fs::path file(path);
  std::string why;
  std::error_code ec;
  if (!inside_folder(files.folder, file)) {
    why = "is outside the scene's folder";
  } else if (why = regular_file_problem(file); why.empty()) {
    const uint64_t size = fs::file_size(file, ec);
    if (ec) {
      why = "cannot be read";
    } else if (size > files.max_file_bytes) {
      why = "is over the limit of " + std::to_string(files.max_file_bytes) +
            " bytes (LoadLimits::max_file_bytes)";
    } else {
      out->resize(size_t(size));
      if (read_regular_file(file, size, out->data(), &why)) return true;
    }
  }
  if (files.refused.empty()) files.refused = "'" + path + "' " + why;
  if (err) *err = why;
  return false;
}

void read_with_tinygltf(CombinedInput& input) {
  const uint64_t limit = LoadLimits{}.max_file_bytes;
  std::error_code ec;
  const uint64_t size = fs::file_size(input.path, ec);
  if (ec) throw IOError("cannot read " + input.path.string());
  if (size > limit || size > UINT32_MAX)  // tinygltf takes the size as 32 bits
    throw InputError(input.path.string() + ": over the limit of " + std::to_string(limit) +
                     " bytes (LoadLimits::max_file_bytes)");
  std::vector<unsigned char> bytes(static_cast<size_t>(size));
  std::string why;
  if (!read_regular_file(input.path, size, bytes.data(), &why))
    throw IOError("cannot read " + input.path.string() + ": " + why);
  check_json_depth(scene_json_text(bytes.data(), bytes.size()), input.path.string());

  TinyGltfFiles files;
  files.folder = fs::absolute(input.path).parent_path();
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keep_image_bytes, nullptr);
  loader.SetFsCallbacks({policy_file_exists, tinygltf::ExpandFilePath, policy_read_file,
                         tinygltf::WriteWholeFile, &files});
  std::string err;
  const bool binary = lower_extension(input.path) == ".glb";
  const std::string base = files.folder.string();
  // What tinygltf would refuse or change in a valid file is mended or
  // refused first (mesh/tinygltf_input.h).
  const TinygltfInput prepared = prepare_for_tinygltf(std::move(bytes), input.path, binary);
  if (prepared.bytes.size() > UINT32_MAX)
    throw InputError(input.path.string() + ": over 4 GiB, more than tinygltf reads");
  const bool ok =
      binary
          ? loader.LoadBinaryFromMemory(&input.model, &err, &input.warnings, prepared.bytes.data(),
                                        unsigned(prepared.bytes.size()), base)
          : loader.LoadASCIIFromString(&input.model, &err, &input.warnings,
                                       reinterpret_cast<const char*>(prepared.bytes.data()),
                                       unsigned(prepared.bytes.size()), base);
  if (!files.refused.empty())
    throw InputError(input.path.string() + ": " + files.refused + " (refused)");
  // What tinygltf did not look for (an absolute path it read as relative)
  // is refused as the loader refuses it.
  const auto check_uri = [&](const std::string& uri, const std::string& what) {
    std::string why;
    if (!uri.empty() && !starts_with_ci(uri, "data:") &&
        !resolve_relative_uri(fs::path(base), uri, &why))
      throw InputError(input.path.string() + ": " + what + ": uri '" + first_line(uri) + "' " +
                       why);
  };
  for (size_t i = 0; i < input.model.buffers.size(); ++i)
    check_uri(input.model.buffers[i].uri, "buffer " + std::to_string(i));
  for (size_t i = 0; i < input.model.images.size(); ++i)
    check_uri(input.model.images[i].uri, "image " + std::to_string(i));
  if (!ok) {
    throw InputError(input.path.string() + ": " +
                     (err.empty() ? std::string("not a valid glTF file") : first_line(err)));
  }
  restore_after_tinygltf(prepared, input.model);
}

}  // namespace

CombinedInputPtr read_combined_input(const fs::path& input_scene, const fs::path& out) {
  // Looked at before anything opens it: a FIFO would block the open.
  const std::string problem = regular_file_problem(input_scene);
  if (problem == "does not exist" || problem == "is a folder")
    throw IOError("cannot read " + input_scene.string() + ": no such file");
  if (!problem.empty()) throw InputError(input_scene.string() + ": " + problem);
  CombinedInputPtr input(new CombinedInput);
  input->path = input_scene;
  if (lower_extension(out) == ".glb") input->plan = plan_streamed_glb(input_scene);
  if (!input->plan) read_with_tinygltf(*input);
  return input;
}

namespace {

// write_combined_gltf once `out` is checked.
void write_checked_combined(CombinedInput& input, const std::vector<SnowPatch>& patches,
                            const fs::path& out) {
  if (input.plan && lower_extension(out) == ".glb") {
    write_streamed_glb(*input.plan, patch_meshes(patches), out);
    return;
  }
  if (input.plan) {  // read for a GLB, written as .gltf
    input.plan.reset();
    read_with_tinygltf(input);
  }
  std::istringstream lines(input.warnings);
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty()) log_warn(input.path.string() + ": " + line);
  }
  const std::vector<TriMesh> snow = patch_meshes(patches);
  embed_images(input.model, input.path, mesh_buffer_bytes(snow));
  append_meshes(input.model, snow, {snow_material()}, "Snow");
  save_gltf(std::move(input.model), out);
}

}  // namespace

void write_combined_gltf(CombinedInputPtr input, const std::vector<SnowPatch>& patches,
                         const fs::path& out) {
  check_combined_output(out);
  write_checked_combined(*input, patches, out);
}

void write_combined_gltf(const fs::path& input_scene, const std::vector<SnowPatch>& patches,
                         const fs::path& out) {
  check_combined_output(out);  // before reading the input
  write_checked_combined(*read_combined_input(input_scene, out), patches, out);
}

}  // namespace snow

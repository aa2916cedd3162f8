#pragma once
// The output policy of every command that writes (snow, render, preview and
// the preview panel's exports): the outputs a command names are checked
// together, before the long work starts, so that a careless command never
// destroys its input, a device or another output of the same run.
#include <filesystem>
#include <string>
#include <vector>

#include "mesh/export.h"

namespace snow {

enum class OutputKind {
  File,  // one file (a PNG, a text file)
  Mesh,  // a mesh file in OutputPath::format with the files its writer puts
         // beside it: a .gltf's "<stem>.bin", "<stem>1.bin", ...; an OBJ's
         // "<stem>.mtl" (see mesh/export.h)
  Maps,  // the --maps folder, replaced whole (mesh/write_maps.h)
};

/// One output a command is about to write.
struct OutputPath {
  std::string option;  // how the user named it, for the message: "-o", "--export", "export"
  std::filesystem::path path;
  OutputKind kind = OutputKind::File;
  MeshFormat format = MeshFormat::Glb;  // Mesh only: the format written (not always the extension)
  std::vector<std::filesystem::path> beside;  // further files written with it (a settings file)
};

/// Checks the outputs of one command reading the glTF scene `input` (empty:
/// no input to protect). Paths are compared after resolving (symlinks, "..",
/// hard links via std::filesystem::equivalent for files that exist). Throws
/// InputError, one line "<option> <path>: <reason>", when
/// - an output, or a file written beside it, is the input or a file the
///   input references (its buffers and images: gltf_input_files), including
///   a .gltf whose "<stem>N.bin" would be one of them ("that is the input
///   scene", "it writes x.bin beside it, a file of the input scene");
/// - an output exists and is not a regular file (a device, a FIFO, a socket,
///   a folder): "not a regular file (a character device)"; the Maps output
///   must be a folder written by --maps, an empty one or none
///   (replaceable_maps_folder), and must not hold the input or the current
///   folder;
/// - two outputs name the same file ("the same file as -o"), or an output
///   lies inside the Maps folder, which is replaced whole;
/// - a name is longer than its folder allows (NAME_MAX).
/// A missing folder is not checked here (the writers say so as IOError).
void check_output_paths(const std::filesystem::path& input, const std::vector<OutputPath>& outputs);

}  // namespace snow

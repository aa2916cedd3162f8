#pragma once
// Writing snow meshes for DCC tools and engines, the pipeline's last stage
// (docs/ARCHITECTURE.md): snow-only GLB/glTF, OBJ (+ .mtl) and binary PLY, and
// the input scene plus snow in one glTF. Every file is written under a
// temporary name and renamed (snow::write_file_atomically), so a failure leaves
// no half-written file.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/trimesh.h"
#include "mesh/polygonize.h"

namespace snow {

enum class MeshFormat {
  Glb,   // binary glTF, one file
  Gltf,  // glTF JSON + "<stem>.bin" beside it
  Obj,   // Wavefront OBJ + "<stem>.mtl" beside it
  Ply,   // binary little-endian PLY, all patches in one mesh
};

/// The format named by the extension of `path` (.glb, .gltf, .obj, .ply;
/// case-insensitive). Throws InputError naming the path for anything else.
MeshFormat format_from_path(const std::filesystem::path& path);

/// "glb", "gltf", "obj" or "ply".
const char* format_name(MeshFormat format);

/// The snow material every exporter uses: "snow", white PBR (linear base
/// colour 0.9, roughness 0.8, metallic 0).
MeshMaterial snow_material();

/// Writes the patches' meshes (snow only) to `path` in `format`, in the
/// scene's world frame (metres, +Y up):
/// - glTF/GLB: one node per patch (named after it) under one root node
///   "Snow", all with snow_material(); a .gltf gets "<stem>.bin" beside it;
/// - OBJ: one `o` per patch (whitespace in names becomes '_'), positions,
///   normals, UVs, `mtllib <stem>.mtl` written beside it with the snow
///   material (Kd, Ns, and the PBR extension Pr/Pm);
/// - PLY: binary little-endian, all patches in one mesh with normals
///   (nx, ny, nz) and UVs (s, t); a comment lists each patch's name and its
///   face range.
/// Patches without triangles are skipped. Throws IOError naming the file
/// when it cannot be written (no partial file is left).
void write_snow_meshes(const std::vector<SnowPatch>& patches, const std::filesystem::path& path,
                       MeshFormat format);

/// Writes the glTF scene `input_scene` (.gltf or .glb) plus the snow to `out`
/// (.glb or .gltf by its extension; anything else: InputError). The snow is
/// appended to the input (its JSON as written, streamed into a .glb where
/// read_combined_input can plan that; else as tinygltf loads it), so its
/// nodes, meshes, materials, textures, samplers, animations, skins, cameras
/// and extensions are kept as they were; the snow sits under one "Snow" node
/// added to the root of the default scene (world frame, identity transform)
/// with snow_material(). Images that the input keeps in files or data URIs
/// are embedded, byte for byte, into buffer 0 as buffer views, so the output
/// opens wherever it is written; buffers are written as save_gltf does. Throws
/// IOError when the input cannot be read or `out` cannot be written, and
/// InputError when the input is not valid glTF (first line of tinygltf's
/// error). Input warnings are logged naming the input.
void write_combined_gltf(const std::filesystem::path& input_scene,
                         const std::vector<SnowPatch>& patches, const std::filesystem::path& out);

/// The input scene of write_combined_gltf, read and parsed ahead of the
/// write (the batch job reads it while the snow is computed, as parsing a
/// large scene takes a noticeable share of the run). Its warnings are
/// logged by the write.
struct CombinedInput;
struct CombinedInputDeleter {
  void operator()(CombinedInput* input) const;
};
using CombinedInputPtr = std::unique_ptr<CombinedInput, CombinedInputDeleter>;

/// Reads `input_scene` for write_combined_gltf to `out`; throws what it
/// throws for the input (IOError, InputError). For a .glb `out`, an input
/// whose data lie in at most one buffer (a .bin file or the GLB's own) and
/// in image files is only planned here: its JSON is read, and the write
/// copies the buffer's and the images' bytes from their files into the GLB
/// (copy_file_range) without reading them into memory. Any other input is
/// read by tinygltf here.
CombinedInputPtr read_combined_input(const std::filesystem::path& input_scene,
                                     const std::filesystem::path& out);

/// write_combined_gltf from an input read ahead, which it consumes.
void write_combined_gltf(CombinedInputPtr input, const std::vector<SnowPatch>& patches,
                         const std::filesystem::path& out);

}  // namespace snow

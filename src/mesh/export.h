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
#include "scene/source_gltf.h"

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

/// Writes the glTF scene that `source` holds (the input as load_scene read
/// it, with LoadSettings::keep_source: its JSON is not read or parsed
/// again) plus the snow to `out` (.glb or .gltf by its extension; anything
/// else: InputError). The input's JSON is kept as written, so its nodes,
/// meshes, materials, textures, samplers, animations, skins, cameras,
/// extensions and extras stay as they were; the snow sits under one "Snow"
/// node added to the root of the default scene (world frame, identity
/// transform) with snow_material(). The output has one buffer: each input
/// buffer's first byteLength bytes, from an 8-byte boundary (files copied
/// by the kernel, read no further than byteLength; data URIs decoded), its
/// bufferViews (and EXT_/KHR_meshopt_compression's) pointed there; then the
/// images that the input keeps in files or data URIs, embedded byte for
/// byte as buffer views, so the output opens wherever it is written; then
/// the snow's data. A .gltf gets that buffer as "<stem>.bin" beside it.
/// Every file is written atomically. Every buffer and image uri follows the
/// input policy (scene/input_policy.h). Throws InputError, one line naming
/// the input and the buffer or image, for what the policy refuses or a
/// buffer the input cannot fill (mesh/glb_stream.h, plan_combined); IOError
/// when a file cannot be read, changed since it was planned, or `out`
/// cannot be written (no partial file is left). Images left at their uri
/// (unreadable, unknown format) are logged as warnings naming the input.
void write_combined_gltf(const SourceGltf& source, const std::vector<SnowPatch>& patches,
                         const std::filesystem::path& out);

/// The combined output planned ahead (mesh/glb_stream.h): its buffers and
/// images found and checked, their files' sizes and times taken. The batch
/// job plans right after the load, so a refused input fails before the
/// snow is computed, and a file changed during the run is noticed.
struct CombinedInput;
struct CombinedInputDeleter {
  void operator()(CombinedInput* input) const;
};
using CombinedInputPtr = std::unique_ptr<CombinedInput, CombinedInputDeleter>;

/// Plans write_combined_gltf for `source` (a copy of its JSON is kept:
/// `source` may be freed after); throws what it throws for the input.
CombinedInputPtr plan_combined_gltf(const SourceGltf& source);

/// write_combined_gltf from an input planned ahead, which it consumes.
void write_combined_gltf(CombinedInputPtr input, const std::vector<SnowPatch>& patches,
                         const std::filesystem::path& out);

}  // namespace snow

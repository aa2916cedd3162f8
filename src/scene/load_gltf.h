#pragma once
// glTF 2.0 loader: reads a .gltf (with external or data-URI buffers and
// images) or a .glb and flattens the default scene into the world-space
// triangle soup of scene/scene.h. Every number read from the file is
// validated before use; hostile or broken files give one InputError.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "scene/source_gltf.h"

namespace snow {

/// Resource limits of the loader. Exceeding one is an InputError naming the
/// limit (except max_image_pixels, which skips the image with a warning).
struct LoadLimits {
  // Triangles in the whole scene (count), before degenerate ones are dropped,
  // after strips/fans are expanded; a mesh instanced N times counts N times.
  uint64_t max_triangles = 50'000'000;
  // Size of any one file read: the .gltf/.glb, each .bin, each image (bytes).
  uint64_t max_file_bytes = uint64_t(4) << 30;
  // Size of the JSON part of a .gltf or .glb (bytes).
  uint64_t max_json_bytes = uint64_t(256) << 20;
  // Pixels (width * height) of one decoded image; larger ones are skipped
  // with a warning (pixels).
  uint64_t max_image_pixels = uint64_t(1) << 26;
  // The scene's data held in memory, summed: the file, the buffers (data:
  // URIs decoded, files as far as their byteLength), each image while it is
  // decoded and each decoded image (RGBA8: width * height * 4), checked
  // before each is allocated (bytes). The commands set it from
  // --memory-budget.
  uint64_t memory_budget = uint64_t(4) << 30;
  // Line segments in the whole scene (count, LoadSettings::lines), before
  // zero-length ones are dropped; a mesh instanced N times counts N times.
  uint64_t max_line_segments = 50'000'000;
  // Samples stored in Scene::motions, summed over nodes (count,
  // LoadSettings::motions). It also bounds the keyframes read from the
  // animations (summed over channels), and the work of sampling: each
  // sample of a node costs one step per animated node on its path from the
  // root, plus one, and those steps may be at most 64 times this limit.
  uint64_t max_motion_samples = 1'000'000;
};

struct LoadSettings {
  bool load_images = true;   // decode baseColor textures into Scene::images (bool)
  bool shading = true;       // read normals and UVs (only renderers use them); false: the
                             // NORMAL and TEXCOORD attributes are not read, and
                             // Scene::normals and Scene::uvs stay empty
  LoadLimits limits;         // resource limits (see LoadLimits)
  bool keep_source = false;  // keep the parsed file in Scene::source (scene/source_gltf.h)
  bool lines = false;        // load LINES, LINE_LOOP, LINE_STRIP into Scene::lines (else
                             // they are skipped with a warning)
  bool motions = false;      // sample the animations of the nodes into Scene::motions (else
                             // the animations are not read)
};

/// The file that a glTF uri names, as the loader reads it: `uri`
/// percent-decoded, '\\' read as '/', relative to `folder`. nullopt, with
/// the reason in *why (e.g. "is an absolute path (refused)"), for a
/// malformed or empty uri, one with a scheme (data:, http:, a drive), an
/// absolute path, or one that leaves the folder: by "..", or through a
/// symlink (the file, symlinks followed, must lie inside the folder,
/// symlinks followed: scene/input_policy.h).
std::optional<std::filesystem::path> resolve_relative_uri(const std::filesystem::path& folder,
                                                          const std::string& uri,
                                                          std::string* why = nullptr);

/// Loads the glTF 2.0 file at `path` (.gltf or .glb, detected by content)
/// and returns its default scene (`scene`, else scene 0, else every root
/// node when the file has no scenes) as world-space triangles in metres,
/// +Y up, front faces counter-clockwise (mirrored instances are re-wound).
///
/// - Node hierarchy with matrix or TRS transforms, instancing (one mesh in
///   many nodes) and EXT_mesh_gpu_instancing; the traversal is iterative.
/// - Primitive modes TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN; POINTS and
///   LINES* are skipped with a warning naming mesh and primitive.
/// - With settings.lines: LINES, LINE_STRIP and LINE_LOOP primitives go to
///   Scene::lines instead (world space, the same transforms and instancing
///   as triangles), one SceneLines per (node, primitive) with segments left;
///   zero-length segments are dropped; a strip or loop of fewer than 2
///   points has none, a loop of 2 points is one segment; an odd LINES index
///   count ignores the last (warned). At most LoadLimits::max_line_segments.
/// - With settings.motions: the animations (glTF 2.0 section 3.11: LINEAR,
///   with quaternions slerped on the shorter arc, STEP, CUBICSPLINE; values
///   clamped before the first and after the last keyframe) are sampled into
///   Scene::motions, one NodeMotion per node that has objects or lines in
///   the scene and whose world transform is animated (a translation,
///   rotation or scale channel on it or an ancestor); EXT_mesh_gpu_instancing
///   instances move with their node. Times: the keyframes of those channels
///   and the first and last of all node channels of the file, with evenly
///   spaced samples between at kMotionSampleHz (scene/gltf/animation.cpp)
///   at least. Where
///   two channels animate the same property of a node, the later in the file
///   wins. `weights` channels and other targets (KHR_animation_pointer) are
///   ignored. At most LoadLimits::max_motion_samples. Without
///   settings.motions the animations are not read.
/// - uint8/16/32 or no indices; float or (KHR_mesh_quantization) 8/16-bit
///   normalized or integer attributes; sparse accessors; byteStride.
/// - KHR_draco_mesh_compression when built with Draco (see
///   gltf_draco_supported()); EXT_meshopt_compression is refused.
/// - Normals (with settings.shading): the file's, transformed by the inverse
///   transpose; flat face normals where the file has none (or a normal is
///   zero/non-finite).
/// - UVs (with settings.shading): the texture coordinate set of the
///   material's baseColorTexture (TEXCOORD_0 by default) with
///   KHR_texture_transform applied, so they sample
///   Material::base_color_image directly; zeros for objects without that
///   set; empty when no object has one.
/// - Materials: one per glTF material (same index); baseColorFactor, and the
///   baseColorTexture decoded to RGBA8 when settings.load_images and the
///   material is used. A missing or undecodable image is a warning.
/// - Degenerate triangles (repeated index, or zero area: height below 1e-7
///   of the longest edge in world space) are dropped and counted.
///
/// Throws InputError (one line: file and element at fault) for broken or
/// hostile input: bad GLB header/chunks, broken JSON, missing or short
/// buffers, out-of-range views/accessors/indices, counts beyond the limits,
/// non-finite positions or transforms, node cycles or shared children,
/// any buffer or image URI that is absolute or leaves the scene's folder
/// ("../", or a symlink out of it; used by the scene or not), files that are
/// not regular files (FIFOs, devices: refused before they are opened), JSON
/// nested deeper than kMaxJsonDepth, data over LoadLimits::memory_budget
/// (the input policy: scene/input_policy.h), unsupported required
/// extensions, a scene without triangles; with settings.motions also broken
/// animations: accessors out of range or of the wrong type or count,
/// keyframe times not finite or not strictly increasing, values not finite,
/// channel nodes or samplers out of range, unknown interpolations, zero
/// rotation quaternions, an animated node with a 'matrix', motions that
/// are not finite. Buffer files are read only as far
/// as their byteLength. With settings.keep_source the parsed file is kept in
/// Scene::source (scene/source_gltf.h) for the combined writer. Throws IOError when the scene file
/// itself does not exist, is a folder or cannot be read.
Scene load_scene(const std::filesystem::path& path, const LoadSettings& settings = {});

/// The bytes load_scene reads from `path`, near enough, without reading
/// them: the file's size, and for a .gltf (by its extension) the sizes of
/// the .bin files in its folder, where its buffers usually are. 0 where the
/// file cannot be read.
uint64_t gltf_input_bytes(const std::filesystem::path& path);

/// The files that load_scene would read for `path`: `path` itself first,
/// then the files named by its buffers[].uri and images[].uri (data: URIs
/// left out), each resolved against the scene's folder as the loader does
/// (resolve_relative_uri); a URI the loader refuses (absolute, leaving the
/// folder) is listed as `folder / uri` all the same, as it names a file the
/// scene points at. For a .glb (by its magic) the JSON chunk is read. Never
/// throws: a file it cannot read or parse lists only itself. The paths are
/// not checked for existence. For the output policy (mesh/output_policy.h).
std::vector<std::filesystem::path> gltf_input_files(const std::filesystem::path& path);

/// True when this build decodes KHR_draco_mesh_compression.
bool gltf_draco_supported();

/// Machine-readable summary (for `snowmodel info --json`): triangle count,
/// stats, bounds in metres, objects (name, node path, node, mesh, primitive,
/// material, triangles), materials, images and warnings. Pretty-printed JSON.
std::string scene_summary_json(const Scene& scene);

/// Human-readable summary of the same (for `snowmodel info`); lists at most
/// the first 50 objects. Ends without a trailing newline.
std::string scene_summary_text(const Scene& scene);

}  // namespace snow

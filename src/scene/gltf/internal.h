#pragma once
// Private to the glTF loader: what its parts share. Not for other code, which
// includes scene/load_gltf.h.
//
// One GltfLoader reads one file. Its members are defined by part:
//   scene/load_gltf.cpp        load(): the order of the steps; the public entry points
//   scene/gltf/document.cpp    errors, JSON access, files and data URIs, the GLB
//                              container, extensions, buffers and bufferViews
//   scene/gltf/accessors.cpp   accessors (typed, normalized, sparse) to floats and indices
//   scene/gltf/nodes.cpp       the node hierarchy, transforms, EXT_mesh_gpu_instancing
//   scene/gltf/materials.cpp   materials, KHR_texture_transform, baseColor images
//   scene/gltf/primitives.cpp  primitives in mesh space, topology, world-space triangles
//   scene/gltf/draco.cpp       KHR_draco_mesh_compression (with SNOW_HAVE_DRACO)
//   scene/gltf/animation.cpp   animations sampled into node motions (LoadSettings::motions)
//
// Every value read from the file is validated before use; a failure is one
// InputError "<file>: <element at fault>: <what>" (fail()).
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "core/default_init.h"
#include "scene/load_gltf.h"
#include "scene/scene.h"

namespace snow::gltf {

using json = nlohmann::json;

/// accessor.componentType values (glTF 2.0, 3.6.2.2).
constexpr int kByte = 5120;
constexpr int kUnsignedByte = 5121;
constexpr int kShort = 5122;
constexpr int kUnsignedShort = 5123;
constexpr int kInt = 5124;
constexpr int kUnsignedInt = 5125;
constexpr int kFloat = 5126;

/// Bytes read from a file or a data: URI. Sized without writing zeros
/// first: the read or the decoding writes every byte.
using Bytes = std::vector<uint8_t, DefaultInitAllocator<uint8_t>>;

/// Makes text from the file safe for a one-line message: control characters
/// become spaces, invalid UTF-8 bytes '?', and text longer than `max_chars`
/// bytes is cut with "...".
std::string one_line(std::string_view text, size_t max_chars = 120);

/// True when `s` starts with `prefix` ignoring ASCII case; `prefix` is lower case.
bool starts_with_ci(std::string_view s, std::string_view prefix);

/// A buffer, read on first use: the GLB BIN chunk, a data: URI or a file.
struct BufferSlot {
  bool loaded = false;
  Bytes owned;
  const uint8_t* data = nullptr;
  uint64_t size = 0;  // declared byteLength (the data holds at least this)
};

/// A bufferView, checked to lie inside its buffer.
struct ViewRange {
  const uint8_t* data = nullptr;
  uint64_t length = 0;
  uint64_t stride = 0;  // 0 when the view has no byteStride
};

/// An accessor, checked to lie inside its bufferViews (sparse ones too).
struct AccessorInfo {
  int index = -1;
  uint64_t count = 0;
  int components = 0;
  int component_type = 0;
  bool normalized = false;
  const uint8_t* data = nullptr;  // first element; null: all zeros (+ sparse)
  uint64_t stride = 0;
  uint64_t sparse_count = 0;
  const uint8_t* sparse_indices = nullptr;
  int sparse_index_type = 0;
  const uint8_t* sparse_values = nullptr;
};

/// Texture coordinate set and KHR_texture_transform of a baseColorTexture.
struct UvMapping {
  int set = 0;
  bool transform = false;
  glm::dmat3 matrix{1.0};
};

/// One primitive decoded in mesh space; shared by all instances of its mesh.
struct PrimitiveGeometry {
  bool skip = false;
  bool lines = false;  // a line primitive (LoadSettings::lines): segments, no triangles
  int material = -1;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;   // empty or one per position
  std::vector<glm::vec2> uvs;       // empty or one per position
  std::vector<uint32_t> triangles;  // three vertex indices per triangle
  std::vector<uint32_t> segments;   // two vertex indices per segment (lines)
};

/// A node's translation, rotation or scale channel (glTF 2.0 section 3.11),
/// its sampler read and validated.
struct MotionChannel {
  enum Path { kTranslation = 0, kRotation = 1, kScale = 2 };
  enum Interpolation { kLinear, kStep, kCubicSpline };
  int node = -1;
  Path path = kTranslation;
  Interpolation interpolation = kLinear;
  std::vector<float> times;   // seconds, finite, strictly ascending, >= 1 entry
  std::vector<float> values;  // per time 3 (translation, scale) or 4 (rotation x, y, z, w)
                              // finite values; CUBICSPLINE: in-tangent, value, out-tangent
};

/// Translation (x, y, z), rotation (x, y, z, w) and scale (x, y, z) of a
/// node, indexed by MotionChannel::Path.
using TrsValues = std::array<glm::dvec4, 3>;
/// T * R * S of a node's translation, rotation (unit) and scale (nodes.cpp).
glm::dmat4 trs_matrix(const TrsValues& trs);
/// A rotation quaternion no longer than this is zero.
constexpr double kZeroQuaternion = 1e-12;

/// What sampling the motions shares (animation.cpp).
struct MotionSet {
  std::vector<MotionChannel> channels;
  std::vector<std::array<int, 3>> per_node;  // per node, its channel per Path, or -1
  std::vector<TrsValues> rest;               // per animated node in the scene, its rest TRS
  std::vector<int> up;                       // per node, its nearest animated ancestor, or -1
  std::vector<glm::dmat4> above;  // per node, the rest local transforms between up (or the
                                  // root) and it, both left out
  double start = 0.0;             // first keyframe time of all channels (s)
  double end = 0.0;               // last keyframe time of all channels (s)
  uint64_t samples = 0;           // stored so far (count)
  uint64_t work = 0;              // sampling steps so far (LoadLimits::max_motion_samples)
};

/// A (node, mesh) pair found by the traversal, with its world matrix.
struct Instance {
  int node = -1;
  int mesh = -1;
  uint32_t path = 0;  // index into node_paths_
  glm::dmat4 world{1.0};
};

class GltfLoader {
 public:
  GltfLoader(const std::filesystem::path& path, const LoadSettings& settings);

  /// Reads the file and returns its default scene (see load_scene), with
  /// Scene::source when LoadSettings::keep_source. Call once.
  Scene load();

 private:
  // --- errors and warnings (document.cpp) -------------------------------------

  /// Throws InputError "<file>: <message>".
  [[noreturn]] void fail(const std::string& message) const;
  [[noreturn]] void fail_triangle_limit() const;
  /// Logs the message and keeps it in Scene::warnings.
  void warn(const std::string& message);

  // --- JSON access with validation (document.cpp) ----------------------------
  // `what` names the element for the message of fail().

  /// object[key], or null when `object` is not an object or has no `key`.
  const json* member(const json& object, const char* key) const;
  /// Top-level array `key` (empty when absent).
  const json& top_array(const char* key) const;
  /// array[index], which must be an object; index < array.size().
  const json& element(const json& array, uint64_t index, const std::string& what) const;
  /// A non-negative integer (an integral float up to 2^53 too).
  uint64_t as_uint(const json& value, const std::string& what) const;
  uint64_t opt_uint(const json& object, const char* key, uint64_t fallback,
                    const std::string& what) const;
  /// Optional index into an array of `size` things; -1 when absent.
  int64_t opt_index(const json& object, const char* key, size_t size, const std::string& what,
                    const char* things) const;
  /// A finite number.
  double as_number(const json& value, const std::string& what) const;
  /// Fixed-size array of finite numbers.
  template <size_t N>
  std::array<double, N> numbers(const json& value, const std::string& what) const;
  /// object[key] when it is a string, else "".
  std::string opt_string(const json& object, const char* key) const;
  /// "mesh 3 ('Name')" / "node 7 ('Name')" for messages.
  std::string mesh_label(int mesh) const;
  std::string node_label(int node) const;
  const json& nodes() const { return top_array("nodes"); }
  const json& meshes() const { return top_array("meshes"); }

  // --- files, URIs, document, buffers (document.cpp) --------------------------

  /// The first `at_most` bytes of `file` (all when it is shorter), at most
  /// LoadLimits::max_file_bytes, charged to the budget (charge) before they
  /// are allocated. A missing file sets *missing and returns nothing when
  /// `missing_ok`, else fails; anything but a regular file fails
  /// (scene/input_policy.h).
  Bytes read_file(const std::filesystem::path& file, const std::string& what, bool missing_ok,
                  bool* missing, uint64_t at_most = UINT64_MAX);
  /// Counts `bytes` more of the scene's data held in memory (the file,
  /// buffers, encoded and decoded images) against
  /// LoadLimits::memory_budget; fails, naming `what` and the budget, when
  /// they would exceed it.
  void charge(uint64_t bytes, const std::string& what);
  /// Resolves a relative URI inside the scene's folder; refuses anything else.
  std::filesystem::path resolve_uri(const std::string& uri, const std::string& what) const;
  /// Bytes of a data: URI; its media type in *mime.
  Bytes decode_data_uri(const std::string& uri, const std::string& what, std::string* mime) const;
  /// Reads the file (.gltf or .glb by content) and parses its JSON into doc_.
  void read_document();
  /// GLB container (glTF 2.0 section 4.4): the JSON chunk's bytes, and the
  /// BIN chunk into glb_bin_.
  void parse_glb_container(const uint8_t*& json_begin, uint64_t& json_size);
  /// Fails on any buffer or image uri that names a file outside the scene's
  /// folder (resolve_uri), used or not: every command refuses such a scene
  /// before reading anything more (scene/input_policy.h).
  void check_uris() const;
  /// Fails on required extensions this build cannot honour; warns on unknown ones.
  void check_extensions();
  const BufferSlot& buffer(uint64_t index);
  /// bufferView `index`, for the element named `user`.
  ViewRange view(uint64_t index, const std::string& user);

  // --- accessors (accessors.cpp) ----------------------------------------------

  /// Accessor `index`, validated against its bufferViews; `role` names its use.
  AccessorInfo accessor_info(uint64_t index, const std::string& role);
  /// The sparse part of an accessor (glTF 2.0 section 3.6.2.3) into `info`.
  void read_sparse(const json& sparse, const std::string& what, uint64_t element_size,
                   AccessorInfo& info);
  /// Elements any one accessor may hold: from LoadLimits::max_triangles.
  uint64_t max_elements() const;
  /// Decodes an attribute accessor to floats (normalization and sparse applied).
  std::vector<float> decode_floats(const AccessorInfo& info, const std::string& role);
  // The element index of sparse entry k of `info`; fails naming `what`
  // when it is out of range.
  uint32_t sparse_target(const AccessorInfo& info, uint64_t k, const std::string& what) const;
  /// Reads a vertex attribute (POSITION, NORMAL, TEXCOORD_n) of `components`
  /// values each, all finite.
  std::vector<float> read_attribute(uint64_t accessor, int components, const std::string& role,
                                    AccessorInfo* info_out);
  /// Reads an unsigned-integer SCALAR accessor (not range-checked).
  std::vector<uint32_t> read_indices(uint64_t accessor, const std::string& role);

  // --- materials and images (materials.cpp) -----------------------------------

  /// Scene::materials, uv_mappings_ and material_images_ from the materials.
  void read_materials();
  /// Image index of a texture, or -1 (with a warning) if it only has sources
  /// in formats stb cannot decode.
  int texture_source(uint64_t texture);
  /// Decodes the baseColor images of the materials that objects use.
  void load_images();
  /// Decodes glTF image `index` into Scene::images; its index there, or -1
  /// (with a warning) when it is missing, undecodable or too large.
  int decode_image(int index);

  // --- node hierarchy (nodes.cpp) ----------------------------------------------

  /// A node's local transform: its 'matrix', else trs_matrix(node_trs).
  glm::dmat4 local_matrix(uint64_t node, const json& object) const;
  /// A node's translation, rotation (normalized; a zero one fails) and
  /// scale, the defaults where absent.
  TrsValues node_trs(uint64_t node, const json& object) const;
  std::string node_name(int node) const;
  /// "/root/child/..." for SceneObject::node_path; deep paths are elided.
  std::string path_string(const std::vector<int>& path) const;
  /// Roots of the scene to load, validated.
  std::vector<int> scene_roots(const std::vector<uint32_t>& parents);
  /// Iterative depth-first traversal: world matrices of every mesh node.
  std::vector<Instance> traverse();
  /// The instances of `mesh` at `node`: one, or one per EXT_mesh_gpu_instancing element.
  void add_instances(int node, int mesh, const glm::dmat4& world, const json& object,
                     const std::vector<int>& path, std::vector<Instance>& instances);

  // --- primitives and world-space triangles (primitives.cpp) ------------------

  const json& primitives_of(int mesh) const;
  /// Triangles the mesh's primitives will produce, from validated declared
  /// counts (no decoding). Used to check the limit and reserve memory early.
  uint64_t estimate_triangles(int mesh);
  PrimitiveGeometry decode_primitive(int mesh, uint64_t p, const json& prim);
  /// The attributes and indices of a primitive read from accessors (`draco`:
  /// it also has a KHR_draco_mesh_compression this build cannot decode);
  /// false, with `geometry` untouched, when it has no POSITION.
  bool read_primitive(const json& prim, const json& attributes, int mode, bool draco,
                      const std::string& what, const std::string& uv_name,
                      PrimitiveGeometry& geometry);
  /// The vertex indices of a primitive (its `indices`, each checked to be
  /// below `vertex_count`, else 0 .. vertex_count - 1).
  std::vector<uint32_t> read_vertex_indices(const json& prim, size_t vertex_count,
                                            const std::string& what);
  /// A LINES, LINE_LOOP or LINE_STRIP primitive's positions and segments
  /// (settings_.lines); false, with `geometry` untouched, when it has no POSITION.
  bool read_lines(const json& prim, const json& attributes, int mode, const std::string& what,
                  PrimitiveGeometry& geometry);
  /// LINES, LINE_LOOP, LINE_STRIP index lists to a segment list.
  void expand_lines(int mode, const std::vector<uint32_t>& indices, const std::string& what,
                    std::vector<uint32_t>& segments);
  /// TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN index lists to a triangle list.
  void expand_topology(int mode, std::vector<uint32_t>& indices, const std::string& what,
                       std::vector<uint32_t>& triangles);
  /// The decoded primitive `p` of `mesh`, cached while instances of the mesh remain.
  const PrimitiveGeometry& geometry(int mesh, size_t p);
  /// Appends every instance's primitives to scene_.
  void build_geometry(const std::vector<Instance>& instances);
  /// Positions (wp) and unit normals (wn) of `g` in world space; true when the
  /// instance is mirrored (its winding is flipped).
  bool transform_vertices(const Instance& instance, const PrimitiveGeometry& g,
                          std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn);
  /// Appends one primitive of one instance to scene_ as a SceneObject.
  void append(const Instance& instance, int primitive, const PrimitiveGeometry& g,
              std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn);
  /// Appends one line primitive of one instance to Scene::lines.
  void append_lines(const Instance& instance, int primitive, const PrimitiveGeometry& g,
                    std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn);
  /// SceneObject::name of primitive `primitive` of an instance.
  std::string object_name(const Instance& instance, int primitive) const;

  // --- animations (animation.cpp) ------------------------------------------------

  /// Scene::motions from the file's animations (settings_.motions), for the
  /// nodes with objects or lines in scene_.
  void read_motions();
  /// Channel `c` of animation `a` into `out`; false when it is not a node
  /// translation, rotation or scale channel (ignored). Counts its keyframes
  /// in `keyframes` against LoadLimits::max_motion_samples.
  bool read_channel(uint64_t a, const json& animation, uint64_t c, uint64_t& keyframes,
                    MotionChannel& out);
  /// A sampler's interpolation, keyframe times (`input`) and values
  /// (`output`) into `out`, whose path is set.
  void read_sampler(const json& sampler, const std::string& what, uint64_t& keyframes,
                    MotionChannel& out);
  /// The keyframe values of `out` (times read) from accessor `accessor`.
  void read_keyframe_values(uint64_t accessor, const std::string& what, MotionChannel& out);
  /// The rest translation, rotation (unit) and scale of an animated node.
  TrsValues rest_trs(int node) const;
  /// Node `node`'s local transform at time `t` (seconds); it is animated.
  glm::dmat4 local_at(int node, double t, const MotionSet& set) const;
  /// The motion of `node`, which has objects or lines and an animated path
  /// from the root; counts its samples and work in `set`.
  NodeMotion sample_motion(int node, MotionSet& set);
  /// The sample times of `node`, animated by the channels `used`: their
  /// keyframes, set.start and set.end, and evenly spaced times between.
  std::vector<float> motion_times(int node, const std::vector<int>& used, MotionSet& set);

  // --- Draco (draco.cpp) --------------------------------------------------------

  /// Decodes a KHR_draco_mesh_compression primitive into `geometry`; fails
  /// when this build has no Draco decoder.
  void decode_draco(const json& extension, const std::string& what, const std::string& uv_name,
                    PrimitiveGeometry& geometry);

  // --- state -------------------------------------------------------------------

  std::filesystem::path path_;
  std::filesystem::path folder_;
  LoadSettings settings_;
  std::string label_;
  uint64_t loaded_bytes_ = 0;  // what charge() has counted (bytes)
  Bytes file_;
  std::filesystem::file_time_type file_modified_{};  // the scene file's, before it was read
  bool is_glb_ = false;
  bool has_glb_bin_ = false;
  const uint8_t* glb_bin_ = nullptr;
  uint64_t glb_bin_size_ = 0;
  json doc_;
  std::vector<BufferSlot> slots_;
  std::vector<UvMapping> uv_mappings_;
  std::vector<int> material_images_;
  std::vector<std::string> node_paths_;
  std::unordered_map<int, std::vector<std::unique_ptr<PrimitiveGeometry>>> geometry_cache_;
  uint64_t line_segments_read_ = 0;  // segments of Scene::lines before zero-length ones are dropped
  // With settings_.motions, per node of the scene as traversed: its parent
  // there (-1 for a root, -2 for a node not in the scene), its local and
  // its world matrix.
  std::vector<int> scene_parents_;
  std::vector<glm::dmat4> node_locals_;
  std::vector<glm::dmat4> node_worlds_;
  Scene scene_;
};

template <size_t N>
std::array<double, N> GltfLoader::numbers(const json& value, const std::string& what) const {
  if (!value.is_array() || value.size() != N)
    fail(what + " must be an array of " + std::to_string(N) + " numbers");
  std::array<double, N> out{};
  for (size_t i = 0; i < N; ++i) {
    if (!value[i].is_number())
      fail(what + " must be an array of " + std::to_string(N) + " numbers");
    out[i] = value[i].get<double>();
    if (!std::isfinite(out[i])) fail(what + " has a non-finite value (NaN or infinite)");
  }
  return out;
}

}  // namespace snow::gltf

#pragma once
// The scene as every stage sees it: world-space triangles grouped by object.
// Units are metres, +Y is up (glTF's frame). Front faces wind counter-
// clockwise seen from outside, also for mirrored instances (the loader flips
// the winding of nodes whose world matrix has a negative determinant).
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace snow {

struct SourceGltf;  // scene/source_gltf.h

/// Axis-aligned box. An empty box has min > max.
struct Bounds {
  glm::vec3 min{std::numeric_limits<float>::max()};
  glm::vec3 max{-std::numeric_limits<float>::max()};

  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  void extend(const glm::vec3& p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  glm::vec3 size() const { return empty() ? glm::vec3(0) : max - min; }
  glm::vec3 center() const { return (min + max) * 0.5f; }
};

/// Decoded RGBA8 image (a baseColor texture).
struct Image {
  std::string name;
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgba;  // width * height * 4, rows top to bottom
};

struct Material {
  std::string name;
  glm::vec4 base_color{1.0f};  // linear baseColorFactor
  int base_color_image = -1;   // index into Scene::images, or -1
};

/// One glTF primitive instanced by one node: a contiguous triangle range.
struct SceneObject {
  std::string name;       // node name, else mesh name, else "mesh<M>.prim<P>"
  std::string node_path;  // "/Root/House/Roof" (node names, or node<N>)
  int node = -1;          // glTF node index
  int mesh = -1;          // glTF mesh index
  int primitive = -1;     // primitive index within the mesh
  int material = -1;      // index into Scene::materials, or -1
  uint32_t first_triangle = 0;
  uint32_t triangle_count = 0;
};

/// A glTF LINES, LINE_STRIP or LINE_LOOP primitive instanced by one node
/// (loaded with LoadSettings::lines): world-space segments, 2 points each.
struct SceneLines {
  std::string name;                 // as SceneObject::name
  std::string node_path;            // as SceneObject::node_path
  int node = -1;                    // glTF node index
  std::vector<glm::vec3> segments;  // 2 points per segment, world (m, +Y up after to_metres_y_up)
};

/// A node's animation (loaded with LoadSettings::motions): its world
/// transform relative to the rest pose the scene's geometry was loaded in,
/// sampled over the time range of all the file's animations played together.
struct NodeMotion {
  int node = -1;                 // glTF node index (SceneObject::node, SceneLines::node)
  std::vector<float> times;      // seconds, strictly ascending, >= 1 entry
  std::vector<glm::mat4> moves;  // per time: world(t) * inverse(world at rest); maps a rest-pose
                                 // world point to where it is at times[k]
};

struct SceneStats {
  uint64_t triangles_read = 0;      // before degenerate ones are dropped
  uint64_t degenerate_dropped = 0;  // zero-area or repeated-index triangles
  uint64_t primitives_skipped = 0;  // POINTS, LINES, ... (each warned)
  uint64_t nodes = 0;               // nodes visited in the scene graph
  uint64_t instances = 0;           // (node, mesh) pairs
};

/// World-space triangle soup, grouped by object. Triangle t has corners
/// positions[3t..3t+2]; normals and uvs follow the same layout (uvs may be
/// empty when no primitive had TEXCOORD_0; normals are filled, with flat
/// normals where the file had none). A scene loaded without shading
/// (LoadSettings::shading) has neither: both are empty. Objects' triangle
/// ranges are contiguous, in order, and cover every triangle. Lines and
/// motions are loaded only on request (LoadSettings::lines, ::motions); they
/// are not triangles and do not count in `bounds`.
struct Scene {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::vec2> uvs;
  std::vector<SceneObject> objects;
  std::vector<SceneLines> lines;    // in the order of the objects; empty unless loaded
  std::vector<NodeMotion> motions;  // by ascending node; empty unless loaded
  std::vector<Material> materials;
  std::vector<Image> images;
  Bounds bounds;
  SceneStats stats;
  std::vector<std::string> warnings;  // also logged as they happen
  std::string generator;              // the file's asset.generator (one line), "" if none
  // The file as read, with LoadSettings::keep_source (scene/load_gltf.h);
  // else null. Shared: copies of the scene refer to the same one.
  std::shared_ptr<const SourceGltf> source;

  size_t triangle_count() const { return positions.size() / 3; }
  /// Object index of triangle t (binary search over the ranges).
  int object_of_triangle(size_t t) const;
};

/// `scene` without its geometry: its materials, images, stats, warnings,
/// source and generator, and its lines and motions unchanged (they are not
/// triangles); no objects or triangles (empty bounds); for the steps that
/// rebuild a scene's objects.
Scene without_geometry(const Scene& scene);

/// Bounds of `object`'s triangles (empty for an object without any).
/// Throws InputError for an index out of range.
Bounds object_bounds(const Scene& scene, int object);

/// Triangle t's unit geometric normal as wound, as the peels write it into
/// the maps (worked out in double; 0 for a degenerate triangle).
glm::vec3 triangle_normal(const Scene& scene, size_t t);

/// Per triangle, as the peels write them into the maps: triangle_normal and
/// the object index (-1 where no object's range holds it). On all cores.
struct TriangleAttributes {
  std::vector<glm::vec3> normal;
  std::vector<int32_t> object;
};
TriangleAttributes triangle_attributes(const Scene& scene);

}  // namespace snow

#pragma once
// Scenes built in code: primitives (boxes, planes, roofs, cylinders, bowls,
// stairs, beams, wall rings) collected as named objects, turned into a
// snow::Scene for the pipeline and tests, or into TriMeshes for the glTF
// writer (tools/gen_assets.cpp makes assets/scenes/courtyard.glb from them).
//
// Conventions: world space, metres, +Y up, counter-clockwise front faces seen
// from outside. Every primitive documented as "closed" is a closed, oriented
// 2-manifold (each edge shared by exactly two triangles, in opposite
// directions) with outward normals, so its signed volume is positive.
// Vertices of one object are welded (shared indices), so closedness can be
// checked on the indices of objects(); Scene keeps the exact positions, so it
// can also be checked there with check_object_topology().
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/trimesh.h"
#include "scene/scene.h"

namespace snow {

/// One object collected by SceneBuilder: welded vertices, 3 indices per
/// triangle.
struct BuilderObject {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  int material = -1;    // index into SceneBuilder's materials, or -1 (default grey)
  bool closed = false;  // the primitive promises a closed 2-manifold (add_mesh: as checked)
};

class SceneBuilder {
 public:
  /// Adds a material (linear RGBA base colour, roughness and metallic in
  /// [0,1]) and returns its index.
  int add_material(const std::string& name, const glm::vec4& base_color, float roughness = 0.8f,
                   float metallic = 0.0f);

  // Every add_* below adds one named object and returns its object index
  // (0, 1, 2, ... in call order). `material` is an index returned by
  // add_material, or -1 for the default grey material. Bad arguments
  // (min >= max, radius <= 0, segments < 3, indices out of range, ...) throw
  // InputError naming the object.

  /// Arbitrary triangles (3 indices per triangle). Degenerate triangles are
  /// kept as given. closed is set from check_topology().
  int add_mesh(const std::string& name, const std::vector<glm::vec3>& positions,
               const std::vector<uint32_t>& indices, int material = -1);
  /// Closed axis-aligned box [min,max]: 12 triangles.
  int add_box(const std::string& name, const glm::vec3& min, const glm::vec3& max,
              int material = -1);
  /// One-sided quad at height y over [min_xz, max_xz], front face +Y: 2 triangles.
  int add_plane(const std::string& name, float y, const glm::vec2& min_xz, const glm::vec2& max_xz,
                int material = -1);
  /// Closed gable roof slab over the footprint [min.x,max.x] x [min.z,max.z];
  /// max.y is ignored. Ridge along x at z_mid = (min.z+max.z)/2. The underside
  /// is two planes sloping at pitch_deg (0 < pitch < 80) that pass through
  /// y = min.y at z = min.z and z = max.z (the roof sits on walls whose top is
  /// at min.y) and meet at the underside ridge y = min.y + (max.z-min.z)/2 *
  /// tan(pitch). The slab extends `overhang` metres (>= 0) beyond the
  /// footprint in x and z: the eaves' underside edges hang at y = min.y -
  /// overhang*tan(pitch). `thickness` (> 0) is measured perpendicular to the
  /// slope (vertical offset thickness/cos(pitch)); eave and gable cuts are
  /// vertical. The top ridge is at y = gable_roof_ridge_y(...).
  int add_gable_roof(const std::string& name, const glm::vec3& min, const glm::vec3& max,
                     float pitch_deg, float overhang, float thickness, int material = -1);
  /// Closed upright cylinder (prism with `segments` >= 3 sides) standing on
  /// base_center, top at base_center.y + height. Vertex k of a ring sits at
  /// angle 2*pi*k/segments from +x towards +z.
  int add_cylinder(const std::string& name, const glm::vec3& base_center, float radius,
                   float height, int segments, int material = -1);
  /// Closed thick-walled basin (a cup) open at the top: outer cylinder of
  /// `radius` from y = center.y to y = center.y + depth; cavity of radius
  /// radius - wall from y = center.y + wall (the basin floor, wall thick) up
  /// to the rim at y = center.y + depth, the rim being the flat annulus
  /// between the two radii. Needs 0 < wall < radius and wall < depth.
  int add_bowl(const std::string& name, const glm::vec3& center, float radius, float depth,
               float wall, int segments, int material = -1);
  /// Closed solid flight of `steps` (>= 1) steps rising along +z. `origin` is
  /// the bottom corner with the smallest x and z. Occupies x in [origin.x,
  /// origin.x + step_width], z in [origin.z, origin.z + steps*tread], y from
  /// origin.y. Step k (0-based) has its tread at y = origin.y + (k+1)*riser
  /// over z in [origin.z + k*tread, origin.z + (k+1)*tread]; the solid is
  /// filled below every tread down to origin.y; its back face is at
  /// z = origin.z + steps*tread.
  int add_stairs(const std::string& name, const glm::vec3& origin, int steps, float step_width,
                 float tread, float riser, int material = -1);
  /// Closed straight beam (rail, slanted or level) whose centre line runs from
  /// `from` to `to`. Its end faces are vertical, its cross-section is `width`
  /// wide (horizontally, perpendicular to the line's xz direction) and
  /// `height` tall (vertically). Needs from.xz != to.xz.
  int add_beam(const std::string& name, const glm::vec3& from, const glm::vec3& to, float width,
               float height, int material = -1);
  /// Closed rectangular ring of walls (genus 1): outer footprint [min,max]
  /// (y from min.y to max.y), walls `thickness` thick inwards, open at the top
  /// and bottom of the enclosed space (the top of the walls is an annulus).
  /// Needs 2*thickness < extent in x and z.
  int add_wall_ring(const std::string& name, const glm::vec3& min, const glm::vec3& max,
                    float thickness, int material = -1);

  /// Top ridge height of add_gable_roof with the same arguments.
  static float gable_roof_ridge_y(const glm::vec3& min, const glm::vec3& max, float pitch_deg,
                                  float thickness);

  /// The scene: objects in order, one SceneObject each (node = mesh = object
  /// index, primitive 0, node_path "/<name>", triangles contiguous), flat
  /// normals, no uvs, materials (the default grey one appended as the last
  /// material, named "Default", only when some object uses -1), bounds,
  /// stats (triangles_read, nodes, instances).
  Scene build() const;
  /// One TriMesh per object, named after it, vertices split where the flat
  /// normal changes (normals filled, uvs empty). TriMesh::material indexes
  /// materials().
  std::vector<TriMesh> meshes() const;
  /// The added materials, plus "Default" grey (0.6, 0.6, 0.6, 1) last when
  /// some object uses -1.
  std::vector<MeshMaterial> materials() const;

  const std::vector<BuilderObject>& objects() const { return objects_; }
  /// Index of the object with that name, or -1.
  int find_object(const std::string& name) const;

 private:
  int add_object(BuilderObject object);
  bool needs_default_material() const;

  std::vector<MeshMaterial> materials_;
  std::vector<BuilderObject> objects_;
};

// --- Topology checks (for tests and asset validation) -----------------------

struct TopologyReport {
  size_t triangles = 0;
  size_t vertices = 0;              // after welding exactly equal positions
  size_t edges = 0;                 // undirected
  size_t boundary_edges = 0;        // used by one triangle
  size_t nonmanifold_edges = 0;     // used by three or more triangles
  size_t misoriented_edges = 0;     // used twice in the same direction
  size_t degenerate_triangles = 0;  // two equal corners after welding
  /// Closed, oriented 2-manifold.
  bool closed() const {
    return triangles > 0 && boundary_edges == 0 && nonmanifold_edges == 0 &&
           misoriented_edges == 0 && degenerate_triangles == 0;
  }
};

/// Edge topology of an indexed triangle list, after welding vertices whose
/// positions are exactly equal.
TopologyReport check_topology(const std::vector<glm::vec3>& positions,
                              const std::vector<uint32_t>& indices);
/// Same for the triangles of one object of a Scene (triangle soup).
TopologyReport check_object_topology(const Scene& scene, int object);
/// Signed volume (m^3) enclosed by an indexed triangle list; positive for a
/// closed mesh with outward (counter-clockwise) faces.
double signed_volume(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices);
/// Same for the triangles of one object of a Scene.
double object_signed_volume(const Scene& scene, int object);
/// Index of the object with that name in a Scene, or -1.
int find_object(const Scene& scene, const std::string& name);

// --- Canned scenes ----------------------------------------------------------
// Each comes with its dimensions; objects are listed in index order. Floors
// are one-sided planes at y = 0 (object 0, "Floor"), square, centred at the
// origin. Materials: "Floor" grey, then one per remaining kind of object.

/// Object 0 "Floor": plane y = 0, x and z in [-size/2, size/2]. 2 triangles.
Scene make_open_plane(float size = 10.0f);

struct TableDims {
  float table_height = 0.75f;   // metres, y of the top surface
  float table_size = 1.0f;      // metres, side of the square top, centred at the origin
  float floor_size = 4.0f;      // metres, side of the square floor
  float top_thickness = 0.05f;  // metres, the top slab spans y in [height - thickness, height]
  float leg_width = 0.06f;      // metres, square legs flush with the top's corners
};
/// Objects: 0 "Floor", 1 "TableTop" (closed box x,z in [-size/2, size/2],
/// y in [h - top_thickness, h]), 2..5 "TableLeg0".."TableLeg3" (closed boxes,
/// leg_width square, y in [0, h - top_thickness], outer faces flush with the
/// top's edges; corners (-,-), (+,-), (-,+), (+,+) in x,z).
Scene make_table_scene(const TableDims& dims);
Scene make_table_scene(float table_height = 0.75f, float table_size = 1.0f,
                       float floor_size = 4.0f);

struct ClosedBoxDims {
  float size = 1.0f;        // metres, outer side of the cube, standing on y = 0, centred in x,z
  float wall = 0.1f;        // metres, thickness of all six sides
  float floor_size = 4.0f;  // metres
};
/// Objects: 0 "Floor", 1 "Box": one closed object made of the outer cube
/// [-size/2, size/2] x [0, size] x [-size/2, size/2] and an inward-facing
/// cavity cube shrunk by `wall` on every side (two closed shells; signed
/// volume size^3 - (size - 2 wall)^3).
Scene make_closed_box_scene(const ClosedBoxDims& dims);
/// Same with wall = min(0.1, 0.1 * size) and floor_size = max(4, 4 * size).
Scene make_closed_box_scene(float size = 1.0f);

struct WallDims {
  float wall_height = 2.0f;     // metres
  float wall_length = 6.0f;     // metres, along x, centred at the origin
  float wall_thickness = 0.2f;  // metres, along z, centred at z = 0
  float floor_size = 10.0f;     // metres
};
/// Objects: 0 "Floor", 1 "Wall" (closed box x in [-length/2, length/2],
/// y in [0, height], z in [-thickness/2, thickness/2]).
Scene make_wall_scene(const WallDims& dims);
Scene make_wall_scene(float wall_height = 2.0f, float wall_length = 6.0f, float floor_size = 10.0f);

struct HouseDims {
  float roof_pitch_deg = 45.0f;  // degrees, roof slope
  float width = 6.0f;            // metres, outer wall footprint along x (the ridge direction)
  float depth = 4.0f;            // metres, outer wall footprint along z
  float wall_height = 3.0f;      // metres, top of the walls = underside of the roof at the walls
  float wall_thickness = 0.2f;   // metres
  float eaves_overhang = 0.5f;   // metres, roof beyond the walls in x and z
  float roof_thickness = 0.15f;  // metres, perpendicular to the slope
  float slab_thickness = 0.1f;   // metres, interior floor slab on y = 0
  float floor_size = 16.0f;      // metres
};
/// Objects: 0 "Floor"; 1 "HouseWalls" (add_wall_ring over x in [-w/2, w/2],
/// z in [-d/2, d/2], y in [0, wall_height]); 2 "HouseSlab" (closed box
/// filling the inside of the walls, y in [0, slab_thickness]);
/// 3 "HouseGableWest", 4 "HouseGableEast" (closed triangular prisms on the
/// x = -w/2 and x = +w/2 walls, wall_thickness thick, from y = wall_height up
/// to the roof underside, closing the attic); 5 "HouseRoof" (add_gable_roof
/// with min = (-w/2, wall_height, -d/2), max = (w/2, *, d/2)). The inside
/// (|x| < w/2 - t, |z| < d/2 - t) is sealed from the sky.
Scene make_house_scene(const HouseDims& dims);
Scene make_house_scene(float roof_pitch_deg, float eaves_overhang = 0.5f);

struct StairsDims {
  int steps = 6;            // count
  float step_width = 1.2f;  // metres, along x, centred at x = 0
  float tread = 0.3f;       // metres, along z
  float riser = 0.18f;      // metres
  float floor_size = 6.0f;  // metres
};
/// Objects: 0 "Floor", 1 "Stairs" (add_stairs with origin (-step_width/2, 0,
/// -steps*tread/2): z in [-steps*tread/2, +steps*tread/2], top tread at
/// y = steps*riser).
Scene make_stairs_scene(const StairsDims& dims = {});

struct BowlDims {
  float radius = 1.0f;      // metres, outer radius, centred at the origin
  float depth = 0.5f;       // metres, rim height above the floor
  float wall = 0.1f;        // metres, wall and basin-floor thickness
  int segments = 32;        // count
  float floor_size = 4.0f;  // metres
};
/// Objects: 0 "Floor", 1 "Bowl" (add_bowl at the origin).
Scene make_bowl_scene(const BowlDims& dims = {});

/// The demo courtyard (assets/scenes/courtyard.glb is written from it by
/// tools/gen_assets.cpp): 34 closed objects, 956 triangles, 9 materials with
/// distinct colours, every object on its own material slot (none uses -1).
/// 24 x 24 m, centred at the origin, on a ground slab whose top is y = 0
/// ("Ground": box x,z in [-12, 12], y in [-0.3, 0]). Groups (object names;
/// footprints in x, z), at least 1 m apart so none shelters another:
///   House: "HouseWalls", "HouseSlab", "HouseGableWest", "HouseGableEast",
///          "HouseRoof": walls x [-10, -3], z [-10, -5], 3 m high, 0.25 m
///          thick; roof pitch 42 deg, ridge along x, eaves 0.5 m (roof x
///          [-10.5, -2.5], z [-10.5, -4.5], ridge top about 5.52 m).
///   Shed: "ShedWalls" (x [6, 9], z [-10, -7.5], 2.2 m), "ShedRoof" (flat
///         slab x [5.8, 9.2], z [-10.2, -7.3], y [2.2, 2.35]), "ShedSlab".
///   Table: "TableTop" (x [1.25, 2.75], z [2.5, 3.5], y [0.7, 0.75]),
///          "TableLeg0".."TableLeg3".
///   Bench: "BenchSeat" (x [-6.8, -5.2], z [-0.2, 0.2], top y = 0.45),
///          "BenchLeg0", "BenchLeg1", "BenchBack" (up to y = 0.9 on -z).
///   Stairs: "Stairs" (5 steps, riser 0.18, tread 0.3, x [8, 9.2], z [2, 3.5],
///           rising along +z), "Terrace" (x [7.5, 11], z [3.5, 7], top
///           y = 1.08: the landing, one riser above the top step), railing
///           "RailPost0".."RailPost6" (0.9 m), "StairRail", "TerraceRailEast",
///           "TerraceRailNorth".
///   Fountain: "FountainBasin" (add_bowl at (-5, 0, 6), radius 1.5, rim
///             0.5 m, wall 0.15), "FountainColumn".
///   Lamp: "LampPole" (at (4, -4), 3 m), "LampHead" (y [3, 3.35]).
SceneBuilder make_courtyard();

/// A delivery truck on a 12 x 12 m ground "Floor", its nose towards -z:
/// "CargoBox" (x [-1.2, 1.2], z [-1, 3.2], y [0.9, 3.4]), "Cab" (z [-2.6,
/// -1.1], y [0.9, 2.8]) with a sloped "Windscreen" wedge in front of it down
/// to the "Hood" (z [-3.5, -2.6], top y = 1.7), a "Chassis" beam and four
/// "Wheel<k>" blocks (0.9 m across, 0.3 m wide): flat roofs with free edges,
/// a sloped windscreen and a gap under the body, for the look of snow on a
/// vehicle.
SceneBuilder make_truck();

/// The wind's test yard on a 40 x 40 m ground "Floor": a 2 m "Cube" at
/// (-8, 0, -8), a "Fence" 1.5 m high across +x (x 2..2.2, z -14..-2), and
/// a "LowerRoof" block 3 m high (x 4..12, z 4..12) against a "HigherBlock"
/// 6 m high (x 12..18): a cube in a field (Tominaga et al. 2011), a snow
/// fence and a roof step (EN 1991-1-3, 5.3.6), for a wind along +x.
SceneBuilder make_wind_yard();

/// A benchmark scene of about `triangles` triangles (>= 300): a rolling
/// terrain "Terrain" over 100 x 100 m (heights within +-1.8 m) as a regular
/// grid, with 8 table tops "Table<k>" (3 x 2 m at y 2.5..2.6) and 8 walls
/// "Wall<k>" (6 m long, 6 m high) standing on it: many small triangles, a
/// few occluders.
SceneBuilder make_terrain(int triangles);

}  // namespace snow

#pragma once
// City scale: `snowmodel snow SCENE --tiles CxR --tile I --tile-dir DIR`
// snows tile I of a C x R split of the untiled run's map grid, on maps
// grown by a halo (plan::tile_halo) so that the snow on the tile itself is
// the untiled run's, and writes the tile's own texels as a maps folder
// DIR/tile_<I> (height, coverage, depth, and what the merge needs to mesh
// them: normal_x/y/z and object) with a "tile" record in its manifest.
// `snowmodel merge DIR` reads the tiles back into the untiled run's maps and
// meshes them in one piece, so patches cross tile borders without seams.
// Tiles run in any order, on any machine; each replaces only its own folder.
#include <filesystem>
#include <string>
#include <vector>

#include "mesh/polygonize.h"
#include "scene/frame.h"
#include "scene/scene.h"
#include "snow/maps.h"

namespace snow::app {

/// A C x R split and one tile of it: index = row * columns + column.
struct TileSpec {
  int columns = 0, rows = 0;
  int index = -1;
};

/// Parses `tiles` ("CxR", each 1..1024) and checks `index` (0..C*R-1).
/// Throws InputError naming the option.
TileSpec parse_tiles(const std::string& tiles, int index);

/// Where a tile lies on the untiled run's grid.
struct TilePlan {
  TileSpec spec;
  MapGrid global;        // the untiled run's grid
  int i0 = 0, j0 = 0;    // the tile's own texels on it: [i0, i1) x [j0, j1)
  int i1 = 0, j1 = 0;    //
  int gi0 = 0, gj0 = 0;  // the first texel of the tile's maps on it
  MapGrid grid;          // the tile's maps: its own texels and the halo, within global
  float halo = 0.0f;     // metres
};

/// Tile `spec` of `global` with a halo of `halo_m` metres (rounded up to
/// whole texels). Columns and rows split the grid as evenly as whole
/// texels allow.
TilePlan plan_tile(const MapGrid& global, const TileSpec& spec, double halo_m);

/// The folder of tile `index` in `dir`.
std::filesystem::path tile_folder(const std::filesystem::path& dir, int index);

/// What a tile writes besides its maps.
struct TileRecord {
  std::string input;        // the scene snowed
  std::string settings;     // the run's settings (JSON text, settings_to_json)
  const Scene* scene;       // the scene of the maps (names the snow patches)
  PolygonizeSettings mesh;  // how its snow is meshed
  FileFrame frame;          // the file's frame, which the meshes go back to
};

/// Writes the tile's own texels of `maps` (peeled on plan.grid), `coverage`
/// and `depth` (the maps' layout) to tile_folder(dir, index) in one step
/// (write_maps), with a "tile" record: the split, the index, the global
/// grid, the own texels, the halo, the input and the settings; and their
/// snow, meshed on its own (cut at the tile's border), as
/// tile_folder(dir, index) + ".glb" for a look at one tile.
void write_tile(const std::filesystem::path& dir, const TilePlan& plan, const SnowMaps& maps,
                const std::vector<float>& coverage, const std::vector<float>& depth,
                const TileRecord& record);

/// Every tile of a folder, assembled.
struct MergedTiles {
  SnowMaps maps;  // the untiled run's grid (ceilings from the layer above)
  std::vector<float> coverage, depth;
  TileSpec split;        // columns and rows (index unused)
  std::string input;     // the scene the tiles snowed
  std::string settings;  // their settings (JSON text)
};

/// Reads the tiles in `dir` and assembles them. Throws InputError naming the
/// problem: no tiles, missing tiles (listed), tiles of another split, grid,
/// scene or settings (named), or merged maps whose memory
/// (kMergeBytesPerLayerTexel per layer texel) exceeds `memory_budget` bytes;
/// IOError where a file cannot be read.
MergedTiles read_tiles(const std::filesystem::path& dir, uint64_t memory_budget);

/// Bytes per layer texel the merge holds: the maps (24), coverage and depth
/// (8), and the meshing's scratch (48).
constexpr uint64_t kMergeBytesPerLayerTexel = 80;

}  // namespace snow::app

#pragma once
// The --maps output: per layer, float images (OpenEXR) of surface height,
// coverage and snow depth, 16-bit PNG previews of each, and a manifest.json
// (origin, texel size, dimensions, layers, up axis, units, files) for
// shader-based snow in engines. The format is documented in README.md ("Snow maps").
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "snow/maps.h"
#include "snow/snowpack.h"

namespace snow {

/// More per layer texel values for write_maps: layer<l>_<name>.exr and .png.
struct MapValues {
  std::string name;                            // file name part: letters, digits, '_'
  const std::vector<float>* values = nullptr;  // maps' layout; 0 written where no surface
  std::string unit;                            // as the manifest states it
};
/// The snowpack's part of a maps folder (--weather runs; what --resume reads
/// back): its values per layer texel and its mass balance (m^3 of water).
struct MapsSnowpack {
  std::vector<MapValues> values;
  double fallen = 0.0, melted = 0.0, lost = 0.0;
  double hour = 0.0;  // hours of weather behind the state
};

/// More for write_maps to hold: values per layer texel, and records of the
/// manifest (name and JSON text, e.g. a tile's record).
struct MapsExtra {
  std::vector<MapValues> values;
  std::vector<std::pair<std::string, std::string>> records;
};

/// The snowpack's part of a maps folder for `pack` after `hour` hours of
/// weather: swe, albedo, density and load (its values point into `pack` and
/// `storage`, which must outlive it).
MapsSnowpack maps_snowpack(const SnowPack& pack, double hour,
                           std::vector<std::vector<float>>& storage);

/// Writes the folder `dir` (its parents created if missing) holding, for
/// every layer l that holds a surface somewhere: layer<l>_height.exr (world
/// Y in metres, NaN where no surface), layer<l>_coverage.exr (in [0,1], 0
/// where no surface; only when coverage is given), layer<l>_depth.exr (snow
/// depth in metres, 0 where no surface; only when depth is given), a .png
/// 16-bit grey preview of each (heights and depths scaled over their range
/// across all layers, coverage over [0,1]; 0 where no surface), and
/// manifest.json. Images are single channel "Y", 32-bit float, ZIP
/// compressed; row r holds grid row j = r (smallest z first) and column i
/// grid column i, i.e. the scene seen from +Y with +X to the right and +Z
/// down. coverage and depth, when given, have the maps' layout (maps.layers
/// * maps.grid.texels() values).
/// The folder is written whole under a temporary name beside `dir` and then
/// put in place in one step (write_folder_atomically): a reader, or a run
/// killed at any moment, sees no folder, the old one or the whole new one,
/// never layers without their manifest. A folder already at `dir` is
/// replaced whole (what it held is deleted), so it must be empty or one
/// written by write_maps (replaceable_maps_folder); anything else is an
/// InputError. Throws InputError for arrays of the wrong size, IOError when
/// the folder or a file cannot be written.
/// With `snowpack`, its values too (each layer of each) and a "snowpack"
/// record in the manifest; with `extra`, its values and records.
void write_maps(const std::filesystem::path& dir, const SnowMaps& maps,
                const std::vector<float>* coverage = nullptr,
                const std::vector<float>* depth = nullptr, const MapsSnowpack* snowpack = nullptr,
                const MapsExtra* extra = nullptr);

/// A maps folder read back (read_maps_folder).
struct MapsFolder {
  MapGrid grid;
  int layers = 0;                          // map_layers
  std::string manifest;                    // manifest.json's text
  std::vector<std::vector<float>> values;  // per name asked, maps' layout, as stored (a layer
                                           // without a file: NaN for "height", else 0)
};

/// Reads the manifest of the maps folder `dir` and the values `names`
/// ("height", "coverage", "depth" or written as MapValues). `where` starts
/// each error message. Throws InputError for a folder that is not a maps
/// folder, a manifest without its fields, an image of another size, or a
/// file name that leaves the folder; IOError where a file cannot be read.
MapsFolder read_maps_folder(const std::filesystem::path& dir, const std::string& where,
                            const std::vector<std::string>& names);

/// Reads back what write_maps wrote with a snowpack, for `maps`: the values
/// named `names` (each in the maps' layout, 0 on layers the folder has no
/// file of) and the mass balance. Throws InputError naming the folder and
/// the mismatch where it was written for another grid (size, texel, origin,
/// layers) or holds no snowpack, IOError where a file cannot be read.
MapsSnowpack read_maps_snowpack(const std::filesystem::path& dir, const SnowMaps& maps,
                                const std::vector<std::string>& names,
                                std::vector<std::vector<float>>& values);

/// True when write_maps may replace what is at `dir`: nothing, an empty
/// folder, or a folder with a manifest.json whose "format" is
/// "snowmodel-maps".
bool replaceable_maps_folder(const std::filesystem::path& dir);

/// A 16-bit greyscale PNG (big-endian samples, Sub filter, zlib from
/// stb_image_write) of `width` x `height` samples, rows top to bottom.
/// Throws InputError for a size that PNG or zlib cannot hold.
std::vector<uint8_t> encode_png16(const std::vector<uint16_t>& grey, int width, int height);

/// A single-channel ("Y") 32-bit float OpenEXR image, ZIP compressed, rows
/// top to bottom. Throws IOError with tinyexr's message on failure.
std::vector<uint8_t> encode_exr(const std::vector<float>& values, int width, int height);

}  // namespace snow

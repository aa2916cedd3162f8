// Tiles and their merge (app/tiles.h).
#include "app/tiles.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "mesh/export.h"
#include "mesh/write_maps.h"

namespace snow::app {
namespace {
namespace fs = std::filesystem;

constexpr int kMaxTilesPerSide = 1024;

/// The values a tile holds besides height, coverage and depth.
const std::vector<std::string> kTileValues = {"normal_x", "normal_y", "normal_z", "object"};

/// Copies the w x h texels from (si, sj) on of each of `layers` layers of
/// `from` (a per layer texel array on `source`) to (di, dj) on of `to` (one
/// on `target`).
template <class T, class U>
void copy_rect(const T& from, const MapGrid& source, int layers, int si, int sj, int w, int h,
               U& to, const MapGrid& target, int di, int dj) {
  for (int l = 0; l < layers; ++l) {
    for (int j = 0; j < h; ++j) {
      const size_t s = (size_t(l) * source.height + size_t(sj + j)) * source.width + size_t(si);
      const size_t t = (size_t(l) * target.height + size_t(dj + j)) * target.width + size_t(di);
      std::copy_n(from.begin() + ptrdiff_t(s), size_t(w), to.begin() + ptrdiff_t(t));
    }
  }
}

nlohmann::json grid_json(const MapGrid& g) {
  return {{"origin", {g.origin.x, g.origin.y}},
          {"texel_size", g.texel},
          {"width", g.width},
          {"height", g.height}};
}

MapGrid grid_of(const nlohmann::json& j) {
  MapGrid g;
  g.origin = {j.at("origin").at(0).get<float>(), j.at("origin").at(1).get<float>()};
  g.texel = j.at("texel_size").get<float>();
  g.width = j.at("width").get<int>();
  g.height = j.at("height").get<int>();
  return g;
}

bool same_grid(const MapGrid& a, const MapGrid& b) {
  return a.width == b.width && a.height == b.height && a.texel == b.texel && a.origin == b.origin;
}

/// "1, 4 and 7" of up to 8 numbers, then "and N more".
std::string list_of(const std::vector<int>& numbers) {
  std::string text;
  for (size_t n = 0; n < numbers.size() && n < 8; ++n) {
    text += (n == 0 ? "" : n + 1 == numbers.size() ? " and " : ", ") + std::to_string(numbers[n]);
  }
  if (numbers.size() > 8) text += " and " + std::to_string(numbers.size() - 8) + " more";
  return text;
}

}  // namespace

TileSpec parse_tiles(const std::string& tiles, int index) {
  TileSpec spec;
  char tail = 0;
  if (std::sscanf(tiles.c_str(), "%dx%d%c", &spec.columns, &spec.rows, &tail) != 2 ||
      spec.columns < 1 || spec.rows < 1 || spec.columns > kMaxTilesPerSide ||
      spec.rows > kMaxTilesPerSide) {
    throw InputError("--tiles must be COLUMNSxROWS, each 1.." + std::to_string(kMaxTilesPerSide) +
                     ", e.g. 4x3, got '" + tiles + "'");
  }
  if (index < 0 || index >= spec.columns * spec.rows) {
    throw InputError("--tile must be 0.." + std::to_string(spec.columns * spec.rows - 1) +
                     " for --tiles " + tiles + ", got " + std::to_string(index));
  }
  spec.index = index;
  return spec;
}

TilePlan plan_tile(const MapGrid& global, const TileSpec& spec, double halo_m) {
  TilePlan p;
  p.spec = spec;
  p.global = global;
  const int c = spec.index % spec.columns, r = spec.index / spec.columns;
  const auto split = [](int size, int parts, int part) {
    return int(int64_t(size) * part / parts);
  };
  p.i0 = split(global.width, spec.columns, c);
  p.i1 = split(global.width, spec.columns, c + 1);
  p.j0 = split(global.height, spec.rows, r);
  p.j1 = split(global.height, spec.rows, r + 1);
  if (p.i1 <= p.i0 || p.j1 <= p.j0) {
    throw InputError("--tiles " + std::to_string(spec.columns) + "x" + std::to_string(spec.rows) +
                     " leaves tile " + std::to_string(spec.index) + " of the " +
                     std::to_string(global.width) + " x " + std::to_string(global.height) +
                     " texel maps empty: use fewer tiles or a finer --texel");
  }
  const int h = int(std::ceil(std::max(halo_m, 0.0) / double(global.texel)));
  p.gi0 = std::max(0, p.i0 - h);
  p.gj0 = std::max(0, p.j0 - h);
  const int gi1 = std::min(global.width, p.i1 + h), gj1 = std::min(global.height, p.j1 + h);
  p.grid.texel = global.texel;
  p.grid.origin = global.origin + glm::vec2(float(p.gi0), float(p.gj0)) * global.texel;
  p.grid.width = gi1 - p.gi0;
  p.grid.height = gj1 - p.gj0;
  p.halo = float(h) * global.texel;
  return p;
}

fs::path tile_folder(const fs::path& dir, int index) {
  char name[32];
  std::snprintf(name, sizeof name, "tile_%04d", index);
  return dir / name;
}

void write_tile(const fs::path& dir, const TilePlan& plan, const SnowMaps& maps,
                const std::vector<float>& coverage, const std::vector<float>& depth,
                const TileRecord& tile) {
  // The tile's own texels as maps of their own.
  SnowMaps own;
  MapGrid g = plan.global;
  g.origin = plan.global.origin + glm::vec2(float(plan.i0), float(plan.j0)) * plan.global.texel;
  g.width = plan.i1 - plan.i0;
  g.height = plan.j1 - plan.j0;
  own.allocate(g, maps.layers);
  const int si = plan.i0 - plan.gi0, sj = plan.j0 - plan.gj0;
  const auto crop = [&](const auto& from, auto& to) {
    copy_rect(from, maps.grid, maps.layers, si, sj, g.width, g.height, to, g, 0, 0);
  };
  crop(maps.ground, own.ground);
  crop(maps.ceiling, own.ceiling);
  crop(maps.normal, own.normal);
  crop(maps.object, own.object);
  const size_t n = size_t(maps.layers) * g.texels();
  std::vector<float> own_coverage(n), own_depth(n);
  crop(coverage, own_coverage);
  crop(depth, own_depth);
  std::vector<std::vector<float>> values(kTileValues.size(), std::vector<float>(n, 0.0f));
  for (size_t k = 0; k < n; ++k) {
    for (int a = 0; a < 3; ++a) values[size_t(a)][k] = own.normal[k][a];
    values[3][k] = float(own.object[k]);
  }
  MapsExtra extra;
  for (size_t v = 0; v < values.size(); ++v) {
    extra.values.push_back({kTileValues[v], &values[v], v < 3 ? "1" : "object index"});
  }
  const nlohmann::json record = {{"columns", plan.spec.columns},
                                 {"rows", plan.spec.rows},
                                 {"index", plan.spec.index},
                                 {"own_texels", {plan.i0, plan.j0, plan.i1, plan.j1}},
                                 {"global", grid_json(plan.global)},
                                 {"halo_m", plan.halo},
                                 {"input", tile.input},
                                 {"settings", nlohmann::json::parse(tile.settings)}};
  extra.records.push_back({"tile", record.dump()});
  const fs::path folder = tile_folder(dir, plan.spec.index);
  write_maps(folder, own, &own_coverage, &own_depth, nullptr, &extra);
  std::vector<SnowPatch> patches = polygonize(own, own_depth, *tile.scene, tile.mesh);
  for (SnowPatch& p : patches) to_file_frame(p.mesh, tile.frame);
  write_snow_meshes(patches, folder.string() + ".glb", MeshFormat::Glb);
}

MergedTiles read_tiles(const fs::path& dir, uint64_t memory_budget) {
  const std::string where = "merge: " + dir.string();
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(where + ": not a folder");
  std::vector<fs::path> folders;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_directory() && name.rfind("tile_", 0) == 0) folders.push_back(e.path());
  }
  if (ec) throw IOError(where + ": cannot list: " + ec.message());
  if (folders.empty()) throw InputError(where + ": holds no tiles (tile_NNNN folders)");
  std::sort(folders.begin(), folders.end());

  MergedTiles out;
  std::map<int, fs::path> tiles;
  nlohmann::json first;
  int layers = 0;
  for (const fs::path& folder : folders) {
    const MapsFolder head = read_maps_folder(folder, where, {});
    const nlohmann::json m = nlohmann::json::parse(head.manifest);
    if (!m.contains("tile")) throw InputError(where + ": " + folder.string() + " is not a tile");
    const nlohmann::json& t = m["tile"];
    try {
      const int index = t.at("index").get<int>();
      if (first.is_null()) {
        first = t;
        out.split = {t.at("columns").get<int>(), t.at("rows").get<int>(), -1};
        out.input = t.at("input").get<std::string>();
        out.settings = t.at("settings").dump();
      }
      const std::string name = folder.filename().string();
      if (t.at("columns") != first.at("columns") || t.at("rows") != first.at("rows"))
        throw InputError(where + ": " + name + " belongs to another split of the scene");
      if (!same_grid(grid_of(t.at("global")), grid_of(first.at("global"))))
        throw InputError(where + ": " + name + " was snowed on another map grid");
      if (t.at("input") != first.at("input"))
        throw InputError(where + ": " + name + " snowed another scene (" +
                         t.at("input").get<std::string>() + ")");
      if (t.at("settings") != first.at("settings"))
        throw InputError(where + ": " + name + " was snowed with other settings");
      if (index < 0 || index >= out.split.columns * out.split.rows ||
          folder != tile_folder(dir, index))
        throw InputError(where + ": " + name + " holds tile " + std::to_string(index));
      tiles[index] = folder;
      layers = std::max(layers, head.layers);
    } catch (const nlohmann::json::exception& e) {
      throw InputError(where + ": " + folder.string() +
                       ": the tile record lacks a field: " + e.what());
    }
  }
  std::vector<int> missing;
  for (int i = 0; i < out.split.columns * out.split.rows; ++i) {
    if (!tiles.count(i)) missing.push_back(i);
  }
  if (!missing.empty()) {
    throw InputError(where + ": tile" + (missing.size() > 1 ? "s " : " ") + list_of(missing) +
                     " of " + std::to_string(out.split.columns) + " x " +
                     std::to_string(out.split.rows) + " missing (run them with --tile)");
  }

  const MapGrid global = grid_of(first.at("global"));
  const uint64_t bytes = uint64_t(layers) * global.texels() * kMergeBytesPerLayerTexel;
  if (bytes > memory_budget) {
    char line[300];
    std::snprintf(line, sizeof line,
                  "%s: the merged maps of %d x %d texels x %d layers need %.1f GiB, over the %.1f "
                  "GiB budget (--memory-budget)",
                  where.c_str(), global.width, global.height, layers, double(bytes) / (1 << 30),
                  double(memory_budget) / (1 << 30));
    throw InputError(line);
  }
  out.maps.allocate(global, layers);
  const size_t n = size_t(layers) * global.texels();
  out.coverage.assign(n, 0.0f);
  out.depth.assign(n, 0.0f);
  std::vector<std::string> names = {"height", "coverage", "depth"};
  names.insert(names.end(), kTileValues.begin(), kTileValues.end());
  for (const auto& [index, folder] : tiles) {
    const TilePlan plan = plan_tile(global, {out.split.columns, out.split.rows, index}, 0.0);
    MapsFolder f = read_maps_folder(folder, where, names);
    if (f.grid.width != plan.i1 - plan.i0 || f.grid.height != plan.j1 - plan.j0) {
      throw InputError(where + ": " + folder.filename().string() + " is " +
                       std::to_string(f.grid.width) + " x " + std::to_string(f.grid.height) +
                       " texels, its place in the split " + std::to_string(plan.i1 - plan.i0) +
                       " x " + std::to_string(plan.j1 - plan.j0));
    }
    // Each value onto the merged maps, on the tile's layers.
    std::vector<float> normal_x = std::move(f.values[3]);
    std::vector<glm::vec3> normal(normal_x.size());
    std::vector<int32_t> object(normal_x.size());
    for (size_t k = 0; k < normal.size(); ++k) {
      const bool surface = !std::isnan(f.values[0][k]);
      normal[k] =
          surface ? glm::vec3(normal_x[k], f.values[4][k], f.values[5][k]) : glm::vec3(0.0f);
      object[k] = surface ? int32_t(std::lround(f.values[6][k])) : -1;
    }
    const auto place = [&](const auto& from, auto& to) {
      copy_rect(from, f.grid, f.layers, 0, 0, f.grid.width, f.grid.height, to, global, plan.i0,
                plan.j0);
    };
    place(f.values[0], out.maps.ground);
    place(f.values[1], out.coverage);
    place(f.values[2], out.depth);
    place(normal, out.maps.normal);
    place(object, out.maps.object);
  }
  // The ceilings, as the peel sets them: the surface above, the open sky on top.
  const size_t texels = global.texels();
  for (size_t k = texels; k < n; ++k) {
    if (!std::isnan(out.maps.ground[k])) out.maps.ceiling[k] = out.maps.ground[k - texels];
  }
  return out;
}

}  // namespace snow::app

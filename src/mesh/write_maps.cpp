// The --maps writer: OpenEXR float images (tinyexr), 16-bit PNG previews
// (PNG 1.2 specification, W3C; zlib from stb_image_write) and a JSON
// manifest. Format: README.md, "Snow maps".
#include "mesh/write_maps.h"

#include <tinyexr.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <system_error>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"

// Debian's libstb exports the zlib encoder of stb_image_write, which its
// header declares only in the implementation part.
extern "C" unsigned char* stbi_zlib_compress(unsigned char* data, int data_len, int* out_len,
                                             int quality);

namespace snow {
namespace {

constexpr int kFormatVersion = 1;

const char* const kNotMapsFolder =
    "the folder holds files and no snowmodel manifest.json; a maps folder is replaced whole: "
    "name a new or empty folder, or one written by --maps";

uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc = 0) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t n = 0; n < 256; ++n) {
      uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (size_t k = 0; k < size; ++k) crc = table[(crc ^ data[k]) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  out.push_back(uint8_t(v >> 24));
  out.push_back(uint8_t(v >> 16));
  out.push_back(uint8_t(v >> 8));
  out.push_back(uint8_t(v));
}

void put_chunk(std::vector<uint8_t>& out, const char type[4], const uint8_t* data, size_t size) {
  put_u32(out, uint32_t(size));
  const size_t start = out.size();
  out.insert(out.end(), type, type + 4);
  if (size) out.insert(out.end(), data, data + size);
  put_u32(out, crc32(out.data() + start, size + 4));
}

bool layer_has_surface(const SnowMaps& maps, int l) {
  const size_t texels = maps.grid.texels();
  const float* g = maps.ground.data() + size_t(l) * texels;
  for (size_t t = 0; t < texels; ++t) {
    if (!std::isnan(g[t])) return true;
  }
  return false;
}

// Range of the values of `v` (one per layer texel of the maps) at texels
// with a surface (finite ones only).
std::pair<float, float> value_range(const SnowMaps& maps, const float* v) {
  float lo = std::numeric_limits<float>::max(), hi = -std::numeric_limits<float>::max();
  for (size_t k = 0; k < maps.ground.size(); ++k) {
    if (std::isnan(maps.ground[k]) || !std::isfinite(v[k])) continue;
    lo = std::min(lo, v[k]);
    hi = std::max(hi, v[k]);
  }
  if (lo > hi) lo = hi = 0.0f;
  return {lo, hi};
}

}  // namespace

std::vector<uint8_t> encode_png16(const std::vector<uint16_t>& grey, int width, int height) {
  if (width < 1 || height < 1 || grey.size() != size_t(width) * size_t(height)) {
    throw InputError("16-bit PNG: " + std::to_string(grey.size()) + " samples for " +
                     std::to_string(width) + " x " + std::to_string(height));
  }
  const size_t row = size_t(width) * 2 + 1;
  if (row * size_t(height) > size_t(std::numeric_limits<int>::max())) {
    throw InputError("16-bit PNG: " + std::to_string(width) + " x " + std::to_string(height) +
                     " is too large for one zlib stream");
  }
  // Filter type 1 (Sub) on big-endian samples: byte x minus byte x - 2.
  std::vector<uint8_t> raw(row * size_t(height));
  for (int j = 0; j < height; ++j) {
    uint8_t* out = raw.data() + size_t(j) * row;
    out[0] = 1;
    uint8_t prev_hi = 0, prev_lo = 0;
    for (int i = 0; i < width; ++i) {
      const uint16_t v = grey[size_t(j) * size_t(width) + size_t(i)];
      const uint8_t hi = uint8_t(v >> 8), lo = uint8_t(v & 0xFF);
      out[1 + 2 * i] = uint8_t(hi - prev_hi);
      out[2 + 2 * i] = uint8_t(lo - prev_lo);
      prev_hi = hi;
      prev_lo = lo;
    }
  }
  int zlen = 0;
  unsigned char* z = stbi_zlib_compress(raw.data(), int(raw.size()), &zlen, 6);
  if (!z) throw InputError("16-bit PNG: zlib compression failed");
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  std::vector<uint8_t> ihdr;
  put_u32(ihdr, uint32_t(width));
  put_u32(ihdr, uint32_t(height));
  ihdr.insert(ihdr.end(), {16, 0, 0, 0, 0});  // depth 16, grey, deflate, filters, no interlace
  put_chunk(png, "IHDR", ihdr.data(), ihdr.size());
  put_chunk(png, "IDAT", z, size_t(zlen));
  std::free(z);
  put_chunk(png, "IEND", nullptr, 0);
  return png;
}

std::vector<uint8_t> encode_exr(const std::vector<float>& values, int width, int height) {
  if (width < 1 || height < 1 || values.size() != size_t(width) * size_t(height)) {
    throw InputError("EXR: " + std::to_string(values.size()) + " values for " +
                     std::to_string(width) + " x " + std::to_string(height));
  }
  EXRHeader header;
  InitEXRHeader(&header);
  EXRImage image;
  InitEXRImage(&image);
  EXRChannelInfo channel;
  std::memset(&channel, 0, sizeof channel);
  std::strncpy(channel.name, "Y", sizeof channel.name - 1);
  int pixel_type = TINYEXR_PIXELTYPE_FLOAT;
  int requested = TINYEXR_PIXELTYPE_FLOAT;
  header.num_channels = 1;
  header.channels = &channel;
  header.pixel_types = &pixel_type;
  header.requested_pixel_types = &requested;
  header.compression_type = TINYEXR_COMPRESSIONTYPE_ZIP;
  const float* plane = values.data();
  image.num_channels = 1;
  image.images = reinterpret_cast<unsigned char**>(const_cast<float**>(&plane));
  image.width = width;
  image.height = height;
  unsigned char* memory = nullptr;
  const char* err = nullptr;
  const size_t size = SaveEXRImageToMemory(&image, &header, &memory, &err);
  if (size == 0 || !memory) {
    const std::string message = err ? err : "unknown error";
    if (err) FreeEXRErrorMessage(err);
    throw IOError("EXR encoding failed: " + message);
  }
  std::vector<uint8_t> out(memory, memory + size);
  std::free(memory);
  return out;
}

namespace {
/// The files of write_maps, written into the existing folder `dir`.
void write_maps_into(const std::filesystem::path& dir, const SnowMaps& maps,
                     const std::vector<float>* coverage, const std::vector<float>* depth,
                     const MapsSnowpack* snowpack, const MapsExtra* extra);
}  // namespace

void write_maps(const std::filesystem::path& dir, const SnowMaps& maps,
                const std::vector<float>* coverage, const std::vector<float>* depth,
                const MapsSnowpack* snowpack, const MapsExtra* extra) {
  const MapGrid& g = maps.grid;
  const size_t texels = g.texels();
  const size_t total = size_t(std::max(maps.layers, 0)) * texels;
  if (maps.ground.size() != total || g.width < 1 || g.height < 1) {
    throw InputError("maps writer: the snow maps are inconsistent (arrays do not match the grid)");
  }
  std::vector<std::pair<std::string, const std::vector<float>*>> given = {{"coverage", coverage},
                                                                          {"snow depth", depth}};
  if (snowpack) {
    for (const MapValues& v : snowpack->values) given.emplace_back(v.name, v.values);
  }
  if (extra) {
    for (const MapValues& v : extra->values) given.emplace_back(v.name, v.values);
  }
  for (const auto& [name, v] : given) {
    if (v && v->size() != total) {
      throw InputError("maps writer: " + name + " has " + std::to_string(v->size()) +
                       " values, the maps have " + std::to_string(total));
    }
  }
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec)) {
    throw IOError("cannot create the maps folder " + dir.string() + ": a file is there");
  }
  if (!replaceable_maps_folder(dir)) {
    throw InputError(dir.string() + ": " + kNotMapsFolder);
  }
  write_folder_atomically(dir, [&](const std::filesystem::path& tmp) {
    write_maps_into(tmp, maps, coverage, depth, snowpack, extra);
  });
}

bool replaceable_maps_folder(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return true;
  if (!fs::is_directory(dir, ec)) return false;
  if (fs::is_empty(dir, ec) && !ec) return true;
  std::ifstream in(dir / "manifest.json", std::ios::binary);
  if (!in) return false;
  const nlohmann::json manifest = nlohmann::json::parse(in, nullptr, false);
  return manifest.is_object() && manifest.value("format", nlohmann::json()) == "snowmodel-maps";
}

namespace {

void write_maps_into(const std::filesystem::path& dir, const SnowMaps& maps,
                     const std::vector<float>* coverage, const std::vector<float>* depth,
                     const MapsSnowpack* snowpack, const MapsExtra* extra) {
  const MapGrid& g = maps.grid;
  const size_t texels = g.texels();

  struct Kind {
    const char* name;
    const std::vector<float>* values;  // nullptr: the heights
    const char* unit;
    const char* meaning;
  };
  std::vector<Kind> kinds = {{"height", nullptr, "m", "surface height, world Y"}};
  if (coverage) kinds.push_back({"coverage", coverage, "1", "share of fall directions that reach"});
  if (depth) kinds.push_back({"depth", depth, "m", "snow depth, vertical"});
  for (const std::vector<MapValues>* values :
       {snowpack ? &snowpack->values : nullptr, extra ? &extra->values : nullptr}) {
    for (size_t v = 0; values && v < values->size(); ++v) {
      const MapValues& m = (*values)[v];
      kinds.push_back({m.name.c_str(), m.values, m.unit.c_str(), ""});
    }
  }

  nlohmann::ordered_json files = nlohmann::ordered_json::array();
  nlohmann::ordered_json ranges = nlohmann::ordered_json::object();
  std::vector<float> plane(texels);
  std::vector<uint16_t> preview(texels);
  int written_layers = 0;
  for (const Kind& kind : kinds) {
    const float* all = kind.values ? kind.values->data() : maps.ground.data();
    auto [lo, hi] = std::string(kind.name) == "coverage" ? std::pair<float, float>(0.0f, 1.0f)
                                                         : value_range(maps, all);
    ranges[kind.name] = {{"png_black", lo}, {"png_white", hi}, {"unit", kind.unit}};
    const float scale = hi > lo ? 65535.0f / (hi - lo) : 0.0f;
    for (int l = 0; l < maps.layers; ++l) {
      if (!layer_has_surface(maps, l)) continue;
      if (&kind == &kinds.front()) written_layers = l + 1;
      const size_t base = size_t(l) * texels;
      for (size_t t = 0; t < texels; ++t) {
        const bool surface = !std::isnan(maps.ground[base + t]);
        const float v = all[base + t];
        plane[t] = kind.values ? (surface && std::isfinite(v) ? v : 0.0f) : v;
        const float n =
            surface && std::isfinite(v) ? std::clamp((v - lo) * scale, 0.0f, 65535.0f) : 0.0f;
        preview[t] = uint16_t(std::lround(n));
      }
      const std::string stem = "layer" + std::to_string(l) + "_" + kind.name;
      const std::vector<uint8_t> exr = encode_exr(plane, g.width, g.height);
      write_bytes_atomically(dir / (stem + ".exr"), exr.data(), exr.size());
      const std::vector<uint8_t> png = encode_png16(preview, g.width, g.height);
      write_bytes_atomically(dir / (stem + ".png"), png.data(), png.size());
      files.push_back({{"layer", l},
                       {"kind", kind.name},
                       {"exr", stem + ".exr"},
                       {"png", stem + ".png"},
                       {"unit", kind.unit}});
    }
  }

  nlohmann::ordered_json manifest;
  manifest["format"] = "snowmodel-maps";
  manifest["version"] = kFormatVersion;
  manifest["units"] = "metres";
  manifest["up_axis"] = "+Y";
  manifest["origin"] = {g.origin.x, g.origin.y};
  manifest["origin_axes"] = "world (x, z) of the corner of texel (0, 0)";
  manifest["texel_size"] = g.texel;
  manifest["width"] = g.width;
  manifest["height"] = g.height;
  manifest["image_axes"] =
      "column i along +X, row j along +Z, row 0 first (the scene seen from +Y, +X right, +Z "
      "down); texel (i, j) centre at origin + ((i + 0.5), (j + 0.5)) * texel_size";
  manifest["layers"] = written_layers;
  manifest["map_layers"] = maps.layers;
  manifest["layer_order"] = "top down: layer 0 is the highest surface under the sky";
  manifest["overflow_columns"] = maps.overflow_columns;
  manifest["no_surface"] = "height NaN; coverage and depth 0; previews 0";
  manifest["exr"] = "one float32 channel Y, ZIP compression";
  manifest["png"] = "16-bit grey, value = png_black + sample / 65535 * (png_white - png_black)";
  manifest["ranges"] = ranges;
  manifest["files"] = files;
  if (snowpack) {
    manifest["snowpack"] = {{"unit", "m^3 of water"},
                            {"fallen", snowpack->fallen},
                            {"melted", snowpack->melted},
                            {"lost", snowpack->lost},
                            {"hour", snowpack->hour}};
  }
  for (size_t r = 0; extra && r < extra->records.size(); ++r) {
    manifest[extra->records[r].first] = nlohmann::ordered_json::parse(extra->records[r].second);
  }
  write_text_atomically(dir / "manifest.json", manifest.dump(2) + "\n");
}

}  // namespace

MapsFolder read_maps_folder(const std::filesystem::path& dir, const std::string& where,
                            const std::vector<std::string>& names) {
  std::ifstream in(dir / "manifest.json", std::ios::binary);
  if (!in) throw InputError(where + ": no manifest.json (give a folder written by --maps)");
  MapsFolder out;
  out.manifest.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  const nlohmann::json m = nlohmann::json::parse(out.manifest, nullptr, false);
  if (!m.is_object() || m.value("format", nlohmann::json()) != "snowmodel-maps") {
    throw InputError(where + ": manifest.json is not a snowmodel maps manifest");
  }
  try {
    MapGrid& g = out.grid;
    g.texel = m.at("texel_size").get<float>();
    g.origin = {m.at("origin").at(0).get<float>(), m.at("origin").at(1).get<float>()};
    g.width = m.at("width").get<int>();
    g.height = m.at("height").get<int>();
    out.layers = m.at("map_layers").get<int>();
    if (g.width < 1 || g.height < 1 || out.layers < 1 || out.layers > 64 || !(g.texel > 0.0f) ||
        double(g.width) * double(g.height) * out.layers > double(size_t(1) << 34)) {
      throw InputError(where + ": manifest.json gives an impossible grid");
    }
    const size_t texels = g.texels();
    for (const std::string& name : names) {
      out.values.emplace_back(size_t(out.layers) * texels, name == "height" ? NAN : 0.0f);
    }
    for (const nlohmann::json& f : m.at("files")) {
      const auto name = std::find(names.begin(), names.end(), f.at("kind").get<std::string>());
      const int l = f.at("layer").get<int>();
      if (name == names.end() || l < 0 || l >= out.layers) continue;
      const std::filesystem::path path = dir / f.at("exr").get<std::string>();
      if (path.filename() != path.lexically_relative(dir)) {
        throw InputError(where + ": a file name leaves the folder: " + path.string());
      }
      float* image = nullptr;
      int w = 0, h = 0;
      const char* err = nullptr;
      if (LoadEXR(&image, &w, &h, path.c_str(), &err) != TINYEXR_SUCCESS) {
        const std::string message = err ? err : "unknown error";
        if (err) FreeEXRErrorMessage(err);
        throw IOError(where + ": cannot read " + path.filename().string() + ": " + message);
      }
      std::vector<float>& values = out.values[size_t(name - names.begin())];
      if (w == g.width && h == g.height) {
        // LoadEXR gives RGBA; a single-channel image fills each with Y.
        for (size_t t = 0; t < texels; ++t) values[size_t(l) * texels + t] = image[4 * t];
      }
      std::free(image);
      if (w != g.width || h != g.height) {
        throw InputError(where + ": " + path.filename().string() + " is " + std::to_string(w) +
                         " x " + std::to_string(h) + ", the manifest says " +
                         std::to_string(g.width) + " x " + std::to_string(g.height));
      }
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where + ": manifest.json lacks a field: " + e.what());
  }
  return out;
}

MapsSnowpack read_maps_snowpack(const std::filesystem::path& dir, const SnowMaps& maps,
                                const std::vector<std::string>& names,
                                std::vector<std::vector<float>>& values) {
  const std::string where = "resume: " + dir.string();
  MapsFolder folder = read_maps_folder(dir, where, names);
  const nlohmann::json m = nlohmann::json::parse(folder.manifest);
  if (!m.contains("snowpack") || !m["snowpack"].is_object()) {
    throw InputError(where + ": the maps hold no snowpack (write them from a --weather run)");
  }
  const MapGrid& g = maps.grid;
  const MapGrid& f = folder.grid;
  const float tolerance = 1e-3f * g.texel;
  if (f.width != g.width || f.height != g.height || folder.layers != maps.layers ||
      std::abs(f.texel - g.texel) > 1e-6f * g.texel ||
      std::abs(f.origin.x - g.origin.x) > tolerance ||
      std::abs(f.origin.y - g.origin.y) > tolerance) {
    char line[400];
    std::snprintf(line, sizeof line,
                  "%s: written for %d x %d texels of %.6g m at (%.6g, %.6g) with %d layers; this "
                  "run's maps are %d x %d of %.6g m at (%.6g, %.6g) with %d layers (same scene, "
                  "--texel or --max-side, --layers and --margin as the first run)",
                  where.c_str(), f.width, f.height, double(f.texel), double(f.origin.x),
                  double(f.origin.y), folder.layers, g.width, g.height, double(g.texel),
                  double(g.origin.x), double(g.origin.y), maps.layers);
    throw InputError(line);
  }
  MapsSnowpack out;
  try {
    const nlohmann::json& p = m["snowpack"];
    out.fallen = p.at("fallen").get<double>();
    out.melted = p.at("melted").get<double>();
    out.lost = p.at("lost").get<double>();
    out.hour = p.at("hour").get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where + ": manifest.json lacks a field: " + e.what());
  }
  values = std::move(folder.values);
  for (std::vector<float>& v : values) {
    for (float& x : v) x = std::isfinite(x) && x > 0.0f ? x : 0.0f;
  }
  return out;
}

MapsSnowpack maps_snowpack(const SnowPack& pack, double hour,
                           std::vector<std::vector<float>>& storage) {
  storage = {pack.density(), pack.load()};
  MapsSnowpack out;
  out.values = {{"swe", &pack.swe, "m of water"},
                {"albedo", &pack.albedo, "1"},
                {"density", &storage[0], "kg/m^3"},
                {"load", &storage[1], "kN/m^2"}};
  out.fallen = pack.fallen;
  out.melted = pack.melted;
  out.lost = pack.lost;
  out.hour = hour;
  return out;
}

}  // namespace snow

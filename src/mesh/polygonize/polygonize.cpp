// Polygonize fallen snow: the driver over the steps in steps.h.
//
// 1. Patches (patches.cpp): snowy layer texels joined across layers by the
//    stabilizer's landing rule (snow::landing_layer; height spans after
//    Onoue and Nishita), so a floor running under a table is one patch.
// 2. Per patch, a thickness field s and a ground field g on texel centres
//    (fields.cpp); the top is g + s, the outline the marching-squares
//    contour of s at min_thickness (Lorensen and Cline 1987, the 2D case;
//    saddles resolved by the cell average), where the snow tapers to zero
//    thickness; the bottom is g - bottom_offset. Top and bottom share the
//    outline vertices, so the result is a closed 2-manifold by construction
//    (top.cpp, solid.cpp). Inside the outline the grid is triangulated
//    adaptively as a right-triangulated irregular network (Evans,
//    Kirkpatrick and Townsend 2001, error pass after mapbox/martini) within
//    half the error budget, so that large flat snow fields never reach the
//    decimator at full resolution.
// 3. Edge-collapse decimation with OpenMesh's Decimater within the other
//    half (decimate.cpp; large tops in pieces, pieces.cpp), the priority
//    and bound being the quadric error of Garland and Heckbert (SIGGRAPH
//    1997) over unweighted planes, i.e. a sum of squared distances in
//    metres.
#include "mesh/polygonize.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <mutex>
#include <numeric>
#include <optional>
#include <set>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "mesh/polygonize/steps.h"

namespace snow {
namespace {

using namespace poly;

std::string unique_name(const std::string& base, std::set<std::string>& used) {
  std::string name = base;
  for (int k = 2; used.count(name); ++k) name = base + "_" + std::to_string(k);
  used.insert(name);
  return name;
}

/// Fills patch.texels, patch.depth_volume (m^3) and patch.object (the scene
/// object most of the patch's texels rest on; -1: none, or one not in the
/// scene); returns the median snow depth of its texels (metres).
float survey_patch(const SnowMaps& maps, const LayerArray<float>& d, const Scene& scene,
                   const PatchTexels& texels, SnowPatch& patch) {
  const float texel = maps.grid.texel;
  patch.texels = texels.texels.size();
  // Texels of each object: [o + 1] for object o, [0] for none (or one not in the scene).
  std::vector<size_t> votes(scene.objects.size() + 1, 0);
  std::vector<float> thickness;
  thickness.reserve(texels.texels.size());
  for (size_t k : texels.texels) {
    patch.depth_volume += double(d[k]) * double(texel) * double(texel);
    const int32_t o = maps.object[k];
    ++votes[o >= 0 && size_t(o) < scene.objects.size() ? size_t(o) + 1 : 0];
    thickness.push_back(d[k]);
  }
  size_t best = 0;
  for (size_t v = 0; v < votes.size(); ++v) {
    if (votes[v] > best) {
      best = votes[v];
      patch.object = int(v) - 1;
    }
  }
  std::nth_element(thickness.begin(), thickness.begin() + thickness.size() / 2, thickness.end());
  return thickness[thickness.size() / 2];
}

/// The closed, decimated solid of `top` within max_error (metres), in
/// `pieces` pieces (top_pieces' `piece`) where there is more than one and
/// they each form a manifold mesh, else whole (`pieces` then 1). False, and
/// a warning, where the top does not close into a manifold mesh.
bool build_patch_solid(const TopMesh& top, const Pieces& piece, size_t& pieces,
                       const PatchField& field, float bottom_offset, double max_error,
                       const std::string& name, Solid& solid) {
  if (pieces > 1 &&
      !build_decimated_in_pieces(top, piece, pieces, field, bottom_offset, max_error, solid)) {
    log_debug("polygonize: " + name + " does not split into " + std::to_string(pieces) +
              " manifold pieces; decimating it whole");
    solid = Solid();
    pieces = 1;
  }
  if (pieces == 1) {
    const size_t failed = build_decimated_solid(top, field, bottom_offset, max_error, solid);
    if (failed > 0) {
      log_warn("polygonize: dropping snow patch " + name + ": " + std::to_string(failed) +
               " faces would not form a manifold mesh");
      return false;
    }
  }
  return true;
}

// Meshes one patch: its top surface, the closed solid, decimation; nullopt
// when it is degenerate, or too small (its plan area then in *small_area).
// Named after its object in mesh.name, made unique by the caller. Safe to
// run for several patches at once.
std::optional<SnowPatch> mesh_patch(const SnowMaps& maps, const LayerArray<float>& d,
                                    const Scene& scene, const PolygonizeSettings& settings,
                                    float min_thickness, const PatchTexels& texels,
                                    double* small_area) {
  const auto start = std::chrono::steady_clock::now();
  auto lap = start;
  const auto seconds = [&lap] {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - lap).count();
    lap = now;
    return s;
  };
  const float texel = maps.grid.texel;
  SnowPatch patch;
  const float median_depth = survey_patch(maps, d, scene, texels, patch);
  const bool named = patch.object >= 0 && size_t(patch.object) < scene.objects.size();
  const std::string base =
      named ? "snow/" + scene.objects[size_t(patch.object)].name : std::string("snow/patch");

  // Error budget: half for the grid-level triangulation, half for the
  // OpenMesh decimation that follows.
  double error =
      settings.decimate_error < 0.0f ? 0.5 * double(texel) : double(settings.decimate_error);
  error = std::min(error, 0.25 * double(median_depth));

  PatchField field = build_field(maps, d, texels);
  if (settings.shoulder_radius > 0.0f) {
    round_shoulders(field, maps, d, texels, settings.shoulder_radius, settings.open_beyond);
  }
  smooth_field(field, settings.smooth_iterations, min_thickness);
  const double field_seconds = seconds();
  const double tolerance = error > 0.0 ? 0.5 * error : -1.0;
  // A wide window is triangulated with cuts between strips of columns (16
  // strips or more, each at least kMinCut wide, so the cuts only split a few
  // large triangles), and a top with many triangles is decimated in pieces
  // of whole strips, each piece with its own bottom (the bottom keeps the
  // cut there).
  int cut = 0;
  if (error > 0.0 && settings.piece_triangles > 0) {
    for (int c = kMinCut; c * 16 <= field.w; c *= 2) cut = c;
  }
  TopMesh top =
      triangulate_top(field, maps.grid, min_thickness, tolerance, cut, settings.piece_triangles);
  size_t pieces = 1;
  Pieces piece;
  if (top.in_pieces) {
    pieces = (top.tris.size() / 3 + settings.piece_triangles - 1) / settings.piece_triangles;
    piece = top_pieces(top, field, maps.grid, cut, pieces);
  }
  smooth_outline(top, settings.smooth_iterations, texel);
  patch.area = top_plan_area(top);
  if (patch.area < double(settings.min_patch_area)) {
    *small_area = patch.area;
    return std::nullopt;
  }
  const double top_seconds = seconds();

  const float bottom_offset = std::max(settings.bottom_offset, 0.0f);
  Solid solid;
  if (!build_patch_solid(top, piece, pieces, field, bottom_offset, 0.5 * error, base, solid)) {
    return std::nullopt;
  }

  if (settings.shoulder_radius > 0.0f) {
    add_lips(solid, field, texel, maps.grid.origin, settings.overhang, settings.cornice);
  }
  flip_degenerate_faces(solid);
  const double solid_seconds = seconds();
  const TriMesh closed = to_trimesh(solid, false);
  patch.volume = signed_volume(closed);
  patch.mesh = settings.closed ? closed : to_trimesh(solid, true);
  patch.mesh.name = base;
  patch.mesh.material = 0;
  if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >= 0.05) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "polygonize: %s, %zu texels, %zu top triangles in %zu pieces: field %.3f s, top "
                  "%.3f s, solid %.3f s, mesh %.3f s",
                  base.c_str(), patch.texels, top.tris.size() / 3, pieces, field_seconds,
                  top_seconds, solid_seconds, seconds());
    log_debug(line);
  }
  return patch;
}

/// InputError unless `maps` and `depth` are consistent (polygonize's
/// contract).
void check_inputs(const SnowMaps& maps, const std::vector<float>& depth) {
  const size_t n = size_t(std::max(maps.layers, 0)) * maps.grid.texels();
  if (maps.layers < 0 || maps.grid.width < 0 || maps.grid.height < 0 || !(maps.grid.texel > 0.0f) ||
      !std::isfinite(maps.grid.texel)) {
    throw InputError("polygonize: snow maps have an invalid grid (texel " +
                     std::to_string(maps.grid.texel) + " m)");
  }
  if (maps.ground.size() != n || maps.ceiling.size() != n || maps.normal.size() != n ||
      maps.object.size() != n) {
    throw InputError("polygonize: snow maps arrays do not match " + std::to_string(maps.layers) +
                     " layers of " + std::to_string(maps.grid.width) + "x" +
                     std::to_string(maps.grid.height) + " texels");
  }
  if (depth.size() != n) {
    throw InputError("polygonize: snow depth has " + std::to_string(depth.size()) +
                     " values, the maps have " + std::to_string(n) + " layer texels");
  }
  if (maps.grid.texels() >= size_t(std::numeric_limits<uint32_t>::max())) {
    throw InputError(
        "polygonize: maps of 2^32 texels or more are not supported; use a coarser "
        "texel size");
  }
}

/// One debug line for all the patches dropped as too small (area >= 0 in
/// small_area, m^2): a building's fringe can leave hundreds of single texels.
void log_small_patches(const std::vector<double>& small_area, float min_patch_area) {
  size_t small = 0;
  double largest_small = 0.0;
  for (const double area : small_area) {
    if (area < 0.0) continue;
    ++small;
    largest_small = std::max(largest_small, area);
  }
  if (small > 0) {
    char line[160];
    std::snprintf(line, sizeof line,
                  "polygonize: dropped %zu snow patches under the smallest area kept, %.3g m^2 "
                  "(the largest %.3g m^2)",
                  small, double(min_patch_area), largest_small);
    log_debug(line);
  }
}

}  // namespace

std::vector<SnowPatch> polygonize(const SnowMaps& maps, const std::vector<float>& depth,
                                  const Scene& scene, PolygonizeSettings settings) {
  check_inputs(maps, depth);
  const size_t n = size_t(std::max(maps.layers, 0)) * maps.grid.texels();
  const float texel = maps.grid.texel;
  const float min_thickness = std::max(settings.min_thickness, 0.0f);
  const float connect = std::clamp(settings.connect_slope, 0.0f, 89.0f);
  const float max_step = texel * std::tan(glm::radians(connect));

  // Clean depth: NaN, negative or surface-less snow is no snow. Written
  // once, on all cores (a LayerArray, not a zero-filled vector).
  const auto t0 = std::chrono::steady_clock::now();
  LayerArray<float> d(n);
  parallel_for_ranges(n, kFieldChunk, [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) {
      const float v = depth[k];
      d[k] = !std::isnan(maps.ground[k]) && std::isfinite(v) && v > 0.0f ? v : 0.0f;
    }
  });

  const std::vector<PatchTexels> found = find_patches(maps, d, min_thickness, max_step);
  char found_line[96];
  std::snprintf(found_line, sizeof found_line, "polygonize: %zu patches found in %.3f s",
                found.size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  log_debug(found_line);
  // Patches are meshed in parallel, largest first (the ground often outweighs
  // the rest), then named and kept in their found order.
  std::vector<size_t> order(found.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return found[a].texels.size() > found[b].texels.size();
  });
  std::vector<std::optional<SnowPatch>> meshed(found.size());
  std::vector<double> small_area(found.size(), -1.0);  // of each patch dropped as too small
  Progress progress("polygonize", double(found.size()));
  std::mutex progress_mutex;
  size_t done = 0;
  parallel_for(order.size(), [&](size_t q) {
    const size_t p = order[q];
    meshed[p] = mesh_patch(maps, d, scene, settings, min_thickness, found[p], &small_area[p]);
    std::lock_guard<std::mutex> lock(progress_mutex);
    progress.update(double(++done));
  });
  log_small_patches(small_area, settings.min_patch_area);
  std::vector<SnowPatch> out;
  std::set<std::string> used_names;
  for (std::optional<SnowPatch>& patch : meshed) {
    if (!patch) continue;
    patch->mesh.name = unique_name(patch->mesh.name, used_names);
    out.push_back(std::move(*patch));
  }
  progress.finish();
  return out;
}

}  // namespace snow

#include "app/snow_warnings.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include <glm/glm.hpp>

#include "core/log.h"
#include "plan/plan.h"
#include "plan/rules.h"
#include "scene/builder.h"
#include "scene/frame.h"

namespace snow::app {

void warn_if_out_of_scale(const Scene& scene, float fall_depth) {
  const glm::vec3 size = scene.bounds.max - scene.bounds.min;
  const float width = std::max(size.x, size.z);
  if (!(width > 0) || fall_depth <= 0.1f * width) return;
  char line[300];
  std::snprintf(line, sizeof line,
                "snow depth %.3g m is %.0f %% of the scene's width (%.3g m); glTF units are "
                "metres: if the scene is not to scale, lower --depth",
                double(fall_depth), 100.0 * double(fall_depth / width), double(width));
  log_warn(line);
}

void warn_if_not_metres_y_up(const Scene& scene) {
  const std::string& generator = scene.generator;
  const FrameFigures f = frame_figures(scene);
  const plan::FrameAdvice a = plan::advise_frame(scene.objects.size(), f.median_object_size,
                                                 f.area_facing_y, f.area_facing_z);
  const std::string by = generator.empty() ? "" : " (written by " + generator + ")";
  if (a.unit_scale != 1.0f) {
    char line[400];
    std::snprintf(line, sizeof line,
                  "the scene's objects are %.3g units across (median)%s: glTF units are metres; "
                  "if the scene is in %s, give --unit-scale %g",
                  double(f.median_object_size), by.c_str(),
                  a.unit_scale < 0.005f ? "millimetres" : "centimetres", double(a.unit_scale));
    log_warn(line);
  }
  if (a.z_up) {
    log_warn("most of the scene's area faces +-Z, little faces up (+Y)" + by +
             ": if the scene is +Z up, give --up z");
  }
}

void warn_if_imprecise(const Scene& scene, float fall_depth) {
  const glm::vec3 far = glm::max(glm::abs(scene.bounds.min), glm::abs(scene.bounds.max));
  const float reach = std::max({far.x, far.y, far.z});
  if (!(std::isfinite(reach) && fall_depth > 0.0f)) return;
  const float step = std::nextafter(reach, INFINITY) - reach;
  if (!(step > 0.1f * fall_depth)) return;
  char line[300];
  std::snprintf(line, sizeof line,
                "the scene reaches %.3g m from the origin, where 32-bit floats are %.3g m apart: "
                "too coarse for %.3g m of snow; move the scene near the origin (or check its "
                "units)",
                double(reach), double(step), double(fall_depth));
  log_warn(line);
}

void warn_if_deep_in_texels(const SnowMaps& maps, float fall_depth) {
  const float texels = fall_depth / maps.grid.texel;
  if (!(texels > plan::kDeepTexels)) return;
  const int side = std::max(maps.grid.width, maps.grid.height);
  const int suggested = plan::side_for_depth(side, maps.grid.texel, fall_depth);
  char line[300];
  std::snprintf(line, sizeof line,
                "the snow is %.0f texels deep (%.3g m on %.3g m texels): the maps are far finer "
                "than its shapes need, at a cost in time; --max-side %d (or --texel %.3g) makes "
                "it %.0f texels deep",
                double(texels), double(fall_depth), double(maps.grid.texel), suggested,
                double(fall_depth / plan::kAimTexels), double(plan::kAimTexels));
  log_warn(line);
}

void warn_if_unsettled(const SnowResult& snow, const StabilizeSettings& settings) {
  if (snow.last.converged || settings.tolerance <= 0.0f || snow.last.iterations == 0) return;
  char line[300];
  std::snprintf(line, sizeof line,
                "the snow did not settle within --max-iterations %d passes: it still moved more "
                "than --tolerance %.3g m (raise --max-iterations, or use less snow or coarser "
                "texels)",
                settings.max_iterations, double(settings.tolerance));
  log_warn(line);
}

std::vector<int32_t> enclosing_objects(const Scene& scene, const SnowMaps& maps) {
  std::vector<int32_t> result;
  if (scene.objects.size() < 2) return result;
  std::vector<Bounds> bounds;
  for (size_t o = 0; o < scene.objects.size(); ++o) bounds.push_back(object_bounds(scene, int(o)));
  const size_t texels = maps.grid.texels();
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const Bounds& b = bounds[o];
    const float slack = 1e-4f * glm::length(b.max - b.min);
    bool encloses = true;
    for (size_t k = 0; k < scene.objects.size() && encloses; ++k) {
      if (k == o || scene.objects[k].triangle_count == 0) continue;
      encloses = glm::all(glm::lessThanEqual(b.min, bounds[k].min + slack)) &&
                 glm::all(glm::greaterThanEqual(b.max, bounds[k].max - slack));
    }
    if (!encloses) continue;
    size_t tops = 0, over_something = 0;
    for (size_t t = 0; t < texels; ++t) {
      if (maps.object[t] != int32_t(o)) continue;
      ++tops;
      if (maps.layers > 1 && !std::isnan(maps.ground[texels + t])) ++over_something;
    }
    if (tops > 0 && 2 * over_something >= tops) result.push_back(int32_t(o));
  }
  return result;
}

void warn_if_sheltered(const Scene& scene, const SnowMaps& maps,
                       const std::vector<float>& coverage) {
  const std::vector<int32_t> enclosing = enclosing_objects(scene, maps);
  const auto is_enclosing = [&](int32_t o) {
    return std::find(enclosing.begin(), enclosing.end(), o) != enclosing.end();
  };
  const size_t texels = maps.grid.texels();
  size_t with_surface = 0, receiving = 0;
  // Columns each object tops: [o + 1] for object o (-1: none).
  std::vector<size_t> top_objects(scene.objects.size() + 1, 0);
  for (size_t t = 0; t < texels; ++t) {
    if (std::isnan(maps.ground[t])) continue;
    ++with_surface;
    const int32_t top = maps.object[t];
    ++top_objects[top >= 0 && size_t(top) < scene.objects.size() ? size_t(top) + 1 : 0];
    for (int l = 0; l < maps.layers; ++l) {
      const size_t k = size_t(l) * texels + t;
      if (coverage[k] > 0.5f && !is_enclosing(maps.object[k])) {
        ++receiving;
        break;
      }
    }
  }
  if (with_surface == 0 || double(receiving) > 0.05 * double(with_surface)) return;
  std::vector<std::pair<size_t, int32_t>> ranked;
  for (size_t k = 0; k < top_objects.size(); ++k) {
    if (top_objects[k] == 0) continue;
    // Enclosing objects first: they are the likely cause.
    const int32_t object = int32_t(k) - 1;
    ranked.push_back({top_objects[k] + (is_enclosing(object) ? texels : 0), object});
  }
  std::sort(ranked.rbegin(), ranked.rend());
  std::string names;
  for (size_t i = 0; i < ranked.size() && i < 3; ++i) {
    const int32_t o = ranked[i].second;
    const std::string name =
        o >= 0 && size_t(o) < scene.objects.size() ? scene.objects[size_t(o)].name : "?";
    names +=
        (i ? ", '" : "'") + name + "' (" + (is_enclosing(o) ? "encloses the scene, " : "") +
        "tops " +
        std::to_string(int(100.0 * double(top_objects[size_t(o + 1)]) / double(with_surface))) +
        "% of the map)";
  }
  log_warn("almost nothing receives snow (" + std::to_string(receiving) + " of " +
           std::to_string(with_surface) + " columns); sheltered by " + names +
           "; use --ignore for a sky dome or helper geometry");
}

void warn_no_patches(const SnowResult& snow, const PolygonizeSettings& settings) {
  float deepest = 0.0f;
  for (float d : snow.depth) {
    if (std::isfinite(d)) deepest = std::max(deepest, d);
  }
  char line[300];
  if (!(snow.volume > 0.0) || deepest <= 0.0f) {
    std::snprintf(line, sizeof line, "no snow patch came out: nothing in the scene holds snow");
  } else if (deepest < settings.min_thickness) {
    std::snprintf(line, sizeof line,
                  "no snow patch came out: the deepest snow is %.3g m, thinner than "
                  "--min-thickness %.3g m (lower it, or raise --depth)",
                  double(deepest), double(settings.min_thickness));
  } else {
    std::snprintf(line, sizeof line,
                  "no snow patch came out: every patch is smaller than --min-patch-area %.3g m^2 "
                  "(lower it for small models)",
                  double(settings.min_patch_area));
  }
  log_warn(line);
}

}  // namespace snow::app

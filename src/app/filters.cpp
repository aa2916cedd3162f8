#include "app/filters.h"

#include <fnmatch.h>

#include <algorithm>

#include "core/error.h"
#include "core/log.h"
#include "plan/rules.h"
#include "scene/enclosure.h"

namespace snow::app {

bool matches(const std::vector<std::string>& globs, const std::string& name,
             const std::string& node_path) {
  for (const std::string& glob : globs) {
    if (fnmatch(glob.c_str(), name.c_str(), 0) == 0 ||
        fnmatch(glob.c_str(), node_path.c_str(), 0) == 0) {
      return true;
    }
  }
  return false;
}

bool matches(const std::vector<std::string>& globs, const SceneObject& object) {
  return matches(globs, object.name, object.node_path);
}

bool matches(const std::vector<std::string>& globs, const SceneLines& lines) {
  return matches(globs, lines.name, lines.node_path);
}

void warn_unmatched(const Scene& scene, const std::vector<std::string>& globs, const char* flag,
                    bool with_lines) {
  for (const std::string& glob : globs) {
    const bool any =
        std::any_of(scene.objects.begin(), scene.objects.end(),
                    [&](const SceneObject& o) { return matches({glob}, o); }) ||
        (with_lines && std::any_of(scene.lines.begin(), scene.lines.end(),
                                   [&](const SceneLines& l) { return matches({glob}, l); }));
    if (!any) {
      log_warn(std::string(flag) + " '" + glob + "' matches no object" +
               (with_lines ? " or line" : ""));
    }
  }
}

namespace {

// The scene without the objects for which `drop(index, object)` is true
// (each is logged with `why`); `scene` itself when none is dropped. Its
// lines and motions pass through unchanged (without_geometry keeps them).
template <class Drop>
Scene without(Scene scene, Drop drop, const char* why) {
  bool any = false;
  for (size_t i = 0; i < scene.objects.size() && !any; ++i) any = drop(i, scene.objects[i]);
  if (!any) return scene;
  Scene out = without_geometry(scene);
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& object = scene.objects[i];
    if (drop(i, object)) {
      log_info("ignoring object '" + object.name + "' (" + why + ")");
      continue;
    }
    SceneObject copy = object;
    copy.first_triangle = uint32_t(out.triangle_count());
    const size_t begin = size_t(object.first_triangle) * 3,
                 end = begin + size_t(object.triangle_count) * 3;
    out.positions.insert(out.positions.end(), scene.positions.begin() + begin,
                         scene.positions.begin() + end);
    if (!scene.normals.empty())
      out.normals.insert(out.normals.end(), scene.normals.begin() + begin,
                         scene.normals.begin() + end);
    if (!scene.uvs.empty())
      out.uvs.insert(out.uvs.end(), scene.uvs.begin() + begin, scene.uvs.begin() + end);
    out.objects.push_back(copy);
  }
  for (const glm::vec3& p : out.positions) out.bounds.extend(p);
  if (out.positions.empty())
    throw InputError(std::string(why) + " removed every object of the scene");
  return out;
}

}  // namespace

Scene without_ignored(Scene scene, const std::vector<std::string>& ignore) {
  return without(
      std::move(scene), [&](size_t, const SceneObject& o) { return matches(ignore, o); },
      "--ignore");
}

Scene without_sky_enclosures(Scene scene, bool keep) {
  if (keep) return scene;
  const std::vector<int> found = find_sky_enclosures(scene, plan::kSkyEnclosureCover);
  if (found.empty()) return scene;
  std::vector<uint8_t> enclosure(scene.objects.size(), 0);
  for (int o : found) {
    enclosure[size_t(o)] = 1;
    log_warn("object '" + scene.objects[size_t(o)].name +
             "' encloses the scene from above (a sky dome or box): it neither receives nor "
             "shelters snow; --keep-enclosures keeps it");
  }
  return without(
      std::move(scene), [&](size_t i, const SceneObject&) { return enclosure[i] != 0; },
      "a sky enclosure");
}

std::vector<uint8_t> receiving_objects(const Scene& scene,
                                       const std::vector<std::string>& no_snow_on) {
  std::vector<uint8_t> receives(scene.objects.size(), 1);
  for (size_t i = 0; i < scene.objects.size(); ++i)
    receives[i] = !matches(no_snow_on, scene.objects[i]);
  return receives;
}

ObjectGrip object_grip(const Scene& scene, const std::vector<std::string>& slippery,
                       const std::vector<std::string>& rough) {
  ObjectGrip grip(scene.objects.size(), kGripNormal);
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const bool slides = matches(slippery, scene.objects[i]),
               holds = matches(rough, scene.objects[i]);
    if (slides && holds) {
      throw InputError("object '" + scene.objects[i].name +
                       "' is matched by both --slippery and --rough");
    }
    if (slides) grip[i] = kGripSlippery;
    if (holds) grip[i] = kGripRough;
  }
  return grip;
}

}  // namespace snow::app

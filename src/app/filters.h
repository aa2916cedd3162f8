#pragma once
// Object filters by name glob (--ignore, --no-snow-on), shared by the snow
// and preview commands. A glob matches an object's name or its node path
// (fnmatch(3) syntax: *, ?, [...]).
#include <cstdint>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "snow/cohesion.h"

namespace snow::app {

/// True when any of `globs` matches the object's name or node path.
bool matches(const std::vector<std::string>& globs, const SceneObject& object);
/// The same for glTF lines, and for any name and node path.
bool matches(const std::vector<std::string>& globs, const SceneLines& lines);
bool matches(const std::vector<std::string>& globs, const std::string& name,
             const std::string& node_path);

/// Warns, naming `flag`, for each glob that matches no object of `scene`
/// (nor, `with_lines`, any of its glTF lines).
void warn_unmatched(const Scene& scene, const std::vector<std::string>& globs, const char* flag,
                    bool with_lines = false);

/// The scene without the objects that match `ignore` (they neither receive
/// nor shelter; each is logged): `scene` itself when none is ignored (moved
/// in, not copied). Throws InputError when nothing is left.
Scene without_ignored(Scene scene, const std::vector<std::string>& ignore);

/// The scene without its sky enclosures (scene/enclosure.h, with the
/// planner's plan::kSkyEnclosureCover), each named in a warning; `scene`
/// itself when there are none or `keep` is set.
Scene without_sky_enclosures(Scene scene, bool keep);

/// Per object of `scene`, the grip of its surface (snow/cohesion.h):
/// kGripSlippery where a `slippery` glob matches, kGripRough where a `rough`
/// one does, else kGripNormal. Throws InputError naming an object that both
/// match.
ObjectGrip object_grip(const Scene& scene, const std::vector<std::string>& slippery,
                       const std::vector<std::string>& rough);

/// Per object of `scene`: 0 where a `no_snow_on` glob matches (it gets no
/// fresh snow but still shelters), else 1.
std::vector<uint8_t> receiving_objects(const Scene& scene,
                                       const std::vector<std::string>& no_snow_on);

}  // namespace snow::app

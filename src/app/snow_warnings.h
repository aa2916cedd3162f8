#pragma once
// The batch job's warnings about a scene and its result: each names the
// problem, the figures behind it and the option that helps.
#include <vector>

#include "mesh/polygonize.h"
#include "scene/scene.h"
#include "snow/accumulate.h"
#include "snow/maps.h"

namespace snow::app {

/// Warns when the fresh snow is deep against the scene's size. glTF units
/// are metres; a model made in other units (a building tile 1 unit wide)
/// gets snow out of scale.
void warn_if_out_of_scale(const Scene& scene, float fall_depth);

/// Warns when the scene lies so far from the origin that 32-bit floats (as
/// glTF stores them, and as the maps hold heights) step by more than a tenth
/// of the fresh snow's depth there: the snow's surface rounds that coarsely
/// (a georeferenced model, e.g. UTM northings of 5e6 m: floats 0.5 m apart).
void warn_if_imprecise(const Scene& scene, float fall_depth);

/// Warns when the fresh snow is more than plan::kDeepTexels texels deep
/// (maps far finer than its shapes need, at a cost in time); suggests the
/// map side that makes it plan::kAimTexels deep.
void warn_if_deep_in_texels(const SnowMaps& maps, float fall_depth);

/// Warns when the last step's stabilizing stopped at --max-iterations with the
/// snow still moving more than --tolerance: the snow shown is not at rest.
void warn_if_unsettled(const SnowResult& snow, const StabilizeSettings& settings);

/// Warns when the scene's figures (snow::frame_figures, plan::advise_frame)
/// say it is not in metres or not +Y up, naming the option that fixes it.
void warn_if_not_metres_y_up(const Scene& scene);

/// Objects that enclose the scene like a sky dome or a sky box: their bounds
/// hold every other object and in most columns they top there is another
/// surface below them (unlike a hilly terrain, which is also wide and tall).
/// Snow that lands on them lands on nothing the user wants snowed.
std::vector<int32_t> enclosing_objects(const Scene& scene, const SnowMaps& maps);

/// Warns when almost no map column receives snow on anything but an object
/// that encloses the whole scene, naming the objects that shelter most of the
/// map (a sky dome, a sky box or a lid-like helper is the usual cause: --ignore
/// them).
void warn_if_sheltered(const Scene& scene, const SnowMaps& maps,
                       const std::vector<float>& coverage);

/// Why no snow patch came out: nothing holds snow, the snow is thinner than
/// --min-thickness everywhere, or every patch is under --min-patch-area.
void warn_no_patches(const SnowResult& snow, const PolygonizeSettings& settings);

}  // namespace snow::app

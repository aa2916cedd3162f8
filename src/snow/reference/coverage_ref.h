#pragma once
// CPU reference of the coverage pass (snow/coverage.h), for tests.
#include <cmath>
#include <initializer_list>
#include <vector>

#include <glm/glm.hpp>

#include "scene/scene.h"
#include "snow/bvh.h"
#include "snow/maps.h"

namespace snow::reference {

/// Coverage per layer texel (the maps' layout) by ray casting: for every
/// texel centre with a surface, at height ground (+ depth when snow_depth is
/// given), the share of `directions` (unit, pointing down) along which the
/// ray towards the sky (-d) hits nothing higher than 1e-4 m (+1e-6 of the
/// height) above the point; 0 on a second sheet (second_sheet). Occluders: the scene's triangles
/// (BVH) and, with snow_depth, snow_surface_triangles(maps, *snow_depth). 0 where no surface.
/// Throws InputError when directions is empty or snow_depth has the wrong size.
std::vector<float> compute_coverage(const Scene& scene, const SnowMaps& maps,
                                    const std::vector<glm::vec3>& directions,
                                    const std::vector<float>* snow_depth = nullptr);

/// Metres: a surface less than this above a point at height y is the
/// point's own (a ray towards the sky that hits it there does not count).
inline float own_surface(float y) { return 1e-4f + 1e-6f * std::abs(y); }

/// Whether a receiver at height y on layer texel k (maps' layout) is a
/// second sheet of the surface above it: a surface of the maps lies over it
/// in its column no higher than 2 own_surface(y) (twice, for the peel's
/// rounding). It takes no snow: what falls there lies on the sheet above (a
/// cloth modelled as two sheets, a bridge laid just under a fold), which
/// the rays would count again, ignoring that sheet as the receiver's own.
inline bool second_sheet(const SnowMaps& maps, size_t k, float y) {
  const size_t texels = maps.grid.texels();
  if (k < texels) return false;  // layer 0
  const float above = maps.ground[k - texels];
  return !std::isnan(above) && !(above > y + 2.0f * own_surface(y));
}

/// Whether p sees the sky along d (unit, pointing down): the ray towards the
/// sky (-d) hits no triangle of the occluders (null ones are skipped) higher
/// than own_surface(p.y) above p. The reference's test, also the exact casts
/// of snow::CoverageRenderer's CPU methods.
bool sees_sky(std::initializer_list<const Bvh*> occluders, const glm::vec3& p, const glm::vec3& d);

/// How many of `directions` (unit, pointing down) see the sky from p: the
/// ray towards the sky (-d) hits no triangle of the occluders (null ones
/// are skipped) higher than own_surface(p.y) above p: sees_sky per direction.
int open_directions(std::initializer_list<const Bvh*> occluders, const glm::vec3& p,
                    const std::vector<glm::vec3>& directions);

/// The snow surface as triangles (a soup, 3 corners each), the rule the GPU
/// shadow pass (shaders/shadow_snow.vert) mirrors: per layer, a heightfield
/// through the texel centres at height ground + depth; quad (i, j) of corners
/// c00 = (i, j), c10 = (i+1, j), c11 = (i+1, j+1), c01 = (i, j+1) splits into
/// (c00, c10, c11) and (c00, c11, c01); a triangle exists when its three
/// corners have a surface on that layer, at least one has depth > 0, and
/// their heights differ by at most kSnowSurfaceCutTexels texels. Depth that
/// is NaN or negative counts as 0.
std::vector<glm::vec3> snow_surface_triangles(const SnowMaps& maps,
                                              const std::vector<float>& snow_depth);

}  // namespace snow::reference

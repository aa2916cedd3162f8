#pragma once
// Private to the peel stage (snow/peel.h): what its files share. Not for
// other code, which includes snow/peel.h.
//
//   snow/peel/peel.cpp           peel_layers: the checks, then the CPU or the
//                                GPU backend (peels_on_cpu)
//   snow/peel/grid.cpp           make_grid, scene_stats, estimate_memory,
//                                check_memory_budget, the settings' checks (no GL)
//   snow/peel/gpu.cpp            the GPU backend: depth-peeling passes
//                                (peel_on_gpu); time_depth_passes
//   snow/reference/peel_ref.cpp  the CPU backend: a vertical ray per texel
//                                (snow::reference::peel_layers; no GL)
#include <string>

#include "scene/scene.h"
#include "snow/maps.h"
#include "snow/peel.h"

namespace snow::peel {

/// Throws InputError for layers outside 1..64, a merge distance that is
/// negative or not finite, or a device other than auto, gpu and cpu.
void validate_settings(const PeelSettings& settings);

/// `m` (metres) as printf's %g, for messages.
std::string format_metres(double m);

/// The smallest 1, 2 or 5 times a power of ten that is >= x (a texel size
/// to suggest); x itself where it is not a finite positive number.
double nice_ceil(double x);

/// The GPU backend of peel_layers on checked settings and a non-empty grid
/// whose memory budget was checked: L+1 depth-peeling passes from straight
/// above (peel_layers' contract, without the overflow warning). Needs a
/// current GL context (or a gl::OnDemandContext). Throws InputError for a
/// side over GL_MAX_TEXTURE_SIZE or maps too large to read back, GLError.
SnowMaps peel_on_gpu(const Scene& scene, const MapGrid& grid, const PeelSettings& settings);

}  // namespace snow::peel

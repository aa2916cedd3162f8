// CoverageMethod::CpuRays: every (receiver, direction) pair cast exactly on
// the CPU cores, as the ray-cast reference (snow/reference/coverage_ref.h)
// casts them, with the last occluder of each direction tried first.
#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "core/log.h"
#include "core/parallel.h"
#include "snow/bvh.h"
#include "snow/coverage/internal.h"
#include "snow/maps.h"
#include "snow/reference/coverage_ref.h"

namespace snow::cov {

bool sees_sky_after(const Bvh& bvh, const Bvh* snow_bvh, const glm::vec3& p, const glm::vec3& up,
                    float t_min, uint32_t& last, uint32_t tried) {
  if (last != Bvh::kNone && last != tried && bvh.reaches(last, p, up, t_min, kOpenSky)) {
    return false;
  }
  const uint32_t hit = bvh.first_hit(p, up, t_min, kOpenSky);
  if (hit != Bvh::kNone) {
    last = hit;
    return false;
  }
  return !(snow_bvh && snow_bvh->occluded(p, up, t_min, kOpenSky));
}

void cast_rays_on_cpu(const Bvh& bvh, const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
                      const std::vector<float>* snow_depth, const std::vector<glm::uvec4>& recv,
                      const std::vector<uint32_t>& recv_index, std::vector<float>& coverage,
                      Progress& progress) {
  std::unique_ptr<Bvh> snow_bvh;
  if (snow_depth) {
    snow_bvh = std::make_unique<Bvh>(reference::snow_surface_triangles(maps, *snow_depth));
  }
  // Each chunk's receivers (neighbours along a row) are cast in turn:
  // reference::open_directions with the last occluder of each direction
  // tried first (sees_sky_after). A chunk holds at most kChunk receivers,
  // and there are at least 4 chunks per core where there are enough
  // receivers; a round takes at least 4 chunks per core, so that a few
  // thousand receivers still spread over the cores.
  constexpr size_t kChunk = 256, kRounds = 16;
  const size_t threads = default_threads();
  const size_t chunk = std::clamp(recv.size() / (4 * threads), size_t(8), kChunk);
  const auto cast_chunk = [&](size_t c) {
    std::vector<uint32_t> last(dirs.size(), Bvh::kNone);
    for (size_t r = c * chunk; r < std::min(recv.size(), (c + 1) * chunk); ++r) {
      const glm::vec3 p = receiver_point(maps.grid, recv[r]);
      int lit = 0;
      for (size_t k = 0; k < dirs.size(); ++k) {
        const glm::vec3 up = -dirs[k];
        if (!(up.y > 0.0f)) continue;  // as sees_sky
        const float t_min = reference::own_surface(p.y) / up.y;
        lit += sees_sky_after(bvh, snow_bvh.get(), p, up, t_min, last[k]);
      }
      coverage[recv_index[r]] = float(lit) / float(dirs.size());
    }
  };
  const size_t chunks = (recv.size() + chunk - 1) / chunk;
  const size_t per_round = std::max((chunks + kRounds - 1) / kRounds, 4 * threads);
  for (size_t first = 0; first < chunks; first += per_round) {
    parallel_for(std::min(per_round, chunks - first), [&](size_t c) { cast_chunk(first + c); });
    progress.update(double(dirs.size()) * double(first + per_round) / double(chunks));
  }
}

}  // namespace snow::cov

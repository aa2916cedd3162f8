// Stage 3: the snow stabilizer (the stage's contract and the map of its
// files: snow/stabilize.h). Where the passes run, and the one-off
// stabilize() on the GPU's Stabilizer.
#include <algorithm>
#include <vector>

#include "plan/rules.h"
#include "snow/stabilize.h"

namespace snow {

bool stabilizes_on_cpu(const StabilizeSettings& settings, StabilizerUse use,
                       const plan::GlFacts& gl) {
  return plan::stabilizer_on_cpu(settings.device, use, gl);
}

StabilizeResult stabilize(const SnowMaps& maps, std::vector<float>& depth,
                          const StabilizeSettings& settings) {
  Stabilizer stabilizer(maps, settings);
  stabilizer.set_depth(depth);
  StabilizeResult result = stabilizer.run();
  depth = stabilizer.depth();
  for (float& d : depth) d = std::max(d, 0.0f);
  return result;
}

}  // namespace snow

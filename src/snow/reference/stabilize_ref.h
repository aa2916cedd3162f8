#pragma once
// CPU reference of the stabilizer passes (snow/stabilize.h), for tests: the
// same outflow, gather, receiver, jump, scatter and apply passes as the GPU
// fragment passes, in the same order and with the same float math, on the
// cells of snow::stabilize_cells.
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "snow/maps.h"
#include "snow/stabilize.h"

namespace snow::reference {

/// Landing codes of the outflow pass besides a layer index (0..63).
constexpr uint8_t kCodeNone = 254;  // no flow in that direction
constexpr uint8_t kCodeVoid = 255;  // flow off the map or into the void below: lost
/// Receiver pointers of the routing passes besides a texel index.
constexpr uint32_t kPointerVoid = 0xffffffffu;

/// Neighbour direction n (0..7): column offset (kDirI[n], kDirJ[n]); 0..3 are
/// the edge neighbours (distance texel), 4..7 the diagonal ones (texel*sqrt2).
constexpr int kDirI[8] = {1, -1, 0, 0, 1, -1, 1, -1};
constexpr int kDirJ[8] = {0, 0, 1, -1, 1, 1, -1, -1};

/// The CPU twin of snow::Stabilizer (same contract, same passes, same float
/// math), plus access to single passes for tests.
class Stabilizer {
 public:
  /// Throws InputError like snow::Stabilizer.
  Stabilizer(const SnowMaps& maps, const StabilizeSettings& settings);

  void set_depth(const std::vector<float>& depth);
  void add_snow(const std::vector<float>& amount, float scale);
  /// Pending routing, then up to `passes` relaxation passes (early stop as
  /// on the GPU). volume and lost_volume are exact (double) sums.
  StabilizeResult iterate(int passes);
  StabilizeResult run() { return iterate(settings_.max_iterations); }

  const std::vector<float>& depth() const { return depth_; }
  double lost_volume() const;
  const std::vector<glm::vec4>& cells() const { return cells_; }

  // Single passes, for tests.
  /// Outflow: fills amount (8 per layer texel, metres) and code (8 per layer
  /// texel: landing layer, kCodeNone or kCodeVoid; kCodeNone where nothing
  /// moves) from the current depth.
  void outflow_pass(int stride = 1);
  /// Gather: depth -= own outflow, += neighbours' outflow landing here; lost
  /// += own outflow to kCodeVoid.
  void gather_pass(int stride = 1);
  /// Largest move (metres) of the last outflow pass.
  float residual() const;
  /// Routing (erosion until stable, receiver, jumps until every pointer
  /// reaches a terminal, scatter, apply); returns the erosion plus jump passes
  /// run. Adds the routed volume (m^3) to *routed_volume when given.
  int route(double* routed_volume = nullptr);

  const std::vector<float>& amount() const { return amount_; }
  const std::vector<uint8_t>& code() const { return code_; }
  const std::vector<uint32_t>& pointer() const { return pointer_; }

 private:
  int land(int i, int j, float h, float support, float rise, bool kept = false) const;
  int gap_at(int i, int j, float h) const;
  double snow_volume_of(const std::vector<float>& depth) const;
  size_t index(int l, int i, int j) const {
    return (size_t(l) * size_t(height_) + size_t(j)) * size_t(width_) + size_t(i);
  }

  StabilizeSettings settings_;
  StrideSchedule schedule_{settings_};
  int width_ = 0, height_ = 0, layers_ = 0;
  float texel_ = 0.0f;
  float distance_[8] = {};  // metres, per direction
  float rise_ = 0.0f;       // metres, kSurfaceContinuityTexels * texel
  std::vector<glm::vec4> cells_;
  std::vector<float> depth_;
  std::vector<float> lost_;  // metres lost per layer texel (accumulated at the source)
  std::vector<float> amount_;
  std::vector<uint8_t> code_;
  std::vector<uint32_t> pointer_;
  std::vector<float> stable_;  // metres, highest snow surface each texel can keep (routing)
  bool route_pending_ = false;
};

/// One-off CPU stabilize (same contract as snow::stabilize): a reference
/// Stabilizer run for max_iterations (or max_iterations_override when >= 0)
/// passes at most. Negative rounding residues are cleared in the output.
StabilizeResult stabilize(const SnowMaps& maps, std::vector<float>& depth,
                          const StabilizeSettings& settings, int max_iterations_override = -1);

}  // namespace snow::reference

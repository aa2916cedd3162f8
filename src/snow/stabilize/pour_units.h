#pragma once
// The pours of the piles of one deposit_piles call (snow/deposit.h): which
// terminals are poured together as one pile (internal to
// src/snow/stabilize).
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "snow/deposit.h"

namespace snow {

/// The pours of deposit_piles: its terminals, in its order, cut into units.
/// A unit of one terminal is poured as its own cone (Pourer::pour); a unit
/// of several, terminals under the open sky whose piles would overlap, as
/// one pile over all of them (Pourer::pour_group). Poured one by one, each
/// of those piles would spread over the others again: a line of terminals
/// at the foot of a slope covered its texels tens of times over, a cost
/// that grows with the cube of the map's side.
struct PourUnits {
  std::vector<uint32_t> terminals;  // in pour order, the terminals of a unit together
  std::vector<float> apex;          // per terminal: the apex height (m) of its lone cone
  std::vector<size_t> begin;        // unit u: terminals[begin[u], begin[u + 1])
  size_t units() const { return begin.size() - 1; }
};

/// Cuts `ordered` (deposit_piles' order) into units, each taking the place
/// of its first terminal in the order. PileGrouping::Wide: terminals under
/// the open sky whose lone cones (the cone at the repose angle on flat
/// ground that holds what arrived) are 8 texels wide or more and would
/// overlap, in plan and in height, share a unit, directly or through a
/// chain. PileGrouping::Pressed: terminals in neighbouring columns whose
/// ceilings continue (differ by less than the surface continuity's rise,
/// snow/column.h) share a unit, through chains, all with the same apex: the
/// pile spreads from the whole full gap at once, where poured one by one
/// each texel's pile crossed the gap again. PileGrouping::Lone: every
/// terminal a unit of its own.
PourUnits plan_pour_units(const glm::vec4* cells, const float* depth, const float* arrive,
                          const std::vector<uint32_t>& ordered, const DepositGrid& grid,
                          PileGrouping grouping);

}  // namespace snow

#pragma once
// Routed snow laid as piles (a step of the stabilizer, snow/stabilize.h). The
// routing sends the snow that cannot stay where it lies down a chain of
// receivers to a terminal, one texel, in one go: all the snow sliding off a
// roof's side arrives at a few texels at the foot of the wall, metres deep
// where a few decimetres fell. Spread by relaxation passes alone, such a spike
// takes thousands of passes to settle. Here each terminal's snow is poured
// instead: it forms a cone at the repose angle around the terminal, over the
// snow already lying there, whose volume is what arrived. The cone is a warm
// start that the relaxation then finishes, so it only has to be close: heights
// along the cheapest paths of repose slopes (Dijkstra from the terminal, each
// step costing distance * tan(repose) of the texel it leaves, as in the
// relaxation's rule), grown in order of the height at which the rising cone
// first covers a texel, twice: at the snow tops, then at the cone heights the
// first growth found (which gaps the surface lies in depends on its height).
// Under a ceiling (a table, an eave, a tree's tiers) a texel takes snow only up
// to kCeilingClearance under it: the cone fills the gap there and spreads on
// (snow sliding off a tree's tiers lands in the low gap under them; snow
// creeping under an eave collects in a hollow there, a spike a metre high on
// one texel, which the relaxation would spread a texel per pass). Texels that
// snow would slide off into the void take none, a pile covers at most 2^20
// texels, and the piles of one call at most twice the maps' layer texels
// (the terminals after that keep their snow, as before). Mass is exact: what
// the cone does not place stays on the terminal.
//
// Terminals under the open sky whose piles would overlap, each at least 8
// texels in radius, are poured as one pile (a line of them where snow slides
// off an eave, or fills a hollow): the upper envelope of a cone at each,
// apexes where each terminal's own cone would peak on flat ground, all raised
// by one height until the pile holds their snow together, grown from all of
// them at once. Poured one by one, each pile spreads over the others again:
// the growths cover the same texels tens of times, a cost that grows with
// the cube of the map's side where the grouped pile's grows with its square.
// Narrower piles are poured one by one as before (cheap, and they then come
// to the same rest whether the snow arrives at once or frame by frame).
// Snow pressed above its ceilings (pour_pressed_snow) is poured as one pile
// per full gap (the pressed texels in neighbouring columns under one
// continuous ceiling), all apexes at one height. What a group's pile does
// not place goes back to its terminals, each its share.
//
// Both stabilizers run this on the CPU after their routing (the GPU reads
// the depth and the scattered sums back and uploads the result), in the
// same order of the terminals, so they agree bit for bit. The order is the
// texel order, except on maps of 512 rows or more, which are cut into 8
// bands of rows: the terminals of the even bands first, then those of the
// odd ones, each band's in texel order. Two bands of a phase lie a band
// apart, so their piles rarely meet, and they are poured on all cores,
// with the same result (pouring serially is a large share of a large map's
// run).
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace snow {

struct DepositGrid {
  int width = 0, height = 0, layers = 0;
  float texel = 0.0f;  // metres
};

/// Pours arrive[k] (metres of depth; > 0 at the terminals, 0 elsewhere) as
/// a pile around each terminal k, in the order above, adding to depth. `cells`
/// are those of stabilize_cells (texels without a surface may be all zero),
/// all three arrays have grid.layers * width * height entries in the maps'
/// layout. Returns the number of terminals poured.
size_t deposit_piles(const glm::vec4* cells, float* depth, const float* arrive,
                     const DepositGrid& grid);
/// Which terminals of a deposit_piles call are poured as one pile.
enum class PileGrouping {
  Lone,     // every terminal its own pile (to compare)
  Wide,     // terminals under the open sky whose wide piles overlap (above)
  Pressed,  // terminals in neighbouring columns under one continuous ceiling
            // (pour_pressed_snow: the snow pressed out of one full gap)
};
struct DepositStats {
  size_t piles_in_parallel = 0;  // terminals poured by bands on several threads
  size_t groups = 0;             // piles poured over several terminals (grouped)
  size_t covered = 0;            // texels covered by all growths, each growth counting its own
};

/// The same with the terminals given (the texels where arrive > 0, in any
/// order), as the routing that filled arrive knows them. `threads`: the
/// most threads to pour on (0 = default_threads()); the result does not
/// depend on it. `grouping`: which terminals pour as one pile.
size_t deposit_piles(const glm::vec4* cells, float* depth, const float* arrive,
                     std::vector<uint32_t> terminals, const DepositGrid& grid, unsigned threads = 0,
                     DepositStats* stats = nullptr, PileGrouping grouping = PileGrouping::Wide);

/// Snow pressed above its ceiling: where snow lies more than `min_over`
/// metres above kCeilingClearance under its ceiling, the excess is taken
/// off and poured as a pile from that texel (in deposit_piles' order). The
/// relaxation squeezes such snow out one texel per pass, and where a whole
/// gap is full (2 m of snow drifting into a house through its door, up to
/// the ceiling) the pressure only diffuses, over thousands of passes, or
/// rocks back and forth between texels; the pile spreads through the full
/// gaps to the nearest room in one go. Both stabilizers call it at the same
/// checks (pressed_snow_due). Returns the piles that moved snow (a pile
/// with no room anywhere leaves its texel as it was and does not count).
size_t pour_pressed_snow(const glm::vec4* cells, float* depth, const DepositGrid& grid,
                         float min_over);

/// pour_pressed_snow looking only at the layer texels `under` (in any
/// order; only those with a surface under a ceiling can be pressed): the
/// same piles where `under` holds every pressed texel, without reading
/// every cell each call. The CPU stabilizer passes those of the tiles whose
/// depth changed since its last call (CpuStabilizer::pour_pressed).
size_t pour_pressed_snow(const glm::vec4* cells, float* depth, const DepositGrid& grid,
                         float min_over, const std::vector<uint32_t>& under);

/// The drain's routing (drain_due, snow/stabilize.h), after the erosion's
/// kept heights `stable`: the excess of every texel more than `min_excess`
/// (m) over its kept height runs down its path (the routing's receivers,
/// the neighbour that limits each texel's kept height), filling on the way
/// each texel's room (how far its free top may rise before that neighbour's
/// kept height plus the repose slope, or its ceiling, stops it), as a
/// stream fills the hollows on its way. What reaches the void is added to
/// `lost` at the texel it leaves from; what is left where a path ends
/// stays there. The same sums on every run (the paths are taken
/// sequentially, in order), so both stabilizers get the same depth bit for
/// bit. Returns the layer texels whose depth changed.
std::vector<uint32_t> spill_excess(const glm::vec4* cells, const float* stable, float* depth,
                                   float* lost, const DepositGrid& grid, float min_excess);

}  // namespace snow

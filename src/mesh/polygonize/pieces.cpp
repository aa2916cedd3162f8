// Decimation in pieces (PolygonizeSettings::piece_triangles): a large top,
// triangulated with cuts between strips of window columns (triangulate_top),
// is split along those cuts into runs of strips; each run is closed into a
// solid and decimated on its own core with the vertices at the seams locked,
// and the pieces are joined at their seam vertices into one closed solid.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <unordered_map>
#include <vector>

#include "core/parallel.h"
#include "mesh/polygonize/omesh.h"
#include "mesh/polygonize/steps.h"

namespace snow::poly {
namespace {

/// The top triangles of one piece of a large top, reindexed, with each
/// vertex's index in the whole top.
struct TopPiece {
  TopMesh top;
  std::vector<uint32_t> origin;
};

/// The triangles around each vertex of a mesh of nv vertices, in index
/// order: vertex v's are around[first[v], first[v + 1]) (one array, not a
/// vector per vertex).
struct Around {
  std::vector<uint32_t> first, around;
  Around(const std::vector<uint32_t>& tris, size_t nv) : first(nv + 1, 0), around(tris.size()) {
    for (uint32_t v : tris) ++first[v + 1];
    for (size_t v = 0; v < nv; ++v) first[v + 1] += first[v];
    std::vector<uint32_t> next(first.begin(), first.end() - 1);
    for (size_t c = 0; c < tris.size(); ++c) around[next[tris[c]]++] = uint32_t(c / 3);
  }
  const uint32_t* begin(size_t v) const { return around.data() + first[v]; }
  size_t count(size_t v) const { return first[v + 1] - first[v]; }
};

/// The top triangles of each piece (pieces.top[t] of triangle t, below
/// `count`), and its bottom ones where the bottom has its own. Where a
/// piece's top triangles around a vertex form several fans (the outline
/// comes in between them), each fan gets a vertex of its own, so every piece
/// is a manifold mesh; they share the origin. A bottom triangle takes the
/// vertices of its piece's top there (the bottom is a coarsening of the
/// top); empty where its piece's top has no fan or several at a corner of
/// it (never seen: the outline's cells are whole in both).
std::vector<TopPiece> split_top(const TopMesh& top, const Pieces& pieces, size_t count) {
  const size_t nv = top.positions.size();
  const Around tops(top.tris, nv), bottoms(top.bottom, nv);
  std::vector<TopPiece> out(count);
  std::vector<uint32_t> local(top.tris.size());           // piece vertex of each corner
  std::vector<uint32_t> local_bottom(top.bottom.size());  // the same for the bottom's
  std::vector<uint32_t> fan;
  struct FanVertex {
    uint32_t root, piece, vertex;  // fan root (an index around v), its piece and piece vertex
  };
  std::vector<FanVertex> fan_vertex;
  for (size_t v = 0; v < nv; ++v) {
    // The triangles around v of each piece, joined into fans by the edges
    // (v, w) they share.
    const uint32_t* const around = tops.begin(v);
    const size_t around_count = tops.count(v);
    fan.resize(around_count);
    std::iota(fan.begin(), fan.end(), 0u);
    const auto root = [&](uint32_t a) {
      while (fan[a] != a) a = fan[a] = fan[fan[a]];
      return a;
    };
    for (size_t a = 0; a < around_count; ++a) {
      for (size_t b = a + 1; b < around_count; ++b) {
        const uint32_t ta = around[a], tb = around[b];
        if (pieces.top[ta] != pieces.top[tb]) continue;
        int shared = 0;
        for (int ea = 0; ea < 3; ++ea) {
          for (int eb = 0; eb < 3; ++eb) {
            shared +=
                int(top.tris[3 * size_t(ta) + size_t(ea)] == top.tris[3 * size_t(tb) + size_t(eb)]);
          }
        }
        if (shared >= 2) fan[root(uint32_t(a))] = root(uint32_t(b));
      }
    }
    fan_vertex.clear();
    for (size_t a = 0; a < around_count; ++a) {
      const uint32_t p = pieces.top[around[a]];
      TopPiece& part = out[p];
      const uint32_t r = root(uint32_t(a));
      auto it = std::find_if(fan_vertex.begin(), fan_vertex.end(),
                             [&](const FanVertex& fv) { return fv.root == r; });
      if (it == fan_vertex.end()) {
        fan_vertex.push_back({r, p, uint32_t(part.origin.size())});
        it = fan_vertex.end() - 1;
        part.origin.push_back(uint32_t(v));
        part.top.positions.push_back(top.positions[v]);
        part.top.sample.push_back(top.sample[v]);
      }
      const size_t t = around[a];
      for (size_t e = 0; e < 3; ++e) {
        if (top.tris[3 * t + e] == v) local[3 * t + e] = it->vertex;
      }
    }
    // A bottom triangle at v takes the vertex of its piece's one fan there.
    for (size_t k = 0; k < bottoms.count(v); ++k) {
      const uint32_t b = bottoms.begin(v)[k], p = pieces.bottom[b];
      const FanVertex* found = nullptr;
      for (const FanVertex& fv : fan_vertex) {
        if (fv.piece != p) continue;
        if (found) return {};
        found = &fv;
      }
      if (!found) return {};
      for (size_t e = 0; e < 3; ++e) {
        if (top.bottom[3 * size_t(b) + e] == v) local_bottom[3 * size_t(b) + e] = found->vertex;
      }
    }
  }
  for (size_t t = 0; t < pieces.top.size(); ++t) {
    for (size_t e = 0; e < 3; ++e) out[pieces.top[t]].top.tris.push_back(local[3 * t + e]);
  }
  for (size_t t = 0; t < pieces.bottom.size(); ++t) {
    for (size_t e = 0; e < 3; ++e) {
      out[pieces.bottom[t]].top.bottom.push_back(local_bottom[3 * t + e]);
    }
  }
  return out;
}

}  // namespace

Pieces top_pieces(const TopMesh& top, const PatchField& f, const MapGrid& grid, int cut,
                  size_t& pieces) {
  const auto strips_of = [&](const std::vector<uint32_t>& tris) {
    std::vector<uint32_t> strip(tris.size() / 3);
    for (size_t t = 0; t < strip.size(); ++t) {
      double x = 0.0;
      for (int e = 0; e < 3; ++e) x += top.positions[tris[3 * t + size_t(e)]].x;
      const double column = (x / 3.0 - double(grid.origin.x)) / double(grid.texel) - 0.5 - f.i0;
      strip[t] = uint32_t(std::clamp(std::floor(column / double(cut)), 0.0, 1e9));
    }
    return strip;
  };
  Pieces out{strips_of(top.tris), strips_of(top.bottom)};
  const size_t n = out.top.size();
  size_t strips = 0;
  for (uint32_t k : out.top) strips = std::max(strips, size_t(k) + 1);
  for (uint32_t k : out.bottom) strips = std::max(strips, size_t(k) + 1);
  std::vector<size_t> count(strips, 0);
  for (uint32_t k : out.top) ++count[k];
  std::vector<uint32_t> run(strips, 0);
  uint32_t p = 0;
  size_t before = 0, used = 0;
  for (size_t k = 0; k < strips; ++k) {
    if (count[k] > 0 && used > 0 && p + 1 < pieces && before * pieces >= (p + 1) * n) ++p;
    run[k] = p;
    if (count[k] > 0) used = size_t(p) + 1;
    before += count[k];
  }
  pieces = used;
  for (uint32_t& k : out.top) k = run[k];
  for (uint32_t& k : out.bottom) k = run[k];
  return out;
}

bool build_decimated_in_pieces(const TopMesh& top, const Pieces& pieces, size_t count,
                               const PatchField& field, float bottom_offset, double max_error,
                               Solid& out) {
  const std::vector<TopPiece> parts = split_top(top, pieces, count);
  if (parts.empty()) return false;
  std::vector<uint8_t> users(top.positions.size(), 0);
  for (const TopPiece& part : parts) {
    for (uint32_t v : part.origin) users[v] = uint8_t(std::min(users[v] + 1, 2));
  }
  std::vector<OMesh> meshes(parts.size());
  std::vector<OpenMesh::FPropHandleT<bool>> tops(parts.size());
  // Per piece vertex: 2 * top index (+ 1 for a bottom vertex) of a seam
  // vertex, -1 for the others; a property, so it survives the garbage
  // collection.
  std::vector<OpenMesh::VPropHandleT<int64_t>> keys(parts.size());
  std::vector<uint8_t> built(parts.size(), 0);
  parallel_for(parts.size(), [&](size_t p) {
    OMesh& m = meshes[p];
    m.add_property(tops[p]);
    m.add_property(keys[p]);
    SolidVertices solid;
    if (build_solid(parts[p].top, field, bottom_offset, m, tops[p], &solid) > 0) return;
    m.request_vertex_status();
    for (auto v : m.vertices()) m.property(keys[p], v) = -1;
    std::vector<OMesh::VertexHandle> seam;
    for (size_t v = 0; v < solid.top.size(); ++v) {
      const int64_t o = int64_t(parts[p].origin[v]);
      if (users[size_t(o)] < 2) continue;
      m.property(keys[p], solid.top[v]) = 2 * o;
      seam.push_back(solid.top[v]);
      if (solid.bottom[v].is_valid() && solid.bottom[v] != solid.top[v]) {
        m.property(keys[p], solid.bottom[v]) = 2 * o + 1;
        seam.push_back(solid.bottom[v]);
      }
    }
    // The seam vertices and their neighbours stay, so the faces at the seam
    // stay as they are: a collapse next to the seam could join two seam
    // vertices across a third, from both sides, into an edge of four faces.
    for (auto v : seam) {
      m.status(v).set_locked(true);
      for (auto w : m.vv_range(v)) m.status(w).set_locked(true);
    }
    decimate(m, max_error);
    built[p] = 1;
  });
  if (std::count(built.begin(), built.end(), 0) > 0) return false;
  std::unordered_map<int64_t, uint32_t> seam;
  for (size_t p = 0; p < parts.size(); ++p) {
    const OMesh& m = meshes[p];
    std::vector<uint32_t> to(m.n_vertices());
    for (auto v : m.vertices()) {
      const int64_t key = m.property(keys[p], v);
      if (key < 0) {
        to[size_t(v.idx())] = add_point(out, m.point(v));
        continue;
      }
      const auto [it, fresh] = seam.try_emplace(key, 0u);
      if (fresh) it->second = add_point(out, m.point(v));
      to[size_t(v.idx())] = it->second;
    }
    add_faces(out, m, tops[p], to);
  }
  return true;
}

}  // namespace snow::poly

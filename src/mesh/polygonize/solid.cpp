// Closing a patch's top into a solid: the bottom lies bottom_offset under
// the ground and shares the top's outline vertices, so top and bottom form a
// closed 2-manifold by construction; then decimation (decimate.cpp) and the
// TriMesh that polygonize returns.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "mesh/polygonize/omesh.h"
#include "mesh/polygonize/steps.h"

namespace snow::poly {

size_t build_solid(const TopMesh& top, const PatchField& f, float bottom_offset, OMesh& mesh,
                   OpenMesh::FPropHandleT<bool> is_top, SolidVertices* vertices) {
  std::vector<OMesh::VertexHandle> top_v(top.positions.size());
  std::vector<OMesh::VertexHandle> bottom_v(top.positions.size());
  // Room for the whole solid at once, so that OpenMesh's arrays do not grow
  // an element at a time (edges: 3 per 2 faces).
  const size_t inner =
      size_t(std::count_if(top.sample.begin(), top.sample.end(), [](int32_t a) { return a >= 0; }));
  const std::vector<uint32_t>& bottom_tris = top.bottom.empty() ? top.tris : top.bottom;
  const size_t faces = (top.tris.size() + bottom_tris.size()) / 3;
  mesh.reserve(top.positions.size() + inner, faces * 3 / 2 + 3, faces);
  for (size_t v = 0; v < top.positions.size(); ++v) {
    const glm::dvec3& p = top.positions[v];
    top_v[v] = mesh.add_vertex(OMesh::Point(p.x, p.y, p.z));
  }
  // Where the bottom has triangles of its own, a bottom vertex is made for
  // the inner vertices they use only.
  std::vector<uint8_t> on_bottom(top.bottom.empty() ? 0 : top.positions.size(), 0);
  for (uint32_t v : top.bottom) on_bottom[v] = 1;
  for (size_t v = 0; v < top.positions.size(); ++v) {
    if (top.sample[v] < 0) {
      bottom_v[v] = top_v[v];  // outline: shared by top and bottom
    } else if (top.bottom.empty() || on_bottom[v]) {
      const glm::dvec3& p = top.positions[v];
      const double y = double(f.g[size_t(top.sample[v])]) - double(bottom_offset);
      bottom_v[v] = mesh.add_vertex(OMesh::Point(p.x, y, p.z));
    }
  }
  size_t failed = 0;
  const auto add = [&](const std::vector<OMesh::VertexHandle>& corner, uint32_t a, uint32_t b,
                       uint32_t c, bool face_top) {
    const auto face = mesh.add_face(corner[a], corner[b], corner[c]);
    if (face.is_valid()) mesh.property(is_top, face) = face_top;
    failed += size_t(!face.is_valid());
  };
  for (size_t t = 0; t < top.tris.size(); t += 3) {
    const auto a = top.tris[t], b = top.tris[t + 1], c = top.tris[t + 2];
    add(top_v, a, b, c, true);
    if (top.bottom.empty()) add(bottom_v, a, c, b, false);
  }
  for (size_t t = 0; t < top.bottom.size(); t += 3) {
    add(bottom_v, top.bottom[t], top.bottom[t + 2], top.bottom[t + 1], false);
  }
  if (vertices) {
    vertices->top = std::move(top_v);
    vertices->bottom = std::move(bottom_v);
  }
  return failed;
}

void add_faces(Solid& solid, const OMesh& m, OpenMesh::FPropHandleT<bool> is_top,
               const std::vector<uint32_t>& to) {
  for (auto f : m.faces()) {
    for (auto v : m.fv_range(f)) solid.tris.push_back(to[size_t(v.idx())]);
    solid.top.push_back(uint8_t(m.property(is_top, f)));
  }
}

uint32_t add_point(Solid& solid, const OMesh::Point& p) {
  solid.positions.emplace_back(p[0], p[1], p[2]);
  return uint32_t(solid.positions.size() - 1);
}

size_t build_decimated_solid(const TopMesh& top, const PatchField& field, float bottom_offset,
                             double max_error, Solid& out) {
  OMesh mesh;
  OpenMesh::FPropHandleT<bool> is_top;
  mesh.add_property(is_top);
  const size_t failed = build_solid(top, field, bottom_offset, mesh, is_top);
  if (failed > 0) return failed;
  if (max_error > 0.0) decimate(mesh, max_error);
  // All of the mesh, its vertices unshared with what `out` holds.
  std::vector<uint32_t> to(mesh.n_vertices());
  for (auto v : mesh.vertices()) to[size_t(v.idx())] = add_point(out, mesh.point(v));
  add_faces(out, mesh, is_top, to);
  return 0;
}

double signed_volume(const TriMesh& m) {
  double v6 = 0.0;
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const glm::dvec3 a = m.positions[m.indices[t]];
    const glm::dvec3 b = m.positions[m.indices[t + 1]];
    const glm::dvec3 c = m.positions[m.indices[t + 2]];
    v6 += glm::dot(a, glm::cross(b, c));
  }
  return v6 / 6.0;
}

bool degenerate_face(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  // As the reader sees the corners: rounded to float.
  const glm::dvec3 pa{glm::vec3(a)}, pb{glm::vec3(b)}, pc{glm::vec3(c)};
  const glm::dvec3 e0 = pb - pa, e1 = pc - pa, e2 = pc - pb;
  const glm::dvec3 cross = glm::cross(e0, e1);
  const double longest2 = std::max({glm::dot(e0, e0), glm::dot(e1, e1), glm::dot(e2, e2)});
  return glm::dot(cross, cross) <= kDegenerateHeight * kDegenerateHeight * longest2 * longest2;
}

size_t flip_degenerate_faces(Solid& solid) {
  const auto key = [](uint32_t a, uint32_t b) { return uint64_t(a) << 32 | b; };
  const auto corner = [&](size_t f, int e) { return solid.tris[3 * f + size_t(e)]; };
  const auto degenerate = [&](size_t f) {
    return degenerate_face(solid.positions[corner(f, 0)], solid.positions[corner(f, 1)],
                           solid.positions[corner(f, 2)]);
  };
  const size_t faces = solid.tris.size() / 3;
  std::vector<size_t> todo;
  for (size_t f = 0; f < faces; ++f) {
    if (degenerate(f)) todo.push_back(f);
  }
  if (todo.empty()) return 0;
  std::unordered_map<uint64_t, size_t> face_of;  // directed edge -> its face
  for (size_t f = 0; f < faces; ++f) {
    for (int e = 0; e < 3; ++e) face_of[key(corner(f, e), corner(f, (e + 1) % 3))] = f;
  }
  size_t left = 0;
  for (size_t round = 0; round < 4 && !todo.empty(); ++round) {
    std::vector<size_t> again;
    for (const size_t f : todo) {
      if (!degenerate(f)) continue;
      // The longest edge u -> v, the third corner x; the face across it
      // (v, u, w) becomes, with this one, (u, w, x) and (w, v, x).
      int longest = 0;
      double length = -1.0;
      for (int e = 0; e < 3; ++e) {
        const glm::dvec3 d =
            solid.positions[corner(f, (e + 1) % 3)] - solid.positions[corner(f, e)];
        if (glm::dot(d, d) > length) {
          length = glm::dot(d, d);
          longest = e;
        }
      }
      const uint32_t u = corner(f, longest), v = corner(f, (longest + 1) % 3),
                     x = corner(f, (longest + 2) % 3);
      const auto across = face_of.find(key(v, u));
      if (across == face_of.end()) {
        again.push_back(f);
        continue;
      }
      const size_t g = across->second;
      int at = 0;
      while (corner(g, at) != v) ++at;
      const uint32_t w = corner(g, (at + 2) % 3);
      if (w == x || face_of.count(key(w, x)) || face_of.count(key(x, w))) {
        again.push_back(f);
        continue;
      }
      for (const size_t h : {f, g}) {
        for (int e = 0; e < 3; ++e) face_of.erase(key(corner(h, e), corner(h, (e + 1) % 3)));
      }
      const uint32_t first[3] = {u, w, x}, second[3] = {w, v, x};
      std::copy_n(first, 3, solid.tris.begin() + ptrdiff_t(3 * f));
      std::copy_n(second, 3, solid.tris.begin() + ptrdiff_t(3 * g));
      solid.top[f] = solid.top[g] = uint8_t(solid.top[f] && solid.top[g]);
      for (const size_t h : {f, g}) {
        for (int e = 0; e < 3; ++e) face_of[key(corner(h, e), corner(h, (e + 1) % 3))] = h;
        if (degenerate(h)) again.push_back(h);
      }
    }
    todo = std::move(again);
  }
  for (const size_t f : todo) left += degenerate(f);
  return left;
}

TriMesh to_trimesh(const Solid& solid, bool top_only) {
  TriMesh out;
  std::vector<int64_t> remap(solid.positions.size(), -1);
  for (size_t f = 0; f < solid.top.size(); ++f) {
    if (top_only && !solid.top[f]) continue;
    for (size_t e = 0; e < 3; ++e) {
      const size_t vi = solid.tris[3 * f + e];
      if (remap[vi] < 0) {
        remap[vi] = int64_t(out.positions.size());
        out.positions.emplace_back(solid.positions[vi]);
      }
      out.indices.push_back(uint32_t(remap[vi]));
    }
  }
  // Vertex normals: the faces' unit normals weighted by their angle at the
  // vertex (Thuermer and Wuethrich 1998), so that they do not depend on how
  // the decimation cut the surface into triangles. A vertex of the top (the
  // outline's included) takes the top's faces only: the bottom lies hidden
  // under the support, and the outline's normals would otherwise tilt the
  // shading of every large top triangle that reaches the outline.
  std::vector<uint8_t> on_top(out.positions.size(), 0);
  {
    size_t t = 0;
    for (size_t f = 0; f < solid.top.size(); ++f) {
      if (top_only && !solid.top[f]) continue;
      if (solid.top[f]) {
        for (int e = 0; e < 3; ++e) on_top[out.indices[t + size_t(e)]] = 1;
      }
      t += 3;
    }
  }
  std::vector<glm::dvec3> normals(out.positions.size(), glm::dvec3(0.0));
  {
    size_t t = 0;
    for (size_t f = 0; f < solid.top.size(); ++f) {
      if (top_only && !solid.top[f]) continue;
      const glm::dvec3 p[3] = {out.positions[out.indices[t]], out.positions[out.indices[t + 1]],
                               out.positions[out.indices[t + 2]]};
      const glm::dvec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
      const double length = glm::length(n);
      for (int e = 0; e < 3 && length > 0.0; ++e) {
        const uint32_t v = out.indices[t + size_t(e)];
        if (on_top[v] && !solid.top[f]) continue;
        const glm::dvec3 u = p[(e + 1) % 3] - p[e], w = p[(e + 2) % 3] - p[e];
        const double lu = glm::length(u), lw = glm::length(w);
        if (lu <= 0.0 || lw <= 0.0) continue;
        const double angle = std::acos(std::clamp(glm::dot(u, w) / (lu * lw), -1.0, 1.0));
        normals[v] += n * (angle / length);
      }
      t += 3;
    }
  }
  out.normals.reserve(normals.size());
  out.uvs.reserve(normals.size());
  for (size_t v = 0; v < normals.size(); ++v) {
    const double len = glm::length(normals[v]);
    out.normals.push_back(len > 0.0 ? glm::vec3(normals[v] / len) : glm::vec3(0, 1, 0));
    out.uvs.emplace_back(out.positions[v].x, out.positions[v].z);
  }
  return out;
}

}  // namespace snow::poly

namespace snow::poly {

namespace {

// An outline edge of a solid: u -> v as its top face has it.
struct OutlineEdge {
  uint32_t u = 0, v = 0;
};

// The edges of `solid` that one top face and one bottom face share.
std::vector<OutlineEdge> outline_edges(const Solid& solid) {
  struct Use {
    uint32_t u = 0, v = 0;
    int top = 0, bottom = 0;
  };
  std::vector<std::pair<uint64_t, Use>> uses;  // keyed by the (smaller, larger) vertex pair
  uses.reserve(solid.tris.size());
  for (size_t t = 0; t < solid.top.size(); ++t) {
    for (int e = 0; e < 3; ++e) {
      const uint32_t u = solid.tris[3 * t + size_t(e)], v = solid.tris[3 * t + size_t(e + 1) % 3];
      const uint64_t key = uint64_t(std::min(u, v)) << 32 | std::max(u, v);
      uses.push_back({key, solid.top[t] ? Use{u, v, 1, 0} : Use{0, 0, 0, 1}});
    }
  }
  std::sort(uses.begin(), uses.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<OutlineEdge> out;
  for (size_t k = 0; k < uses.size();) {
    Use sum;
    size_t end = k;
    for (; end < uses.size() && uses[end].first == uses[k].first; ++end) {
      const Use& e = uses[end].second;
      if (e.top) {
        sum.u = e.u;
        sum.v = e.v;
      }
      sum.top += e.top;
      sum.bottom += e.bottom;
    }
    if (sum.top == 1 && sum.bottom == 1) out.push_back({sum.u, sum.v});
    k = end;
  }
  return out;
}

}  // namespace

void add_lips(Solid& solid, const PatchField& f, float texel, const glm::vec2& origin,
              float overhang, const Cornice& cornice) {
  if (!(overhang > 0.0f || cornice.length > 0.0f) || f.drop_edge.empty()) return;
  const glm::dvec2 downwind(cornice.direction);
  const size_t faces = solid.top.size();
  const std::vector<OutlineEdge> outline = outline_edges(solid);
  // The outline vertices at a free edge, their outward direction (x, z) and
  // how far they reach out.
  const size_t n = solid.positions.size();
  std::vector<glm::dvec2> out(n, glm::dvec2(0.0));
  std::vector<uint8_t> on_outline(n, 0);
  for (const OutlineEdge& e : outline) {
    const glm::dvec3 d = solid.positions[e.v] - solid.positions[e.u];
    const glm::dvec2 away(-d.z, d.x);  // the top lies to the left of u -> v seen from above
    out[e.u] += away;
    out[e.v] += away;
    on_outline[e.u] = on_outline[e.v] = 1;
  }
  // The thickness near a point: the largest at free-edge members within a
  // sample (0 where none is near: not a free edge), and whether one of
  // them drops onto a surface (not off the scene).
  struct Edge {
    float s = 0.0f;
    bool over_surface = false;
  };
  const auto edge_near = [&](const glm::dvec3& p) {
    const int ci = int(std::floor((p.x - double(origin.x)) / double(texel))) - f.i0;
    const int cj = int(std::floor((p.z - double(origin.y)) / double(texel))) - f.j0;
    Edge e;
    for (int j = cj - 1; j <= cj + 1; ++j) {
      for (int i = ci - 1; i <= ci + 1; ++i) {
        if (i < 0 || j < 0 || i >= f.w || j >= f.h) continue;
        const size_t a = f.at(i, j);
        if (!f.drop_edge[a]) continue;
        e.s = std::max(e.s, f.s[a]);
        e.over_surface |= f.drop_edge[a] == kDropToSurface;
      }
    }
    return e;
  };
  double volume_before = 0.0;  // m^3 enclosed before the lips
  for (size_t t = 0; t < faces; ++t) {
    const glm::dvec3 a = solid.positions[solid.tris[3 * t]],
                     b = solid.positions[solid.tris[3 * t + 1]],
                     c = solid.positions[solid.tris[3 * t + 2]];
    volume_before += glm::dot(a, glm::cross(b, c)) / 6.0;
  }
  std::vector<uint32_t> lip(n, UINT32_MAX);  // the top's copy of each outline vertex that moves
  for (size_t v = 0; v < n; ++v) {
    if (!on_outline[v]) continue;
    const double length = glm::length(out[v]);
    const Edge edge = edge_near(solid.positions[v]);
    const float s = edge.s;
    if (!(length > 0.0)) continue;
    const glm::dvec2 dir = out[v] / length;
    const double lip_reach = std::min(double(overhang), double(kOverhangShare) * double(s));
    const double lee = edge.over_surface ? std::max(0.0, glm::dot(dir, downwind)) : 0.0;
    const double reach = std::max(
        lip_reach, std::min(double(cornice.length) * lee, double(kCorniceShare) * double(s)));
    if (!(reach > 0.0)) continue;
    lip[v] = uint32_t(solid.positions.size());
    solid.positions.push_back(solid.positions[v] + glm::dvec3(dir.x * reach,
                                                              0.5 * std::max(lip_reach, 0.0),
                                                              dir.y * reach));
  }
  for (size_t t = 0; t < faces; ++t) {
    if (!solid.top[t]) continue;
    for (int e = 0; e < 3; ++e) {
      uint32_t& v = solid.tris[3 * t + size_t(e)];
      if (lip[v] != UINT32_MAX) v = lip[v];
    }
  }
  // The band under the lip: per outline edge u -> v (as the top had it), the
  // quad v' u' u v, a triangle where one end does not move.
  for (const OutlineEdge& e : outline) {
    const uint32_t u2 = lip[e.u] != UINT32_MAX ? lip[e.u] : e.u;
    const uint32_t v2 = lip[e.v] != UINT32_MAX ? lip[e.v] : e.v;
    const auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
      solid.tris.insert(solid.tris.end(), {a, b, c});
      solid.top.push_back(0);
    };
    if (u2 != e.u) add(v2, u2, e.u);
    if (v2 != e.v) add(v2, e.u, e.v);
  }
  // The lip's snow comes off the top (as it creeps out over the edge): the
  // top's other vertices go down by the lip's volume over the top's plan
  // area, so the solid holds what it held.
  const auto volume = [&] {
    double v6 = 0.0;
    for (size_t t = 0; t < solid.top.size(); ++t) {
      const glm::dvec3 a = solid.positions[solid.tris[3 * t]],
                       b = solid.positions[solid.tris[3 * t + 1]],
                       c = solid.positions[solid.tris[3 * t + 2]];
      v6 += glm::dot(a, glm::cross(b, c));
    }
    return v6 / 6.0;
  };
  std::vector<uint8_t> lowered(solid.positions.size(), 0);
  double plan_area = 0.0;
  for (size_t t = 0; t < faces; ++t) {
    if (!solid.top[t]) continue;
    const glm::dvec3 a = solid.positions[solid.tris[3 * t]],
                     b = solid.positions[solid.tris[3 * t + 1]],
                     c = solid.positions[solid.tris[3 * t + 2]];
    plan_area += 0.5 * std::abs(glm::cross(b - a, c - a).y);
    for (int e = 0; e < 3; ++e) {
      const uint32_t v = solid.tris[3 * t + size_t(e)];
      if (v < n && !on_outline[v]) lowered[v] = 1;
    }
  }
  const double added = volume() - volume_before;
  if (plan_area > 0.0 && added > 0.0) {
    const double drop = added / plan_area;
    for (size_t v = 0; v < lowered.size(); ++v) {
      if (lowered[v]) solid.positions[v].y -= drop;
    }
  }
}

}  // namespace snow::poly

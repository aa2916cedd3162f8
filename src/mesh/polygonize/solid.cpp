// Closing a patch's top into a solid: the bottom lies bottom_offset under
// the ground and shares the top's outline vertices, so top and bottom form a
// closed 2-manifold by construction; then decimation (decimate.cpp) and the
// TriMesh that polygonize returns.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
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

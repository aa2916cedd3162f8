// Part of the glTF loader (see scene/gltf/internal.h): meshes and primitives
// (glTF 2.0 section 3.7.2) decoded once in mesh space, their topologies
// (3.7.2.1) expanded to triangle lists, and every instance's triangles put
// into the scene in world space, re-wound where the instance is mirrored.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>
#include <unordered_map>

#include "core/log.h"
#include "core/parallel.h"
#include "scene/gltf/internal.h"

namespace snow::gltf {
namespace {

const char* const kModeNames[] = {"POINTS",    "LINES",          "LINE_LOOP",   "LINE_STRIP",
                                  "TRIANGLES", "TRIANGLE_STRIP", "TRIANGLE_FAN"};

// Vertices or triangles per task of the loops that put a primitive's
// triangles into the scene.
constexpr size_t kLoadChunk = size_t(1) << 15;

/// Drops vertices that no element of `elements` (g's triangles or segments)
/// uses (primitives often index a small part of a vertex array shared with
/// others), so instances transform only these.
void compact_vertices(PrimitiveGeometry& g, std::vector<uint32_t>& elements) {
  const size_t vertex_count = g.positions.size();
  if (elements.size() >= vertex_count * 2) {
    // Usually every vertex is used: check before building a remap.
    std::vector<uint8_t> used(vertex_count, 0);
    for (uint32_t i : elements) used[i] = 1;
    if (std::find(used.begin(), used.end(), 0) == used.end()) return;
  }
  std::vector<uint32_t> remap(vertex_count, UINT32_MAX);
  uint32_t next = 0;
  for (uint32_t& i : elements) {
    if (remap[i] == UINT32_MAX) remap[i] = next++;
    i = remap[i];
  }
  auto gather = [&](auto& values) {
    if (values.empty()) return;
    std::remove_reference_t<decltype(values)> out(next);
    for (size_t v = 0; v < vertex_count; ++v)
      if (remap[v] != UINT32_MAX) out[remap[v]] = values[v];
    values = std::move(out);
  };
  gather(g.positions);
  gather(g.normals);
  gather(g.uvs);
}

}  // namespace

const json& GltfLoader::primitives_of(int mesh) const {
  const std::string what = mesh_label(mesh);
  const json& object = element(meshes(), uint64_t(mesh), what);
  const json* primitives = member(object, "primitives");
  if (!primitives || !primitives->is_array()) fail(what + " has no 'primitives' array");
  return *primitives;
}

uint64_t GltfLoader::estimate_triangles(int mesh) {
  uint64_t total = 0;
  const json& primitives = primitives_of(mesh);
  const size_t accessor_count = top_array("accessors").size();
  for (size_t p = 0; p < primitives.size(); ++p) {
    const json& prim = primitives[p];
    const std::string what = mesh_label(mesh) + " primitive " + std::to_string(p);
    const uint64_t mode = opt_uint(prim, "mode", 4, what);
    if (mode < 4 || mode > 6) continue;  // reported when decoded
    const json* attributes = member(prim, "attributes");
    int64_t source = opt_index(prim, "indices", accessor_count, what, "accessors");
    std::string role = what + " indices";
    if (source < 0 && attributes) {
      source = opt_index(*attributes, "POSITION", accessor_count, what, "accessors");
      role = what + " POSITION";
    }
    if (source < 0) continue;
    const uint64_t n = accessor_info(uint64_t(source), role).count;
    total += mode == 4 ? n / 3 : (n >= 3 ? n - 2 : 0);
  }
  return total;
}

PrimitiveGeometry GltfLoader::decode_primitive(int mesh, uint64_t p, const json& prim) {
  PrimitiveGeometry geometry;
  const std::string mesh_text = mesh_label(mesh);
  const std::string what = mesh_text + " primitive " + std::to_string(p);
  if (!prim.is_object()) fail(what + " must be a JSON object");
  const uint64_t mode = opt_uint(prim, "mode", 4, what);
  if (mode > 6) fail(what + " has unknown mode " + std::to_string(mode));
  const std::string mesh_name = opt_string(meshes()[size_t(mesh)], "name");
  const std::string short_mesh =
      mesh_name.empty() ? std::to_string(mesh) : "'" + one_line(mesh_name, 60) + "'";
  const bool line_mode = settings_.lines && mode >= 1 && mode <= 3;
  if (line_mode) {
    const json* attributes = member(prim, "attributes");
    if (!attributes || !attributes->is_object()) fail(what + " has no 'attributes' object");
    if (!read_lines(prim, *attributes, int(mode), what, geometry)) {
      warn("ignoring primitive " + std::to_string(p) + " of mesh " + short_mesh + " (no POSITION)");
      ++scene_.stats.primitives_skipped;
      geometry.skip = true;
    }
    return geometry;
  }
  if (mode < 4) {
    warn("ignoring primitive " + std::to_string(p) + " of mesh " + short_mesh + " (" +
         kModeNames[mode] + ")");
    ++scene_.stats.primitives_skipped;
    geometry.skip = true;
    return geometry;
  }
  geometry.material = int(opt_index(prim, "material", scene_.materials.size(), what, "materials"));
  const json* attributes = member(prim, "attributes");
  if (!attributes || !attributes->is_object()) fail(what + " has no 'attributes' object");
  const int uv_set = geometry.material >= 0 ? uv_mappings_[size_t(geometry.material)].set : 0;
  const std::string uv_name = "TEXCOORD_" + std::to_string(uv_set);

  const json* extensions = member(prim, "extensions");
  const json* draco = extensions ? member(*extensions, "KHR_draco_mesh_compression") : nullptr;
  if (draco && gltf_draco_supported()) {
    decode_draco(*draco, what, uv_name, geometry);
  } else if (!read_primitive(prim, *attributes, int(mode), draco != nullptr, what, uv_name,
                             geometry)) {
    warn("ignoring primitive " + std::to_string(p) + " of mesh " + short_mesh + " (no POSITION)");
    ++scene_.stats.primitives_skipped;
    geometry.skip = true;
    return geometry;
  }
  compact_vertices(geometry, geometry.triangles);
  if (!geometry.uvs.empty() && geometry.material >= 0) {
    const UvMapping& mapping = uv_mappings_[size_t(geometry.material)];
    if (mapping.transform) {
      for (glm::vec2& uv : geometry.uvs) uv = glm::vec2(mapping.matrix * glm::dvec3(uv, 1.0));
    }
  }
  return geometry;
}

bool GltfLoader::read_primitive(const json& prim, const json& attributes, int mode, bool draco,
                                const std::string& what, const std::string& uv_name,
                                PrimitiveGeometry& geometry) {
  const size_t accessor_count = top_array("accessors").size();
  const int64_t position = opt_index(attributes, "POSITION", accessor_count, what, "accessors");
  if (position < 0) return false;
  AccessorInfo position_info;
  {
    const json* view = member(top_array("accessors")[size_t(position)], "bufferView");
    if (draco && !view)
      fail(what +
           " is compressed with KHR_draco_mesh_compression, but this build has no Draco "
           "decoder");
    if (!draco && !view && !member(top_array("accessors")[size_t(position)], "sparse"))
      warn(what + ": POSITION accessor " + std::to_string(position) + " has no data (all zeros)");
  }
  std::vector<float> values =
      read_attribute(uint64_t(position), 3, what + " POSITION", &position_info);
  const size_t vertex_count = values.size() / 3;
  geometry.positions.resize(vertex_count);
  if (vertex_count > 0)  // an empty vector's data() may be null
    std::memcpy(geometry.positions.data(), values.data(), vertex_count * 3 * sizeof(float));
  const int64_t normal =
      settings_.shading ? opt_index(attributes, "NORMAL", accessor_count, what, "accessors") : -1;
  if (normal >= 0) {
    values = read_attribute(uint64_t(normal), 3, what + " NORMAL", nullptr);
    if (values.size() / 3 != vertex_count) {
      warn(what + ": NORMAL count differs from POSITION count; using flat normals");
    } else {
      geometry.normals.resize(vertex_count);
      if (!values.empty())
        std::memcpy(geometry.normals.data(), values.data(), values.size() * sizeof(float));
    }
  }
  const int64_t uv = settings_.shading
                         ? opt_index(attributes, uv_name.c_str(), accessor_count, what, "accessors")
                         : -1;
  if (uv >= 0) {
    values = read_attribute(uint64_t(uv), 2, what + " " + uv_name, nullptr);
    if (values.size() / 2 != vertex_count) {
      warn(what + ": " + uv_name + " count differs from POSITION count; ignored");
    } else {
      geometry.uvs.resize(vertex_count);
      if (!values.empty())
        std::memcpy(geometry.uvs.data(), values.data(), values.size() * sizeof(float));
    }
  }
  std::vector<uint32_t> indices = read_vertex_indices(prim, vertex_count, what);
  expand_topology(mode, indices, what, geometry.triangles);
  return true;
}

std::vector<uint32_t> GltfLoader::read_vertex_indices(const json& prim, size_t vertex_count,
                                                      const std::string& what) {
  const size_t accessor_count = top_array("accessors").size();
  std::vector<uint32_t> indices;
  const int64_t index_accessor = opt_index(prim, "indices", accessor_count, what, "accessors");
  if (index_accessor >= 0) {
    indices = read_indices(uint64_t(index_accessor), what + " indices");
    for (size_t i = 0; i < indices.size(); ++i) {
      if (indices[i] >= vertex_count)
        fail(what + ": index " + std::to_string(indices[i]) + " (element " + std::to_string(i) +
             " of accessor " + std::to_string(index_accessor) + ") is out of range (" +
             std::to_string(vertex_count) + " vertices)");
    }
  } else {
    indices.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) indices[i] = uint32_t(i);
  }
  return indices;
}

bool GltfLoader::read_lines(const json& prim, const json& attributes, int mode,
                            const std::string& what, PrimitiveGeometry& geometry) {
  const size_t accessor_count = top_array("accessors").size();
  const int64_t position = opt_index(attributes, "POSITION", accessor_count, what, "accessors");
  if (position < 0) return false;
  const std::vector<float> values =
      read_attribute(uint64_t(position), 3, what + " POSITION", nullptr);
  const size_t vertex_count = values.size() / 3;
  geometry.lines = true;
  geometry.positions.resize(vertex_count);
  if (vertex_count > 0)  // an empty vector's data() may be null
    std::memcpy(geometry.positions.data(), values.data(), vertex_count * 3 * sizeof(float));
  expand_lines(mode, read_vertex_indices(prim, vertex_count, what), what, geometry.segments);
  compact_vertices(geometry, geometry.segments);
  return true;
}

void GltfLoader::expand_lines(int mode, const std::vector<uint32_t>& indices,
                              const std::string& what, std::vector<uint32_t>& segments) {
  const size_t n = indices.size();
  if (mode == 1) {  // LINES: {v_2i, v_2i+1}
    if (n % 2 != 0) warn(what + ": index count " + std::to_string(n) + " is odd; the last ignored");
    segments.assign(indices.begin(), indices.begin() + ptrdiff_t(n - n % 2));
    return;
  }
  if (n < 2) return;
  // LINE_STRIP: {v_i, v_i+1}; LINE_LOOP also {v_n-1, v_0}, but not for 2
  // points, where it would repeat the one segment.
  const bool close = mode == 2 && n > 2;
  segments.reserve(2 * (n - 1 + (close ? 1 : 0)));
  for (size_t i = 0; i + 1 < n; ++i) {
    segments.push_back(indices[i]);
    segments.push_back(indices[i + 1]);
  }
  if (close) {
    segments.push_back(indices[n - 1]);
    segments.push_back(indices[0]);
  }
}

void GltfLoader::expand_topology(int mode, std::vector<uint32_t>& indices, const std::string& what,
                                 std::vector<uint32_t>& triangles) {
  const size_t n = indices.size();
  if (mode == 4) {
    if (n % 3 != 0)
      warn(what + ": index count " + std::to_string(n) + " is not a multiple of 3; the last " +
           std::to_string(n % 3) + " ignored");
    indices.resize(n - n % 3);
    triangles = std::move(indices);
    return;
  }
  if (n < 3) return;
  triangles.resize((n - 2) * 3);
  for (size_t i = 0; i + 2 < n; ++i) {
    uint32_t* out = triangles.data() + 3 * i;
    if (mode == 5) {  // strip: {v_i, v_{i+1+i%2}, v_{i+2-i%2}}
      out[0] = indices[i];
      out[1] = indices[i + 1 + i % 2];
      out[2] = indices[i + 2 - i % 2];
    } else {  // fan: {v_{i+1}, v_{i+2}, v_0}
      out[0] = indices[i + 1];
      out[1] = indices[i + 2];
      out[2] = indices[0];
    }
  }
}

const PrimitiveGeometry& GltfLoader::geometry(int mesh, size_t p) {
  auto& slot = geometry_cache_[mesh];
  if (slot.empty()) {
    const json& primitives = primitives_of(mesh);
    slot.resize(primitives.size());
  }
  if (!slot[p])
    slot[p] =
        std::make_unique<PrimitiveGeometry>(decode_primitive(mesh, p, primitives_of(mesh)[p]));
  return *slot[p];
}

void GltfLoader::build_geometry(const std::vector<Instance>& instances) {
  // Check the triangle limit and reserve memory from declared counts.
  std::unordered_map<int, uint64_t> estimate;
  std::unordered_map<int, uint32_t> uses;
  uint64_t total = 0;
  for (const Instance& instance : instances) {
    auto it = estimate.find(instance.mesh);
    if (it == estimate.end())
      it = estimate.emplace(instance.mesh, estimate_triangles(instance.mesh)).first;
    total += it->second;
    ++uses[instance.mesh];
    if (total > settings_.limits.max_triangles) fail_triangle_limit();
  }
  scene_.positions.reserve(size_t(total) * 3);
  if (settings_.shading) scene_.normals.reserve(size_t(total) * 3);
  Progress progress("load", double(instances.size()));
  std::vector<glm::vec3> world_positions, world_normals;
  for (size_t i = 0; i < instances.size(); ++i) {
    const Instance& instance = instances[i];
    ++scene_.stats.instances;
    const size_t primitive_count = primitives_of(instance.mesh).size();
    for (size_t p = 0; p < primitive_count; ++p) {
      const PrimitiveGeometry& g = geometry(instance.mesh, p);
      if (g.skip) continue;
      if (g.lines)
        append_lines(instance, int(p), g, world_positions, world_normals);
      else
        append(instance, int(p), g, world_positions, world_normals);
    }
    if (--uses[instance.mesh] == 0) geometry_cache_.erase(instance.mesh);
    progress.update(double(i + 1));
  }
}

bool GltfLoader::transform_vertices(const Instance& instance, const PrimitiveGeometry& g,
                                    std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn) {
  const glm::dmat4& world = instance.world;
  const glm::dmat3 linear(world);
  const double det = glm::determinant(linear);
  const bool flip = det < 0;
  // det * inverse-transpose = columns (c1 x c2, c2 x c0, c0 x c1); the sign
  // of det keeps normals pointing the same way for mirrored instances.
  const double sign = det < 0 ? -1.0 : 1.0;
  const glm::mat3 normal_matrix(glm::dmat3(glm::cross(linear[1], linear[2]),
                                           glm::cross(linear[2], linear[0]),
                                           glm::cross(linear[0], linear[1])) *
                                sign);
  const size_t vertex_count = g.positions.size();
  const size_t vertex_chunks = (vertex_count + kLoadChunk - 1) / kLoadChunk;
  wp.resize(vertex_count);
  std::vector<size_t> not_finite(vertex_chunks, SIZE_MAX);  // per chunk, the first
  const bool has_normals = !g.normals.empty();
  if (has_normals) wn.resize(vertex_count);
  parallel_for_ranges(vertex_count, kLoadChunk, [&](size_t begin, size_t end) {
    for (size_t v = begin; v < end; ++v) {
      const glm::dvec3 p = glm::dvec3(world * glm::dvec4(glm::dvec3(g.positions[v]), 1.0));
      wp[v] = glm::vec3(p);
      if (!std::isfinite(wp[v].x) || !std::isfinite(wp[v].y) || !std::isfinite(wp[v].z)) {
        not_finite[begin / kLoadChunk] = std::min(not_finite[begin / kLoadChunk], v);
      }
      if (!has_normals) continue;
      const glm::vec3 n = normal_matrix * g.normals[v];
      const float length = glm::length(n);
      wn[v] = length > 1e-30f && std::isfinite(length) ? n / length : glm::vec3(0.0f);
    }
  });
  for (const size_t v : not_finite) {
    if (v == SIZE_MAX) continue;
    fail(node_label(instance.node) + ": vertex " + std::to_string(v) + " of " +
         mesh_label(instance.mesh) + " is not finite in world space");
  }
  return flip;
}

void GltfLoader::append(const Instance& instance, int primitive, const PrimitiveGeometry& g,
                        std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn) {
  const uint64_t triangle_count = g.triangles.size() / 3;
  if (scene_.stats.triangles_read + triangle_count > settings_.limits.max_triangles)
    fail_triangle_limit();
  scene_.stats.triangles_read += triangle_count;
  // Vertices, then triangles, in chunks on all cores; each chunk writes its
  // own elements, and what it finds (the first vertex not finite, its kept
  // triangles, their bounds) is combined in chunk order, so the scene is
  // the same on any number of cores.
  const bool flip = transform_vertices(instance, g, wp, wn);
  const bool has_normals = !g.normals.empty();
  const bool has_uvs = !g.uvs.empty();
  if (has_uvs && scene_.uvs.empty() && !scene_.positions.empty())
    scene_.uvs.resize(scene_.positions.size(), glm::vec2(0.0f));
  const bool write_uvs = has_uvs || !scene_.uvs.empty();
  if (write_uvs && scene_.uvs.capacity() < scene_.positions.capacity())
    scene_.uvs.reserve(scene_.positions.capacity());

  SceneObject object;
  object.node = instance.node;
  object.mesh = instance.mesh;
  object.primitive = primitive;
  object.material = g.material;
  object.first_triangle = uint32_t(scene_.triangle_count());
  // Triangle t's corners as wound in world space, or false where it is
  // degenerate: a repeated index, or zero area (the height is below 1e-7
  // of the longest edge).
  const auto indices = [&](uint64_t t, uint32_t(&v)[3]) {
    v[0] = g.triangles[3 * t];
    v[1] = g.triangles[3 * t + 1];
    v[2] = g.triangles[3 * t + 2];
    if (flip) std::swap(v[1], v[2]);
  };
  const auto corners = [&](uint64_t t, uint32_t(&v)[3]) {
    indices(t, v);
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) return false;
    const glm::vec3 pa = wp[v[0]], pb = wp[v[1]], pc = wp[v[2]];
    const glm::dvec3 e0 = glm::dvec3(pb - pa), e1 = glm::dvec3(pc - pa), e2 = glm::dvec3(pc - pb);
    const glm::dvec3 cross = glm::cross(e0, e1);
    const double area2 = glm::dot(cross, cross);
    const double longest2 = std::max({glm::dot(e0, e0), glm::dot(e1, e1), glm::dot(e2, e2)});
    return area2 > 1e-14 * longest2 * longest2;
  };
  const size_t chunks = size_t((triangle_count + kLoadChunk - 1) / kLoadChunk);
  std::vector<size_t> chunk_kept(chunks + 1, 0);  // then each chunk's first output triangle
  std::vector<uint8_t> keep(triangle_count);      // corners() of each, worked out once
  parallel_for(chunks, [&](size_t c) {
    uint32_t v[3];
    for (uint64_t t = c * kLoadChunk; t < std::min<uint64_t>(triangle_count, (c + 1) * kLoadChunk);
         ++t) {
      keep[t] = corners(t, v);
      chunk_kept[c + 1] += keep[t];
    }
  });
  for (size_t c = 0; c < chunks; ++c) chunk_kept[c + 1] += chunk_kept[c];
  const uint64_t kept = chunk_kept[chunks];
  scene_.stats.degenerate_dropped += triangle_count - kept;
  const size_t out = scene_.positions.size();
  scene_.positions.resize(out + 3 * kept);
  if (settings_.shading) {
    scene_.normals.resize(out + 3 * kept);
    if (write_uvs) scene_.uvs.resize(out + 3 * kept);
  }
  std::vector<Bounds> chunk_bounds(chunks);
  parallel_for(chunks, [&](size_t c) {
    size_t at = out + 3 * chunk_kept[c];
    uint32_t v[3];
    for (uint64_t t = c * kLoadChunk; t < std::min<uint64_t>(triangle_count, (c + 1) * kLoadChunk);
         ++t) {
      if (!keep[t]) continue;
      indices(t, v);
      glm::vec3 face(0.0f);
      if (settings_.shading) {
        const glm::dvec3 cross =
            glm::cross(glm::dvec3(wp[v[1]] - wp[v[0]]), glm::dvec3(wp[v[2]] - wp[v[0]]));
        face = glm::vec3(cross / std::sqrt(glm::dot(cross, cross)));
      }
      for (const uint32_t corner : v) {
        scene_.positions[at] = wp[corner];
        chunk_bounds[c].extend(wp[corner]);
        if (settings_.shading) {
          glm::vec3 n = face;
          if (has_normals &&
              (wn[corner].x != 0.0f || wn[corner].y != 0.0f || wn[corner].z != 0.0f)) {
            n = wn[corner];
          }
          scene_.normals[at] = n;
          if (write_uvs) scene_.uvs[at] = has_uvs ? g.uvs[corner] : glm::vec2(0.0f);
        }
        ++at;
      }
    }
  });
  for (const Bounds& b : chunk_bounds) {
    if (b.empty()) continue;
    scene_.bounds.extend(b.min);
    scene_.bounds.extend(b.max);
  }
  if (kept == 0) return;
  if (scene_.triangle_count() > UINT32_MAX) fail("the scene has more than 2^32 triangles");
  object.triangle_count = uint32_t(kept);
  object.name = object_name(instance, primitive);
  object.node_path = node_paths_[instance.path];
  scene_.objects.push_back(std::move(object));
}

std::string GltfLoader::object_name(const Instance& instance, int primitive) const {
  const std::string node_name = opt_string(nodes()[size_t(instance.node)], "name");
  const std::string mesh_name = opt_string(meshes()[size_t(instance.mesh)], "name");
  return !node_name.empty() ? node_name
         : !mesh_name.empty()
             ? mesh_name
             : "mesh" + std::to_string(instance.mesh) + ".prim" + std::to_string(primitive);
}

void GltfLoader::append_lines(const Instance& instance, int primitive, const PrimitiveGeometry& g,
                              std::vector<glm::vec3>& wp, std::vector<glm::vec3>& wn) {
  const uint64_t segment_count = g.segments.size() / 2;
  if (line_segments_read_ + segment_count > settings_.limits.max_line_segments)
    fail("more than " + std::to_string(settings_.limits.max_line_segments) +
         " line segments (LoadLimits::max_line_segments)");
  line_segments_read_ += segment_count;
  transform_vertices(instance, g, wp, wn);  // fails on a point not finite
  SceneLines lines;
  for (uint64_t s = 0; s < segment_count; ++s) {
    const glm::vec3 a = wp[g.segments[2 * s]], b = wp[g.segments[2 * s + 1]];
    if (a == b) continue;  // zero length
    lines.segments.push_back(a);
    lines.segments.push_back(b);
  }
  if (lines.segments.empty()) return;
  lines.name = object_name(instance, primitive);
  lines.node_path = node_paths_[instance.path];
  lines.node = instance.node;
  scene_.lines.push_back(std::move(lines));
}

}  // namespace snow::gltf

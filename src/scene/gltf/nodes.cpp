// Part of the glTF loader (see scene/gltf/internal.h): the node hierarchy
// (glTF 2.0 section 3.5) with matrix or TRS transforms, the scene's roots,
// and EXT_mesh_gpu_instancing. The traversal is iterative, so
// a deep hierarchy cannot overflow the stack; cycles and shared children fail.
#include <glm/gtc/quaternion.hpp>

#include "scene/gltf/internal.h"

namespace snow::gltf {
namespace {

constexpr size_t kMaxPathNames = 24;  // node paths deeper than this are elided

bool finite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

}  // namespace

glm::dmat4 trs_matrix(const TrsValues& trs) {
  const glm::dvec4& q = trs[MotionChannel::kRotation];
  glm::dmat4 m = glm::mat4_cast(glm::dquat(q.w, q.x, q.y, q.z));
  for (int c = 0; c < 3; ++c) m[c] *= trs[MotionChannel::kScale][c];
  m[3] = glm::dvec4(glm::dvec3(trs[MotionChannel::kTranslation]), 1.0);
  return m;
}

TrsValues GltfLoader::node_trs(uint64_t node, const json& object) const {
  const std::string what = node_label(int(node));
  TrsValues trs = {glm::dvec4(0.0), glm::dvec4(0.0, 0.0, 0.0, 1.0), glm::dvec4(1.0, 1.0, 1.0, 0.0)};
  if (const json* t = member(object, "translation")) {
    const auto v = numbers<3>(*t, what + " 'translation'");
    trs[MotionChannel::kTranslation] = glm::dvec4(v[0], v[1], v[2], 0.0);
  }
  if (const json* r = member(object, "rotation")) {
    const auto q = numbers<4>(*r, what + " 'rotation'");
    const glm::dvec4 v(q[0], q[1], q[2], q[3]);
    const double length = glm::length(v);
    if (!(length > kZeroQuaternion)) fail(what + " 'rotation' is a zero quaternion");
    trs[MotionChannel::kRotation] = v / length;
  }
  if (const json* s = member(object, "scale")) {
    const auto v = numbers<3>(*s, what + " 'scale'");
    trs[MotionChannel::kScale] = glm::dvec4(v[0], v[1], v[2], 0.0);
  }
  return trs;
}

glm::dmat4 GltfLoader::local_matrix(uint64_t node, const json& object) const {
  if (const json* matrix = member(object, "matrix")) {
    const auto m = numbers<16>(*matrix, node_label(int(node)) + " 'matrix'");
    glm::dmat4 out;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) out[c][r] = m[size_t(c * 4 + r)];
    return out;
  }
  return trs_matrix(node_trs(node, object));
}

std::string GltfLoader::node_name(int node) const {
  std::string name = opt_string(nodes()[size_t(node)], "name");
  return name.empty() ? "node" + std::to_string(node) : name;
}

std::string GltfLoader::path_string(const std::vector<int>& path) const {
  std::string out;
  const size_t n = path.size();
  for (size_t i = 0; i < n; ++i) {
    if (n > kMaxPathNames && i == 4) {
      out += "/...(" + std::to_string(n - kMaxPathNames) + " levels)";
      i = n - (kMaxPathNames - 4) - 1;
      continue;
    }
    out += "/" + node_name(path[i]);
  }
  return out;
}

std::vector<int> GltfLoader::scene_roots(const std::vector<uint32_t>& parents) {
  const json& scenes = top_array("scenes");
  const size_t node_count = nodes().size();
  std::vector<int> roots;
  int64_t scene_index = opt_index(doc_, "scene", scenes.size(), "top-level", "scenes");
  if (scene_index < 0 && !scenes.empty()) scene_index = 0;
  if (scene_index < 0) {
    for (size_t n = 0; n < node_count; ++n)
      if (parents[n] == 0) roots.push_back(int(n));
    return roots;
  }
  const std::string what = "scene " + std::to_string(scene_index);
  const json& object = element(scenes, uint64_t(scene_index), what);
  const json* list = member(object, "nodes");
  if (!list) return roots;
  if (!list->is_array()) fail(what + " 'nodes' must be an array");
  for (const json& value : *list) {
    const uint64_t n = as_uint(value, what + " node");
    if (n >= node_count)
      fail(what + " lists node " + std::to_string(n) + ", out of range (" +
           std::to_string(node_count) + " nodes)");
    if (parents[n] != 0)
      warn(what + " lists " + node_label(int(n)) +
           ", which is a child of another node; its ancestors' transforms are not applied");
    roots.push_back(int(n));
  }
  return roots;
}

std::vector<Instance> GltfLoader::traverse() {
  const json& node_array = nodes();
  const size_t node_count = node_array.size();
  const size_t mesh_count = meshes().size();
  // Validate children and find parents (glTF node graphs are strict trees).
  std::vector<uint32_t> parents(node_count, 0);
  for (size_t n = 0; n < node_count; ++n) {
    const json& object = element(node_array, n, "node " + std::to_string(n));
    const json* children = member(object, "children");
    if (!children) continue;
    if (!children->is_array()) fail(node_label(int(n)) + " 'children' must be an array");
    for (const json& child : *children) {
      const uint64_t c = as_uint(child, node_label(int(n)) + " child");
      if (c >= node_count)
        fail(node_label(int(n)) + " has child " + std::to_string(c) + ", out of range (" +
             std::to_string(node_count) + " nodes)");
      if (c == n) fail("node cycle: " + node_label(int(n)) + " is its own child");
      if (++parents[c] > 1)
        fail(node_label(int(c)) + " is a child of more than one node (glTF needs a tree)");
    }
  }
  const std::vector<int> roots = scene_roots(parents);

  struct Entry {
    int node;
    bool exit;
    glm::dmat4 parent;
    int parent_node;  // -1 for a root
  };
  std::vector<Entry> stack;
  std::vector<uint8_t> state(node_count, 0);  // 0 new, 1 on the current path, 2 done
  std::vector<int> path;
  std::vector<Instance> instances;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it)
    stack.push_back({*it, false, glm::dmat4(1.0), -1});
  if (settings_.motions) {
    scene_parents_.assign(node_count, -2);
    node_locals_.assign(node_count, glm::dmat4(1.0));
    node_worlds_.assign(node_count, glm::dmat4(1.0));
  }
  while (!stack.empty()) {
    const Entry entry = stack.back();
    stack.pop_back();
    const int n = entry.node;
    if (entry.exit) {
      state[size_t(n)] = 2;
      path.pop_back();
      continue;
    }
    if (state[size_t(n)] == 1) fail("node cycle through " + node_label(n));
    if (state[size_t(n)] == 2)
      fail(node_label(n) + " is reached twice in the scene (repeated root or shared child)");
    state[size_t(n)] = 1;
    path.push_back(n);
    ++scene_.stats.nodes;
    const json& object = node_array[size_t(n)];
    const glm::dmat4 local = local_matrix(uint64_t(n), object);
    const glm::dmat4 world = entry.parent * local;
    if (!finite(world)) fail(node_label(n) + ": world transform is not finite");
    if (settings_.motions) {
      scene_parents_[size_t(n)] = entry.parent_node;
      node_locals_[size_t(n)] = local;
      node_worlds_[size_t(n)] = world;
    }
    stack.push_back({n, true, glm::dmat4(1.0), -1});
    const int64_t mesh = opt_index(object, "mesh", mesh_count, node_label(n), "meshes");
    if (mesh >= 0) add_instances(n, int(mesh), world, object, path, instances);
    if (const json* children = member(object, "children")) {
      for (auto c = children->rbegin(); c != children->rend(); ++c)
        stack.push_back({int(c->get<uint64_t>()), false, world, n});
    }
  }
  return instances;
}

void GltfLoader::add_instances(int node, int mesh, const glm::dmat4& world, const json& object,
                               const std::vector<int>& path, std::vector<Instance>& instances) {
  const uint32_t path_id = uint32_t(node_paths_.size());
  node_paths_.push_back(path_string(path));
  if (member(object, "skin"))
    warn(node_label(node) + ": skin ignored, " + mesh_label(mesh) +
         " placed in its bind pose by the node transform");
  const json* extensions = member(object, "extensions");
  const json* gpu = extensions ? member(*extensions, "EXT_mesh_gpu_instancing") : nullptr;
  const json* attributes = gpu ? member(*gpu, "attributes") : nullptr;
  if (!attributes || !attributes->is_object()) {
    instances.push_back({node, mesh, path_id, world});
    return;
  }
  // EXT_mesh_gpu_instancing: one instance per element of the TRS accessors.
  const std::string what = node_label(node) + " EXT_mesh_gpu_instancing";
  const size_t accessor_count = top_array("accessors").size();
  std::vector<float> t, r, s;
  uint64_t count = 0;
  bool have_count = false;
  auto read = [&](const char* name, int components, std::vector<float>& out) {
    const int64_t a = opt_index(*attributes, name, accessor_count, what, "accessors");
    if (a < 0) return;
    out = read_attribute(uint64_t(a), components, what + " " + name, nullptr);
    const uint64_t n = out.size() / size_t(components);
    if (have_count && n != count) fail(what + ": attribute counts differ");
    count = n;
    have_count = true;
  };
  read("TRANSLATION", 3, t);
  read("ROTATION", 4, r);
  read("SCALE", 3, s);
  if (!have_count) {
    instances.push_back({node, mesh, path_id, world});
    return;
  }
  if (count > settings_.limits.max_triangles)
    fail(what + ": " + std::to_string(count) + " instances exceed LoadLimits::max_triangles");
  for (uint64_t i = 0; i < count; ++i) {
    glm::dmat4 local(1.0);
    if (!t.empty()) local[3] = glm::dvec4(t[3 * i], t[3 * i + 1], t[3 * i + 2], 1.0);
    if (!r.empty()) {
      glm::dquat q(r[4 * i + 3], r[4 * i], r[4 * i + 1], r[4 * i + 2]);
      const double length = glm::length(q);
      if (!(length > 1e-12))
        fail(what + ": instance " + std::to_string(i) + " has a zero rotation");
      local = local * glm::dmat4(glm::mat4_cast(q / length));
    }
    if (!s.empty())
      local = local * glm::dmat4(glm::dvec4(s[3 * i], 0, 0, 0), glm::dvec4(0, s[3 * i + 1], 0, 0),
                                 glm::dvec4(0, 0, s[3 * i + 2], 0), glm::dvec4(0, 0, 0, 1));
    const glm::dmat4 instance_world = world * local;
    if (!finite(instance_world))
      fail(what + ": instance " + std::to_string(i) + " transform is not finite");
    instances.push_back({node, mesh, path_id, instance_world});
  }
}

}  // namespace snow::gltf

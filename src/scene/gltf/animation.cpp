// Part of the glTF loader (see scene/gltf/internal.h): animations (glTF 2.0
// section 3.11) sampled into node motions (LoadSettings::motions). Every
// channel is checked; those that move a node (translation, rotation, scale)
// are read with their samplers. Then each node with objects or lines whose
// path from the root is animated has its world transform evaluated at its
// sample times (scene/load_gltf.h) and stored relative to its rest pose.
// Keyframes, samples and the work of sampling are counted against
// LoadLimits::max_motion_samples before they are read, stored or done.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

#include <glm/gtc/quaternion.hpp>

#include "scene/gltf/internal.h"

namespace snow::gltf {
namespace {

// Samples per second at least between a node's keyframes (1/s).
constexpr double kMotionSampleHz = 60.0;
// Sampling steps (per sample, one per animated node on the path from the
// root, plus one) allowed per LoadLimits::max_motion_samples (count).
constexpr uint64_t kMotionWorkPerSample = 64;

int components_of(MotionChannel::Path path) { return path == MotionChannel::kRotation ? 4 : 3; }

bool finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

bool animated(const std::array<int, 3>& channels) {
  return channels[0] >= 0 || channels[1] >= 0 || channels[2] >= 0;
}

/// Spherical interpolation of two quaternions (x, y, z, w; not zero) on
/// the shorter arc, from `a` at u = 0 to `b` at u = 1; unit length.
glm::dvec4 slerp_shortest(glm::dvec4 a, glm::dvec4 b, double u) {
  a = glm::normalize(a);
  b = glm::normalize(b);
  double d = glm::dot(a, b);
  if (d < 0.0) {
    b = -b;
    d = -d;
  }
  if (d > 0.9995) return glm::normalize(a + u * (b - a));  // nearly the same: lerp
  const double theta = std::acos(std::min(d, 1.0));
  return glm::normalize(std::sin((1.0 - u) * theta) * a + std::sin(u * theta) * b);
}

/// The value of channel `c` at time `t` (seconds): x, y, z (w 0), or a
/// rotation's x, y, z, w, unnormalized. Held before the first keyframe and
/// after the last.
glm::dvec4 channel_value(const MotionChannel& c, double t) {
  const size_t n = c.times.size();
  const int k = components_of(c.path);
  const bool cubic = c.interpolation == MotionChannel::kCubicSpline;
  // Key i's in-tangent (part 0), value (1) or out-tangent (2).
  const auto key = [&](size_t i, size_t part) {
    const float* v = c.values.data() + (cubic ? 3 * i + part : i) * size_t(k);
    return glm::dvec4(v[0], v[1], v[2], k == 4 ? v[3] : 0.0);
  };
  if (t <= c.times[0]) return key(0, 1);
  if (t >= c.times[n - 1]) return key(n - 1, 1);
  const auto after = std::upper_bound(c.times.begin(), c.times.end(), t,
                                      [](double a, float b) { return a < double(b); });
  const size_t i = size_t(after - c.times.begin()) - 1;  // times[i] <= t < times[i + 1]
  const double dt = double(c.times[i + 1]) - double(c.times[i]);
  const double u = (t - double(c.times[i])) / dt;
  if (c.interpolation == MotionChannel::kStep) return key(i, 1);
  if (!cubic) {
    if (c.path == MotionChannel::kRotation) return slerp_shortest(key(i, 1), key(i + 1, 1), u);
    return key(i, 1) + u * (key(i + 1, 1) - key(i, 1));
  }
  // Cubic Hermite spline (glTF 2.0 appendix C).
  const double u2 = u * u, u3 = u2 * u;
  return (2 * u3 - 3 * u2 + 1) * key(i, 1) + dt * (u3 - 2 * u2 + u) * key(i, 2) +
         (-2 * u3 + 3 * u2) * key(i + 1, 1) + dt * (u3 - u2) * key(i + 1, 0);
}

/// Per node, its nearest animated ancestor in the scene (`up`, or -1) and
/// the product of the rest locals strictly between that ancestor (or the
/// root) and the node (`above`). `parents` as GltfLoader::scene_parents_.
void motion_paths(const std::vector<int>& parents, const std::vector<glm::dmat4>& locals,
                  MotionSet& set) {
  const size_t count = parents.size();
  set.up.assign(count, -1);
  set.above.assign(count, glm::dmat4(1.0));
  std::vector<uint8_t> done(count, 0);
  std::vector<int> walk;  // from a node up to one done, or a root
  for (size_t s = 0; s < count; ++s) {
    for (int m = int(s); m >= 0 && !done[size_t(m)]; m = parents[size_t(m)]) walk.push_back(m);
    for (auto it = walk.rbegin(); it != walk.rend(); ++it) {
      const size_t m = size_t(*it);
      const int p = parents[m];
      if (p >= 0 && animated(set.per_node[size_t(p)])) {
        set.up[m] = p;
      } else if (p >= 0) {
        set.up[m] = set.up[size_t(p)];
        set.above[m] = set.above[size_t(p)] * locals[size_t(p)];
      }
      done[m] = 1;
    }
    walk.clear();
  }
}

}  // namespace

void GltfLoader::read_motions() {
  const json& animations = top_array("animations");
  MotionSet set;
  uint64_t keyframes = 0;
  for (size_t a = 0; a < animations.size(); ++a) {
    const json& animation = element(animations, a, "animation " + std::to_string(a));
    const json* channels = member(animation, "channels");
    if (!channels || !channels->is_array())
      fail("animation " + std::to_string(a) + " has no 'channels' array");
    for (size_t c = 0; c < channels->size(); ++c) {
      MotionChannel channel;
      if (read_channel(a, animation, c, keyframes, channel))
        set.channels.push_back(std::move(channel));
    }
  }
  if (set.channels.empty()) return;
  const size_t node_count = nodes().size();
  set.per_node.assign(node_count, {-1, -1, -1});
  set.start = std::numeric_limits<double>::infinity();
  set.end = -set.start;
  for (size_t i = 0; i < set.channels.size(); ++i) {
    const MotionChannel& c = set.channels[i];
    set.per_node[size_t(c.node)][c.path] = int(i);  // the later channel wins
    set.start = std::min(set.start, double(c.times.front()));
    set.end = std::max(set.end, double(c.times.back()));
  }
  set.rest.resize(node_count);
  for (size_t n = 0; n < node_count; ++n)
    if (scene_parents_[n] != -2 && animated(set.per_node[n])) set.rest[n] = rest_trs(int(n));
  motion_paths(scene_parents_, node_locals_, set);
  std::vector<uint8_t> shown(node_count, 0);  // has objects or lines
  for (const SceneObject& o : scene_.objects) shown[size_t(o.node)] = 1;
  for (const SceneLines& l : scene_.lines) shown[size_t(l.node)] = 1;
  for (size_t n = 0; n < node_count; ++n) {
    if (shown[n] && (animated(set.per_node[n]) || set.up[n] >= 0))
      scene_.motions.push_back(sample_motion(int(n), set));
  }
}

bool GltfLoader::read_channel(uint64_t a, const json& animation, uint64_t c, uint64_t& keyframes,
                              MotionChannel& out) {
  const std::string what = "animation " + std::to_string(a) + " channel " + std::to_string(c);
  const json& channel = element(*member(animation, "channels"), c, what);
  const json* target = member(channel, "target");
  if (!target || !target->is_object()) fail(what + " has no 'target' object");
  const json* samplers = member(animation, "samplers");
  if (!samplers || !samplers->is_array())
    fail("animation " + std::to_string(a) + " has no 'samplers' array");
  const json* sampler = member(channel, "sampler");
  if (!sampler) fail(what + " has no 'sampler'");
  const uint64_t s = as_uint(*sampler, what + " 'sampler'");
  if (s >= samplers->size())
    fail(what + " 'sampler' = " + std::to_string(s) + " is out of range (" +
         std::to_string(samplers->size()) + " samplers)");
  const int64_t node = opt_index(*target, "node", nodes().size(), what + " target", "nodes");
  const std::string path = opt_string(*target, "path");
  if (path == "translation") {
    out.path = MotionChannel::kTranslation;
  } else if (path == "rotation") {
    out.path = MotionChannel::kRotation;
  } else if (path == "scale") {
    out.path = MotionChannel::kScale;
  } else {
    return false;  // weights, KHR_animation_pointer's "pointer": not a node's motion
  }
  if (node < 0) return false;  // no node: ignored (glTF 2.0 section 3.11)
  out.node = int(node);
  const std::string sampler_what =
      "animation " + std::to_string(a) + " sampler " + std::to_string(s);
  read_sampler(element(*samplers, s, sampler_what), sampler_what, keyframes, out);
  return true;
}

void GltfLoader::read_sampler(const json& sampler, const std::string& what, uint64_t& keyframes,
                              MotionChannel& out) {
  const std::string interpolation =
      member(sampler, "interpolation") ? opt_string(sampler, "interpolation") : "LINEAR";
  if (interpolation == "LINEAR") {
    out.interpolation = MotionChannel::kLinear;
  } else if (interpolation == "STEP") {
    out.interpolation = MotionChannel::kStep;
  } else if (interpolation == "CUBICSPLINE") {
    out.interpolation = MotionChannel::kCubicSpline;
  } else {
    fail(what + " has unknown interpolation '" + one_line(interpolation, 40) + "'");
  }
  const json* input = member(sampler, "input");
  const json* output = member(sampler, "output");
  if (!input || !output) fail(what + " needs an 'input' and an 'output'");
  const uint64_t accessor = as_uint(*input, what + " 'input'");
  const AccessorInfo info = accessor_info(accessor, what + " input");
  const std::string input_what = "accessor " + std::to_string(accessor) + " (" + what + " input)";
  if (info.components != 1 || info.component_type != kFloat)
    fail(input_what + " must be SCALAR float");
  if (info.count == 0) fail(input_what + " has no keyframes");
  keyframes += info.count;
  const uint64_t limit = settings_.limits.max_motion_samples;
  if (keyframes > limit)
    fail(what + ": the animations have more than " + std::to_string(limit) +
         " keyframes (LoadLimits::max_motion_samples)");
  out.times = decode_floats(info, what + " input");
  for (size_t i = 0; i < out.times.size(); ++i) {
    if (!std::isfinite(out.times[i]))
      fail(input_what + " time " + std::to_string(i) + " is not finite (NaN or infinite)");
    if (i > 0 && !(out.times[i] > out.times[i - 1]))
      fail(input_what + " times are not strictly increasing (element " + std::to_string(i) + ")");
  }
  read_keyframe_values(as_uint(*output, what + " 'output'"), what, out);
}

void GltfLoader::read_keyframe_values(uint64_t accessor, const std::string& what,
                                      MotionChannel& out) {
  const AccessorInfo info = accessor_info(accessor, what + " output");
  const std::string output_what = "accessor " + std::to_string(accessor) + " (" + what + " output)";
  const bool rotation = out.path == MotionChannel::kRotation;
  const int k = components_of(out.path);
  const int type = info.component_type;
  const bool normalized = info.normalized && (type == kByte || type == kUnsignedByte ||
                                              type == kShort || type == kUnsignedShort);
  if (info.components != k || !(type == kFloat || (rotation && normalized)))
    fail(output_what + " must be " +
         (rotation ? "VEC4 float or normalized integers" : "VEC3 float") + " for a " +
         (rotation                            ? "rotation"
          : out.path == MotionChannel::kScale ? "scale"
                                              : "translation"));
  const bool cubic = out.interpolation == MotionChannel::kCubicSpline;
  const uint64_t needed = uint64_t(out.times.size()) * (cubic ? 3 : 1);
  if (info.count != needed)
    fail(output_what + " has " + std::to_string(info.count) + " elements, not " +
         std::to_string(needed) + " (" + std::to_string(out.times.size()) + " keyframes" +
         (cubic ? ", 3 each for CUBICSPLINE)" : ")"));
  out.values = decode_floats(info, what + " output");
  for (size_t i = 0; i < out.values.size(); ++i) {
    if (!std::isfinite(out.values[i]))
      fail(output_what + " element " + std::to_string(i / size_t(k)) +
           " is not finite (NaN or infinite)");
  }
  if (!rotation) return;
  for (size_t i = 0; i < out.times.size(); ++i) {
    const float* q = out.values.data() + 4 * (cubic ? 3 * i + 1 : i);
    if (!(glm::length(glm::dvec4(q[0], q[1], q[2], q[3])) > kZeroQuaternion))
      fail(output_what + " keyframe " + std::to_string(i) + " is a zero quaternion");
  }
}

TrsValues GltfLoader::rest_trs(int node) const {
  const json& object = nodes()[size_t(node)];
  if (member(object, "matrix"))
    fail(node_label(node) + " is animated but has a 'matrix' (glTF animates only TRS nodes)");
  return node_trs(uint64_t(node), object);
}

glm::dmat4 GltfLoader::local_at(int node, double t, const MotionSet& set) const {
  TrsValues trs = set.rest[size_t(node)];
  const std::array<int, 3>& channels = set.per_node[size_t(node)];
  for (size_t p = 0; p < 3; ++p)
    if (channels[p] >= 0) trs[p] = channel_value(set.channels[size_t(channels[p])], t);
  const double length = glm::length(trs[MotionChannel::kRotation]);
  if (!(length > kZeroQuaternion))
    fail(node_label(node) + ": its rotation at " + std::to_string(t) +
         " s is a zero quaternion (CUBICSPLINE tangents)");
  trs[MotionChannel::kRotation] /= length;
  return trs_matrix(trs);
}

NodeMotion GltfLoader::sample_motion(int node, MotionSet& set) {
  const bool own = animated(set.per_node[size_t(node)]);
  std::vector<int> chain;  // the animated nodes on the path, from the root down
  for (int a = own ? node : set.up[size_t(node)]; a >= 0; a = set.up[size_t(a)]) chain.push_back(a);
  std::reverse(chain.begin(), chain.end());
  std::vector<int> used;  // their channels
  for (const int a : chain)
    for (const int c : set.per_node[size_t(a)])
      if (c >= 0) used.push_back(c);
  NodeMotion motion;
  motion.node = node;
  motion.times = motion_times(node, used, set);
  const uint64_t limit = settings_.limits.max_motion_samples;
  const uint64_t work_limit =
      limit > UINT64_MAX / kMotionWorkPerSample ? UINT64_MAX : limit * kMotionWorkPerSample;
  set.work += uint64_t(motion.times.size()) * (uint64_t(chain.size()) + 1);
  if (set.work > work_limit)
    fail(node_label(node) + ": sampling the motions takes more than " +
         std::to_string(kMotionWorkPerSample) + " x LoadLimits::max_motion_samples (" +
         std::to_string(limit) + ") steps");
  const glm::dmat4 tail =
      own ? glm::dmat4(1.0) : set.above[size_t(node)] * node_locals_[size_t(node)];
  const glm::dmat4 rest_inverse = glm::inverse(node_worlds_[size_t(node)]);
  motion.moves.reserve(motion.times.size());
  for (const float t : motion.times) {
    glm::dmat4 world(1.0);
    for (const int a : chain) world = world * set.above[size_t(a)] * local_at(a, t, set);
    const glm::mat4 move(world * tail * rest_inverse);
    if (!finite(move))
      fail(node_label(node) + ": its motion at " + std::to_string(t) +
           " s is not finite (a singular rest transform, or an overflow)");
    motion.moves.push_back(move);
  }
  return motion;
}

std::vector<float> GltfLoader::motion_times(int node, const std::vector<int>& used,
                                            MotionSet& set) {
  std::vector<float> keys = {float(set.start), float(set.end)};
  for (const int c : used) {
    const std::vector<float>& times = set.channels[size_t(c)].times;
    keys.insert(keys.end(), times.begin(), times.end());
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  // Each gap of d seconds is cut into ceil(d * kMotionSampleHz) steps.
  const auto steps = [](float a, float b) {
    return std::max(1.0, std::ceil((double(b) - double(a)) * kMotionSampleHz));
  };
  double total = 1.0;
  for (size_t i = 0; i + 1 < keys.size(); ++i) total += steps(keys[i], keys[i + 1]);
  const uint64_t limit = settings_.limits.max_motion_samples;
  if (double(set.samples) + total > double(limit)) {
    // (Formatted as a double: a hostile animation's count overflows integers.)
    char needed[32];
    std::snprintf(needed, sizeof needed, total < 1e15 ? "%.0f" : "%.3g", total);
    fail(node_label(node) + ": its motion needs " + needed +
         " samples, over LoadLimits::max_motion_samples (" + std::to_string(limit) +
         " for all nodes, " + std::to_string(set.samples) + " stored before)");
  }
  std::vector<float> times;
  times.reserve(size_t(total));
  times.push_back(keys[0]);
  for (size_t i = 0; i + 1 < keys.size(); ++i) {
    const double a = keys[i], d = double(keys[i + 1]) - a, n = steps(keys[i], keys[i + 1]);
    for (double j = 1; j < n; ++j) {
      const float t = float(a + d * j / n);
      // Float rounding may repeat a time.
      if (t > times.back() && t < keys[i + 1]) times.push_back(t);
    }
    times.push_back(keys[i + 1]);
  }
  set.samples += times.size();
  return times;
}

}  // namespace snow::gltf

// Part of the glTF loader (see scene/gltf/internal.h): accessors (glTF 2.0
// section 3.6) with byteStride, sparse storage and normalized
// integers (3.11, KHR_mesh_quantization), decoded to floats or indices.
// Sizes are checked with 64-bit arithmetic before any allocation, so a
// declared count of 1e9 over a 48-byte buffer fails at once.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "scene/gltf/internal.h"

namespace snow::gltf {
namespace {

constexpr uint64_t kMaxAccessorCount = 1ull << 32;

int component_size(int component_type) {
  switch (component_type) {
    case kByte:
    case kUnsignedByte:
      return 1;
    case kShort:
    case kUnsignedShort:
      return 2;
    case kInt:
    case kUnsignedInt:
    case kFloat:
      return 4;
    default:
      return 0;
  }
}

int type_components(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  if (type == "MAT2") return 4;
  if (type == "MAT3") return 9;
  if (type == "MAT4") return 16;
  return 0;
}

/// Converts `count` elements of `components` values of type T into floats.
template <typename T>
void convert_elements(const uint8_t* src, uint64_t stride, uint64_t count, int components,
                      bool normalized, float* out) {
  if (count == 0) return;  // `out` may be null (an empty vector's data)
  if (std::is_same<T, float>::value && stride == sizeof(float) * size_t(components)) {
    std::memcpy(out, src, count * stride);
    return;
  }
  for (uint64_t i = 0; i < count; ++i) {
    const uint8_t* element = src + i * stride;
    for (int c = 0; c < components; ++c) {
      T value;
      std::memcpy(&value, element + c * sizeof(T), sizeof(T));
      float f = static_cast<float>(value);
      if (normalized && !std::is_same<T, float>::value) {
        // glTF 2.0 section 3.11 (normalized integers).
        if (std::is_same<T, int8_t>::value) f = std::max(f / 127.0f, -1.0f);
        if (std::is_same<T, uint8_t>::value) f = f / 255.0f;
        if (std::is_same<T, int16_t>::value) f = std::max(f / 32767.0f, -1.0f);
        if (std::is_same<T, uint16_t>::value) f = f / 65535.0f;
      }
      out[i * size_t(components) + size_t(c)] = f;
    }
  }
}

void convert_any(int component_type, const uint8_t* src, uint64_t stride, uint64_t count,
                 int components, bool normalized, float* out) {
  switch (component_type) {
    case kByte:
      return convert_elements<int8_t>(src, stride, count, components, normalized, out);
    case kUnsignedByte:
      return convert_elements<uint8_t>(src, stride, count, components, normalized, out);
    case kShort:
      return convert_elements<int16_t>(src, stride, count, components, normalized, out);
    case kUnsignedShort:
      return convert_elements<uint16_t>(src, stride, count, components, normalized, out);
    case kInt:
      return convert_elements<int32_t>(src, stride, count, components, false, out);
    case kUnsignedInt:
      return convert_elements<uint32_t>(src, stride, count, components, false, out);
    default:
      return convert_elements<float>(src, stride, count, components, false, out);
  }
}

uint32_t read_uint(const uint8_t* p, int component_type) {
  switch (component_type) {
    case kUnsignedByte:
      return *p;
    case kUnsignedShort: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    default: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

}  // namespace

AccessorInfo GltfLoader::accessor_info(uint64_t index, const std::string& role) {
  const json& accessors = top_array("accessors");
  if (index >= accessors.size())
    fail(role + ": accessor " + std::to_string(index) + " is out of range (" +
         std::to_string(accessors.size()) + " accessors)");
  const std::string what = "accessor " + std::to_string(index) + " (" + role + ")";
  const json& object = element(accessors, index, what);
  AccessorInfo info;
  info.index = int(index);
  const json* type_value = member(object, "componentType");
  if (!type_value) fail(what + " has no 'componentType'");
  info.component_type =
      int(std::min<uint64_t>(as_uint(*type_value, what + " 'componentType'"), 1 << 20));
  const int csize = component_size(info.component_type);
  if (csize == 0) fail(what + " has unknown componentType " + std::to_string(info.component_type));
  info.components = type_components(opt_string(object, "type"));
  if (info.components == 0) fail(what + " has a missing or unknown 'type'");
  const json* normalized = member(object, "normalized");
  info.normalized = normalized && normalized->is_boolean() && normalized->get<bool>();
  const json* count_value = member(object, "count");
  if (!count_value) fail(what + " has no 'count'");
  info.count = as_uint(*count_value, what + " 'count'");
  if (info.count > kMaxAccessorCount)
    fail(what + " declares count " + std::to_string(info.count) + ", over 2^32");
  const uint64_t element_size = uint64_t(csize) * uint64_t(info.components);
  const int64_t view_index =
      opt_index(object, "bufferView", top_array("bufferViews").size(), what, "bufferViews");
  if (view_index >= 0) {
    const ViewRange range = view(uint64_t(view_index), what);
    const uint64_t offset = opt_uint(object, "byteOffset", 0, what);
    info.stride = range.stride ? range.stride : element_size;
    if (info.stride < element_size)
      fail(what + ": bufferView " + std::to_string(view_index) + " byteStride " +
           std::to_string(info.stride) + " is smaller than an element (" +
           std::to_string(element_size) + " bytes)");
    if (info.count > 0) {
      const uint64_t needed = (info.count - 1) * info.stride + element_size;
      if (offset > range.length || needed > range.length - offset)
        fail(what + ": " + std::to_string(info.count) + " elements of " +
             std::to_string(element_size) + " bytes need " + std::to_string(needed) +
             " bytes from offset " + std::to_string(offset) + ", but bufferView " +
             std::to_string(view_index) + " holds " + std::to_string(range.length));
    }
    info.data = range.data + offset;
  }
  if (info.count > max_elements())
    fail(what + " declares count " + std::to_string(info.count) + ", over the limit of " +
         std::to_string(max_elements()) + " elements (from LoadLimits::max_triangles)");
  if (const json* sparse = member(object, "sparse")) read_sparse(*sparse, what, element_size, info);
  return info;
}

void GltfLoader::read_sparse(const json& sparse, const std::string& what, uint64_t element_size,
                             AccessorInfo& info) {
  const std::string swhat = what + " sparse";
  const json* scount = member(sparse, "count");
  if (!scount) fail(swhat + " has no 'count'");
  info.sparse_count = as_uint(*scount, swhat + " 'count'");
  if (info.sparse_count > info.count)
    fail(swhat + " 'count' " + std::to_string(info.sparse_count) + " exceeds the accessor count " +
         std::to_string(info.count));
  const json* indices = member(sparse, "indices");
  const json* values = member(sparse, "values");
  if (!indices || !indices->is_object() || !values || !values->is_object())
    fail(swhat + " needs 'indices' and 'values' objects");
  const json* itype = member(*indices, "componentType");
  if (!itype) fail(swhat + " indices have no 'componentType'");
  info.sparse_index_type =
      int(std::min<uint64_t>(as_uint(*itype, swhat + " indices 'componentType'"), 1 << 20));
  if (info.sparse_index_type != kUnsignedByte && info.sparse_index_type != kUnsignedShort &&
      info.sparse_index_type != kUnsignedInt)
    fail(swhat + " indices have componentType " + std::to_string(info.sparse_index_type) +
         " (must be an unsigned integer type)");
  const size_t view_count = top_array("bufferViews").size();
  const int64_t iview =
      opt_index(*indices, "bufferView", view_count, swhat + " indices", "bufferViews");
  const int64_t vview =
      opt_index(*values, "bufferView", view_count, swhat + " values", "bufferViews");
  if (iview < 0 || vview < 0) fail(swhat + " indices and values need a 'bufferView'");
  const ViewRange irange = view(uint64_t(iview), swhat);
  const ViewRange vrange = view(uint64_t(vview), swhat);
  const uint64_t ioffset = opt_uint(*indices, "byteOffset", 0, swhat + " indices");
  const uint64_t voffset = opt_uint(*values, "byteOffset", 0, swhat + " values");
  const uint64_t ineeded = info.sparse_count * uint64_t(component_size(info.sparse_index_type));
  const uint64_t vneeded = info.sparse_count * element_size;
  if (ioffset > irange.length || ineeded > irange.length - ioffset)
    fail(swhat + " indices need " + std::to_string(ineeded) + " bytes from offset " +
         std::to_string(ioffset) + ", but bufferView " + std::to_string(iview) + " holds " +
         std::to_string(irange.length));
  if (voffset > vrange.length || vneeded > vrange.length - voffset)
    fail(swhat + " values need " + std::to_string(vneeded) + " bytes from offset " +
         std::to_string(voffset) + ", but bufferView " + std::to_string(vview) + " holds " +
         std::to_string(vrange.length));
  info.sparse_indices = irange.data + ioffset;
  info.sparse_values = vrange.data + voffset;
}

uint64_t GltfLoader::max_elements() const { return settings_.limits.max_triangles * 3 + 2; }

uint32_t GltfLoader::sparse_target(const AccessorInfo& info, uint64_t k,
                                   const std::string& what) const {
  const int isize = component_size(info.sparse_index_type);
  const uint32_t target =
      read_uint(info.sparse_indices + k * uint64_t(isize), info.sparse_index_type);
  if (target >= info.count)
    fail(what + " sparse index " + std::to_string(target) + " is out of range (count " +
         std::to_string(info.count) + ")");
  return target;
}

std::vector<float> GltfLoader::decode_floats(const AccessorInfo& info, const std::string& role) {
  const std::string what = "accessor " + std::to_string(info.index) + " (" + role + ")";
  std::vector<float> out(size_t(info.count) * size_t(info.components), 0.0f);
  if (info.data)
    convert_any(info.component_type, info.data, info.stride, info.count, info.components,
                info.normalized, out.data());
  const uint64_t element_size =
      uint64_t(component_size(info.component_type)) * uint64_t(info.components);
  for (uint64_t k = 0; k < info.sparse_count; ++k) {
    const uint32_t target = sparse_target(info, k, what);
    convert_any(info.component_type, info.sparse_values + k * element_size, element_size, 1,
                info.components, info.normalized,
                out.data() + size_t(target) * size_t(info.components));
  }
  return out;
}

std::vector<float> GltfLoader::read_attribute(uint64_t accessor, int components,
                                              const std::string& role, AccessorInfo* info_out) {
  const AccessorInfo info = accessor_info(accessor, role);
  const std::string what = "accessor " + std::to_string(accessor) + " (" + role + ")";
  if (info.components != components) fail(what + " must be VEC" + std::to_string(components));
  if (info.component_type == kInt || info.component_type == kUnsignedInt)
    fail(what + " has componentType " + std::to_string(info.component_type) +
         ", not allowed for vertex attributes");
  if (info_out) *info_out = info;
  std::vector<float> values = decode_floats(info, role);
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i]))
      fail(what + " element " + std::to_string(i / size_t(components)) +
           " is not finite (NaN or infinite)");
  }
  return values;
}

std::vector<uint32_t> GltfLoader::read_indices(uint64_t accessor, const std::string& role) {
  const AccessorInfo info = accessor_info(accessor, role);
  const std::string what = "accessor " + std::to_string(accessor) + " (" + role + ")";
  if (info.components != 1) fail(what + " must be SCALAR");
  if (info.component_type != kUnsignedByte && info.component_type != kUnsignedShort &&
      info.component_type != kUnsignedInt)
    fail(what + " has componentType " + std::to_string(info.component_type) +
         " (indices must be unsigned byte, short or int)");
  std::vector<uint32_t> out(size_t(info.count), 0u);
  if (info.data) {
    const int csize = component_size(info.component_type);
    if (info.stride == uint64_t(csize) && info.component_type == kUnsignedInt) {
      if (!out.empty()) std::memcpy(out.data(), info.data, size_t(info.count) * 4);
    } else if (info.component_type == kUnsignedShort) {
      for (uint64_t i = 0; i < info.count; ++i) {
        uint16_t v;
        std::memcpy(&v, info.data + i * info.stride, 2);
        out[size_t(i)] = v;
      }
    } else {
      for (uint64_t i = 0; i < info.count; ++i)
        out[size_t(i)] = read_uint(info.data + i * info.stride, info.component_type);
    }
  }
  for (uint64_t k = 0; k < info.sparse_count; ++k) {
    const uint32_t target = sparse_target(info, k, what);
    out[target] = read_uint(info.sparse_values + k * uint64_t(component_size(info.component_type)),
                            info.component_type);
  }
  return out;
}

}  // namespace snow::gltf

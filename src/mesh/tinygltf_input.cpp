#include "mesh/tinygltf_input.h"

#include <tiny_gltf.h>

#include <cstring>
#include <limits>
#include <string>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"

namespace snow {
namespace {

using json = nlohmann::json;

uint32_t u32_at(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

void put_u32(std::vector<unsigned char>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
}

/// SAX handler that stops at the first whole number outside int's range
/// (outside the size_t keys), keeping where it lies. Iterative: no depth of
/// nesting overflows the stack here.
class WideInteger : public nlohmann::json_sax<json> {
 public:
  std::string where;  // JSON pointer of the number found; empty if none
  std::string value;

  bool null() override { return element(); }
  bool boolean(bool) override { return element(); }
  bool number_integer(number_integer_t v) override {
    return v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()
               ? found(std::to_string(v))
               : element();
  }
  bool number_unsigned(number_unsigned_t v) override {
    return v > uint64_t(std::numeric_limits<int>::max()) ? found(std::to_string(v)) : element();
  }
  bool number_float(number_float_t, const string_t&) override { return element(); }
  bool string(string_t&) override { return element(); }
  bool binary(binary_t&) override { return element(); }
  bool start_object(std::size_t) override {
    element();
    frames_.push_back({false, 0, {}});
    return true;
  }
  bool key(string_t& k) override {
    frames_.back().key = k;
    return true;
  }
  bool end_object() override {
    frames_.pop_back();
    return true;
  }
  bool start_array(std::size_t) override {
    element();
    frames_.push_back({true, 0, {}});
    return true;
  }
  bool end_array() override {
    frames_.pop_back();
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;  // tinygltf says what is wrong
  }

 private:
  struct Frame {
    bool array;
    size_t next;  // array: index of the next element
    std::string key;
  };
  std::vector<Frame> frames_;

  // A value starts: an array counts it.
  bool element() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().next;
    return true;
  }
  bool found(const std::string& text) {
    if (!frames_.empty() && !frames_.back().array) {
      const std::string& k = frames_.back().key;
      if (k == "byteLength" || k == "byteOffset" || k == "count") return true;
    }
    element();
    for (const Frame& f : frames_) where += "/" + (f.array ? std::to_string(f.next - 1) : f.key);
    value = text;
    return false;  // the first is enough
  }
};

/// Takes each indices accessor without a bufferView out of a Draco
/// primitive of `g`; true if it took any.
bool take_draco_indices(json& g, std::vector<TinygltfInput::DracoIndices>& taken) {
  if (!g.is_object() || !g.contains("meshes") || !g["meshes"].is_array()) return false;
  const json* accessors =
      g.contains("accessors") && g["accessors"].is_array() ? &g["accessors"] : nullptr;
  for (size_t m = 0; m < g["meshes"].size(); ++m) {
    json& mesh = g["meshes"][m];
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array())
      continue;
    for (size_t p = 0; p < mesh["primitives"].size(); ++p) {
      json& prim = mesh["primitives"][p];
      if (!prim.is_object() || !prim.contains("indices") || !prim["indices"].is_number_unsigned() ||
          !prim.contains("extensions") || !prim["extensions"].is_object() ||
          !prim["extensions"].contains("KHR_draco_mesh_compression"))
        continue;
      const uint64_t index = prim["indices"].get<uint64_t>();
      if (!accessors || index >= accessors->size() || !(*accessors)[index].is_object() ||
          (*accessors)[index].contains("bufferView"))
        continue;
      taken.push_back({int(m), int(p), int(index)});
      prim.erase("indices");
    }
  }
  return !taken.empty();
}

}  // namespace

TinygltfInput prepare_for_tinygltf(std::vector<unsigned char> bytes,
                                   const std::filesystem::path& path, bool binary) {
  TinygltfInput input;
  input.bytes = std::move(bytes);
  // The JSON: the whole .gltf, or a GLB's first chunk.
  size_t start = 0, length = input.bytes.size();
  if (binary) {
    if (input.bytes.size() < 20 || u32_at(input.bytes.data() + 16) != 0x4E4F534Au) return input;
    start = 20;
    length = u32_at(input.bytes.data() + 12);
    if (length > input.bytes.size() - start) return input;
  }
  const char* text = reinterpret_cast<const char*>(input.bytes.data()) + start;
  WideInteger wide;
  json::sax_parse(text, text + length, &wide);
  if (!wide.where.empty()) {
    throw InputError(path.string() + ": " + wide.where + " is " + wide.value +
                     ", beyond the whole numbers -2^31..2^31-1 that the scene plus snow keeps "
                     "when it rewrites the scene; write the snow alone (--snow-output, or "
                     "--snow-only)");
  }
  if (std::string_view(text, length).find("KHR_draco_mesh_compression") == std::string::npos)
    return input;
  json g = json::parse(text, text + length, nullptr, /*allow_exceptions=*/false);
  if (g.is_discarded() || !take_draco_indices(g, input.draco_indices)) return input;
  std::string rewritten = g.dump();
  if (!binary) {
    input.bytes.assign(rewritten.begin(), rewritten.end());
    return input;
  }
  while (rewritten.size() % 4) rewritten += ' ';
  const std::vector<unsigned char> rest(input.bytes.begin() + long(start + length),
                                        input.bytes.end());
  std::vector<unsigned char> out;
  put_u32(out, u32_at(input.bytes.data()));      // magic
  put_u32(out, u32_at(input.bytes.data() + 4));  // version
  put_u32(out, uint32_t(20 + rewritten.size() + rest.size()));
  put_u32(out, uint32_t(rewritten.size()));
  put_u32(out, 0x4E4F534Au);  // JSON
  out.insert(out.end(), rewritten.begin(), rewritten.end());
  out.insert(out.end(), rest.begin(), rest.end());
  input.bytes = std::move(out);
  return input;
}

void restore_after_tinygltf(const TinygltfInput& input, tinygltf::Model& model) {
  for (const TinygltfInput::DracoIndices& d : input.draco_indices) {
    if (size_t(d.mesh) < model.meshes.size() &&
        size_t(d.primitive) < model.meshes[size_t(d.mesh)].primitives.size())
      model.meshes[size_t(d.mesh)].primitives[size_t(d.primitive)].indices = d.accessor;
  }
}

}  // namespace snow

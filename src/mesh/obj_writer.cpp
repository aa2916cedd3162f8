// Wavefront OBJ and MTL (Wavefront Technologies, "Object Files (.obj)" and
// "Material Library Files (.mtl)", Advanced Visualizer manual, appendices
// B1 and B2; PBR keys Pr/Pm after the Exocortex/Clara.io extension that
// Blender's importer reads).
#include "mesh/obj_writer.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <string>

#include "core/fs.h"

namespace snow {
namespace {

void append_number(std::string& out, float v) {
  char buf[32];
  if (!std::isfinite(v)) v = 0.0f;
  const auto result = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::general, 9);
  out.append(buf, result.ptr);
}

void append_index(std::string& out, size_t v) {
  char buf[24];
  const auto result = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, result.ptr);
}

std::string object_name(const std::string& name, size_t index) {
  std::string out = name.empty() ? "mesh" + std::to_string(index) : name;
  for (char& c : out) {
    if (std::isspace(static_cast<unsigned char>(c)) || c == '#') c = '_';
  }
  return out;
}

std::string material_library(const MeshMaterial& m, const std::string& name) {
  auto num = [](float v) {
    std::string s;
    append_number(s, v);
    return s;
  };
  const glm::vec3 kd = glm::clamp(glm::vec3(m.base_color), 0.0f, 1.0f);
  const float roughness = std::clamp(m.roughness, 0.0f, 1.0f);
  // Blinn-Phong exponent matching the roughness (Ns = 2 / alpha^2 - 2 with
  // alpha = roughness^2), clamped to the usual 0..1000.
  const float alpha = std::max(roughness * roughness, 1e-3f);
  const float ns = std::clamp(2.0f / (alpha * alpha) - 2.0f, 0.0f, 1000.0f);
  std::string out = "# snowmodel material\nnewmtl " + name + "\n";
  out += "Ka 0 0 0\n";
  out += "Kd " + num(kd.r) + " " + num(kd.g) + " " + num(kd.b) + "\n";
  out += "Ks 0.04 0.04 0.04\n";
  out += "Ns " + num(ns) + "\n";
  out += "d " + num(std::clamp(m.base_color.a, 0.0f, 1.0f)) + "\n";
  out += "illum 2\n";
  out += "Pr " + num(roughness) + "\n";
  out += "Pm " + num(std::clamp(m.metallic, 0.0f, 1.0f)) + "\n";
  return out;
}

}  // namespace

void write_obj(const std::vector<TriMesh>& meshes, const MeshMaterial& material,
               const std::filesystem::path& path) {
  const std::string material_name = object_name(material.name, 0);
  std::filesystem::path mtl_path = path;
  mtl_path.replace_extension(".mtl");

  std::string out = "# snowmodel snow meshes (metres, +Y up)\nmtllib ";
  out += mtl_path.filename().string();
  out += "\n";
  size_t base_v = 1, base_vt = 1, base_vn = 1;
  for (size_t m = 0; m < meshes.size(); ++m) {
    const TriMesh& mesh = meshes[m];
    if (mesh.indices.size() < 3 || mesh.positions.empty()) continue;
    const bool has_uv = mesh.uvs.size() == mesh.positions.size();
    const bool has_n = mesh.normals.size() == mesh.positions.size();
    out += "o " + object_name(mesh.name, m) + "\n";
    for (const glm::vec3& p : mesh.positions) {
      out += "v ";
      append_number(out, p.x);
      out += ' ';
      append_number(out, p.y);
      out += ' ';
      append_number(out, p.z);
      out += '\n';
    }
    if (has_uv) {
      for (const glm::vec2& t : mesh.uvs) {
        out += "vt ";
        append_number(out, t.x);
        out += ' ';
        append_number(out, t.y);
        out += '\n';
      }
    }
    if (has_n) {
      for (const glm::vec3& n : mesh.normals) {
        out += "vn ";
        append_number(out, n.x);
        out += ' ';
        append_number(out, n.y);
        out += ' ';
        append_number(out, n.z);
        out += '\n';
      }
    }
    out += "usemtl " + material_name + "\n";
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      out += 'f';
      for (int c = 0; c < 3; ++c) {
        const size_t i = mesh.indices[t + size_t(c)];
        out += ' ';
        append_index(out, base_v + i);
        if (has_uv || has_n) {
          out += '/';
          if (has_uv) append_index(out, base_vt + i);
          if (has_n) {
            out += '/';
            append_index(out, base_vn + i);
          }
        }
      }
      out += '\n';
    }
    base_v += mesh.positions.size();
    if (has_uv) base_vt += mesh.uvs.size();
    if (has_n) base_vn += mesh.normals.size();
  }
  write_text_atomically(mtl_path, material_library(material, material_name));
  write_text_atomically(path, out);
}

}  // namespace snow

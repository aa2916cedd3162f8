// Binary PLY (Greg Turk, "The PLY Polygon File Format", 1994), with the
// vertex property names that Blender, MeshLab and Open3D read (nx ny nz for
// normals, s t for texture coordinates).
#include "mesh/ply_writer.h"

#include <cstdint>
#include <cstring>
#include <string>

#include "core/fs.h"

namespace snow {
namespace {

void put_u32(std::string& out, uint32_t v) {
  const char b[4] = {char(v & 0xffu), char((v >> 8) & 0xffu), char((v >> 16) & 0xffu),
                     char((v >> 24) & 0xffu)};
  out.append(b, 4);
}

void put_f32(std::string& out, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof(bits));
  put_u32(out, bits);
}

}  // namespace

void write_ply(const std::vector<TriMesh>& meshes, const std::filesystem::path& path) {
  size_t vertices = 0, faces = 0;
  std::string comments;
  for (const TriMesh& m : meshes) {
    std::string name = m.name.empty() ? "mesh" : m.name;
    for (char& c : name) {
      if (c == '\n' || c == '\r') c = ' ';
    }
    comments += "comment mesh " + name + " faces " + std::to_string(faces) + " " +
                std::to_string(m.indices.size() / 3) + "\n";
    vertices += m.positions.size();
    faces += m.indices.size() / 3;
  }
  std::string out =
      "ply\nformat binary_little_endian 1.0\ncomment snowmodel snow meshes (metres, +Y up)\n";
  out += comments;
  out += "element vertex " + std::to_string(vertices) + "\n";
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "s", "t"}) {
    out += std::string("property float ") + p + "\n";
  }
  out += "element face " + std::to_string(faces) + "\n";
  out += "property list uchar uint vertex_indices\nend_header\n";
  out.reserve(out.size() + vertices * 32 + faces * 13);
  for (const TriMesh& m : meshes) {
    const bool has_n = m.normals.size() == m.positions.size();
    const bool has_uv = m.uvs.size() == m.positions.size();
    for (size_t v = 0; v < m.positions.size(); ++v) {
      const glm::vec3 n = has_n ? m.normals[v] : glm::vec3(0, 1, 0);
      const glm::vec2 t = has_uv ? m.uvs[v] : glm::vec2(0);
      for (float f :
           {m.positions[v].x, m.positions[v].y, m.positions[v].z, n.x, n.y, n.z, t.x, t.y}) {
        put_f32(out, f);
      }
    }
  }
  uint32_t base = 0;
  for (const TriMesh& m : meshes) {
    for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
      out += char(3);
      for (int c = 0; c < 3; ++c) put_u32(out, base + m.indices[t + size_t(c)]);
    }
    base += uint32_t(m.positions.size());
  }
  write_bytes_atomically(path, out.data(), out.size());
}

}  // namespace snow

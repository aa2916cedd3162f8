#pragma once
// Shader programs built from the sources embedded at build time (shaders/).
// Shader files may `#include "name"` another file of shaders/ (one level,
// e.g. the binding header shared with C++); the loader splices it in after
// the #version line.
#include <initializer_list>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "gl/objects.h"

namespace snow::gl {

/// Source text of an embedded shader file, e.g. "peel.frag".
/// Throws GLError if there is no such file.
const std::string& shader_source(const std::string& name);

/// `source` with every `#include "file"` line replaced by that embedded file
/// (nested includes too, up to 8 deep), wrapped in #line directives so the
/// driver's log line numbers stay right. `name` is used in errors.
std::string resolve_includes(const std::string& name, const std::string& source);

class Program {
 public:
  Program() = default;
  /// Compiles and links the named files; the stage comes from the extension
  /// (.vert .geom .frag .comp). Throws GLError naming the file with the
  /// driver's log on a compile or link error.
  explicit Program(std::initializer_list<std::string> files);

  /// Same from source text given here: (file name, source) pairs, the stage
  /// from each name's extension, `#include` resolved against the embedded
  /// files. For tests and tools; passes use the embedded files.
  static Program from_sources(const std::vector<std::pair<std::string, std::string>>& sources);

  /// "peel.vert+peel.frag": the files the program was built from.
  const std::string& name() const { return name_; }

  GLuint id() const { return handle_.id(); }
  void use() const { glUseProgram(handle_.id()); }

  /// Uniform setters by name (cached location; unknown names are ignored,
  /// since drivers drop unused uniforms).
  void set(const char* name, int v) const;
  void set(const char* name, float v) const;
  void set(const char* name, const glm::vec2& v) const;
  void set(const char* name, const glm::vec3& v) const;
  void set(const char* name, const glm::vec4& v) const;
  void set(const char* name, const glm::ivec2& v) const;
  void set(const char* name, const glm::mat4& v) const;
  void set(const char* name, const glm::mat3& v) const;

  /// Cached glGetUniformLocation; -1 for unknown (or optimised-out) names.
  GLint uniform_location(const char* name) const;

 private:
  ProgramHandle handle_;
  std::string name_;
  mutable std::unordered_map<std::string, GLint> locations_;
};

}  // namespace snow::gl

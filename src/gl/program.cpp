// Shader programs from the embedded shaders/ files.
#include "gl/program.h"

#include <glm/gtc/type_ptr.hpp>
#include <sstream>

#include "core/error.h"
#include "gl/shader_sources.h"

namespace snow::gl {
namespace {

constexpr int kMaxIncludeDepth = 8;

GLenum stage_from_name(const std::string& name) {
  const size_t dot = name.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : name.substr(dot + 1);
  if (ext == "vert") return GL_VERTEX_SHADER;
  if (ext == "frag") return GL_FRAGMENT_SHADER;
  if (ext == "comp") return GL_COMPUTE_SHADER;
  if (ext == "geom") return GL_GEOMETRY_SHADER;
  if (ext == "tesc") return GL_TESS_CONTROL_SHADER;
  if (ext == "tese") return GL_TESS_EVALUATION_SHADER;
  throw GLError(name + ": unknown shader stage (use .vert .frag .comp .geom .tesc .tese)");
}

// First non-empty line of a driver log, for one-line error messages.
std::string first_line(const std::string& log) {
  std::istringstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) return line;
  }
  return "(no driver log)";
}

std::string shader_log(GLuint shader) {
  GLint length = 0;
  glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<size_t>(length > 0 ? length : 0), '\0');
  if (length > 0) glGetShaderInfoLog(shader, length, nullptr, log.data());
  while (!log.empty() && log.back() == '\0') log.pop_back();
  return log;
}

std::string program_log(GLuint program) {
  GLint length = 0;
  glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<size_t>(length > 0 ? length : 0), '\0');
  if (length > 0) glGetProgramInfoLog(program, length, nullptr, log.data());
  while (!log.empty() && log.back() == '\0') log.pop_back();
  return log;
}

// Parses `#include "file"` (spaces allowed); returns false for other lines.
bool parse_include(const std::string& line, std::string* file) {
  size_t i = line.find_first_not_of(" \t");
  if (i == std::string::npos || line[i] != '#') return false;
  i = line.find_first_not_of(" \t", i + 1);
  if (i == std::string::npos || line.compare(i, 7, "include") != 0) return false;
  const size_t open = line.find('"', i + 7);
  const size_t close = open == std::string::npos ? open : line.find('"', open + 1);
  if (close == std::string::npos) return false;
  *file = line.substr(open + 1, close - open - 1);
  return true;
}

std::string resolve(const std::string& name, const std::string& source, int depth,
                    int* next_string) {
  if (depth > kMaxIncludeDepth) {
    throw GLError(name + ": #include nested deeper than " + std::to_string(kMaxIncludeDepth));
  }
  const int this_string = (*next_string)++;
  std::istringstream in(source);
  std::string out;
  std::string line;
  std::string file;
  int line_number = 0;
  bool seen_version = false;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find("#version") != std::string::npos) seen_version = true;
    if (parse_include(line, &file)) {
      if (depth == 0 && !seen_version) {
        throw GLError(name + ":" + std::to_string(line_number) + ": #include before #version");
      }
      const int included_string = *next_string;
      out += "#line 1 " + std::to_string(included_string) + "\n";
      out += resolve(file, shader_source(file), depth + 1, next_string);
      out += "#line " + std::to_string(line_number + 1) + " " + std::to_string(this_string) + "\n";
    } else {
      out += line;
      out += '\n';
    }
  }
  return out;
}

GLuint compile(const std::string& name, const std::string& source) {
  const GLenum stage = stage_from_name(name);
  const std::string text = resolve_includes(name, source);
  const GLuint shader = glCreateShader(stage);
  if (!shader) throw GLError(name + ": glCreateShader failed");
  const char* ptr = text.c_str();
  glShaderSource(shader, 1, &ptr, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    const std::string log = shader_log(shader);
    glDeleteShader(shader);
    throw GLError(name + ": compile error: " + first_line(log), log);
  }
  return shader;
}

}  // namespace

const std::string& shader_source(const std::string& name) {
  const auto& sources = embedded_shader_sources();
  const auto it = sources.find(name);
  if (it == sources.end()) throw GLError("no embedded shader file '" + name + "'");
  return it->second;
}

std::string resolve_includes(const std::string& name, const std::string& source) {
  int next_string = 0;
  return resolve(name, source, 0, &next_string);
}

Program Program::from_sources(const std::vector<std::pair<std::string, std::string>>& sources) {
  Program program;
  for (const auto& [file, text] : sources) {
    if (!program.name_.empty()) program.name_ += "+";
    program.name_ += file;
  }
  if (sources.empty()) throw GLError("shader program with no files");

  std::vector<GLuint> shaders;
  try {
    for (const auto& [file, text] : sources) shaders.push_back(compile(file, text));
  } catch (...) {
    for (GLuint s : shaders) glDeleteShader(s);
    throw;
  }
  program.handle_ = ProgramHandle(glCreateProgram());
  const GLuint id = program.handle_.id();
  for (GLuint s : shaders) glAttachShader(id, s);
  glLinkProgram(id);
  for (GLuint s : shaders) {
    glDetachShader(id, s);
    glDeleteShader(s);
  }
  GLint ok = GL_FALSE;
  glGetProgramiv(id, GL_LINK_STATUS, &ok);
  if (!ok) {
    const std::string log = program_log(id);
    throw GLError(program.name_ + ": link error: " + first_line(log), log);
  }
  return program;
}

Program::Program(std::initializer_list<std::string> files) {
  std::vector<std::pair<std::string, std::string>> sources;
  for (const std::string& file : files) sources.emplace_back(file, shader_source(file));
  *this = from_sources(sources);
}

GLint Program::uniform_location(const char* name) const {
  const auto it = locations_.find(name);
  if (it != locations_.end()) return it->second;
  const GLint location = glGetUniformLocation(handle_.id(), name);
  locations_.emplace(name, location);
  return location;
}

void Program::set(const char* name, int v) const {
  glProgramUniform1i(handle_.id(), uniform_location(name), v);
}
void Program::set(const char* name, float v) const {
  glProgramUniform1f(handle_.id(), uniform_location(name), v);
}
void Program::set(const char* name, const glm::vec2& v) const {
  glProgramUniform2fv(handle_.id(), uniform_location(name), 1, glm::value_ptr(v));
}
void Program::set(const char* name, const glm::vec3& v) const {
  glProgramUniform3fv(handle_.id(), uniform_location(name), 1, glm::value_ptr(v));
}
void Program::set(const char* name, const glm::vec4& v) const {
  glProgramUniform4fv(handle_.id(), uniform_location(name), 1, glm::value_ptr(v));
}
void Program::set(const char* name, const glm::ivec2& v) const {
  glProgramUniform2iv(handle_.id(), uniform_location(name), 1, glm::value_ptr(v));
}
void Program::set(const char* name, const glm::mat4& v) const {
  glProgramUniformMatrix4fv(handle_.id(), uniform_location(name), 1, GL_FALSE, glm::value_ptr(v));
}
void Program::set(const char* name, const glm::mat3& v) const {
  glProgramUniformMatrix3fv(handle_.id(), uniform_location(name), 1, GL_FALSE, glm::value_ptr(v));
}

}  // namespace snow::gl

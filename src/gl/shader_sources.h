#pragma once
#include <map>
#include <string>

namespace snow::gl {
/// File name (e.g. "peel.frag") -> source, embedded by cmake/EmbedShaders.cmake.
const std::map<std::string, std::string>& embedded_shader_sources();
}  // namespace snow::gl

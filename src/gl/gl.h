#pragma once
// The one include for GL calls. Only files in src/gl, src/render and the GPU
// pass files (src/snow/*.cpp) include it.
#include <glad/gl.h>

#include <string>

namespace snow::gl {

/// Throws GLError("<what>: GL_OUT_OF_MEMORY ...") if glGetError reports an
/// error. Call after allocations and at the end of each pass.
void check_error(const char* what);

}  // namespace snow::gl

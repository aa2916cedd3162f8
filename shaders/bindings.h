// Binding slots and vertex attribute locations shared by C++ and GLSL.
// Included by C++ as "shaders/bindings.h" and by shaders as
// `#include "bindings.h"` (spliced in by snow::gl::Program after #version).
// Plain #defines so that both languages read the same numbers and GLSL 4.30
// can use them in layout() qualifiers. One block per pass; slots only need
// to be unique within a pass.
#ifndef SNOW_SHADERS_BINDINGS_H
#define SNOW_SHADERS_BINDINGS_H

// --- Vertex attributes (every pass drawing scene triangles) ---------------
#define SNOW_ATTR_POSITION 0  // vec3, metres, world space
#define SNOW_ATTR_NORMAL 1    // vec3, world space
#define SNOW_ATTR_UV 2        // vec2, glTF TEXCOORD_0

// --- Preview renderer (preview.vert/.frag) --------------------------------
#define SNOW_PREVIEW_BASE_COLOR_TEXTURE 0  // sampler2D, sRGB baseColor
#define SNOW_PREVIEW_UBO 0                 // uniform block PreviewFrame

#endif  // SNOW_SHADERS_BINDINGS_H

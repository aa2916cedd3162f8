// Preview renderer (src/render/preview.cpp): world-space triangles to clip space.
#version 430 core
#include "bindings.h"

layout(location = SNOW_ATTR_POSITION) in vec3 a_position;  // world, metres
layout(location = SNOW_ATTR_NORMAL) in vec3 a_normal;      // world
layout(location = SNOW_ATTR_UV) in vec2 a_uv;              // TEXCOORD_0

uniform mat4 u_view_projection;

out vec3 v_position;
out vec3 v_normal;
out vec2 v_uv;

void main() {
  v_position = a_position;
  v_normal = a_normal;
  v_uv = a_uv;
  gl_Position = u_view_projection * vec4(a_position, 1.0);
}

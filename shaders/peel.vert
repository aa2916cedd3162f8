#version 450 core
// Depth peeling from straight above (src/snow/peel/gpu.cpp): orthographic camera
// looking down -Y over the map grid; depth grows downwards from y_top.
#include "bindings.h"

layout(location = SNOW_ATTR_POSITION) in vec3 position;

uniform vec2 grid_origin;  // world (x, z) of the grid's corner, metres
uniform vec2 grid_extent;  // grid size in metres (width * texel, height * texel)
uniform float y_top;       // metres, maps to depth 0
uniform float y_range;     // metres, y_top - y_range maps to depth 1

out float v_height;

void main() {
  vec2 uv = (position.xz - grid_origin) / grid_extent;
  gl_Position = vec4(uv * 2.0 - 1.0, (y_top - position.y) / y_range * 2.0 - 1.0, 1.0);
  v_height = position.y;
}

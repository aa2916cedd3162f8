#version 450 core
// Shadow map along one fall direction d (src/snow/coverage/gpu.cpp): an
// orthographic projection along d onto the horizontal plane (a shear:
// u = x - y * d.x/d.y, v = z - y * d.z/d.y), so that shadow texels line up
// with the snow map's; depth grows downwards from y_top, so the depth test
// keeps the highest surface along each line of fall.
#include "bindings.h"

layout(location = SNOW_ATTR_POSITION) in vec3 position;

uniform vec4 shear_origin;  // (a = d.x/d.y, b = d.z/d.y, u0, v0): u0, v0 metres
uniform vec2 map_extent;    // metres covered by the whole shadow map in u and v
uniform float y_top;        // metres, maps to depth 0
uniform float y_range;      // metres, y_top - y_range maps to depth 1


void main() {
  vec2 uv = vec2(position.x - shear_origin.z - position.y * shear_origin.x,
                 position.z - shear_origin.w - position.y * shear_origin.y);
  gl_Position = vec4(uv / map_extent * 2.0 - 1.0, (y_top - position.y) / y_range * 2.0 - 1.0, 1.0);
}

#version 450 core
// The snow surface of one layer (ground + depth) drawn into a shadow map as
// a heightfield through the texel centres, with no vertex buffer: vertex
// gl_VertexID is corner (gl_VertexID % 6) of quad quad_origin + (q %
// quad_columns, q / quad_columns), q = gl_VertexID / 6 (the draw covers the
// layer's snowy quads only).
// Mirrors snow::reference::snow_surface_triangles: a triangle exists when its
// three corners have a surface, one has snow, and their heights differ by at
// most `cut`; otherwise all its corners go outside the clip volume.
#include "bindings.h"

layout(binding = SNOW_SHADOW_SNOW_TEXTURE) uniform sampler2DArray snow_surface;  // (top, depth)

uniform int layer;
uniform ivec2 quad_origin;  // first quad of the drawn rectangle
uniform int quad_columns;   // quads per row of the drawn rectangle
uniform vec2 grid_origin;   // metres
uniform float texel;        // metres
uniform float cut;          // metres
uniform vec4 shear_origin;  // as in shadow.vert
uniform vec2 map_extent;
uniform float y_top;
uniform float y_range;


const ivec2 kCorner[4] = ivec2[](ivec2(0, 0), ivec2(1, 0), ivec2(1, 1), ivec2(0, 1));
const int kTriangleCorner[6] = int[](0, 1, 2, 0, 2, 3);

void main() {
  int quad = gl_VertexID / 6;
  int corner = gl_VertexID % 6;
  ivec2 ij = quad_origin + ivec2(quad % quad_columns, quad / quad_columns);
  int first = corner < 3 ? 0 : 3;
  bool ok = true;
  bool snowy = false;
  float lo = 3.0e38, hi = -3.0e38;
  for (int c = 0; c < 3; ++c) {
    vec2 s = texelFetch(snow_surface, ivec3(ij + kCorner[kTriangleCorner[first + c]], layer), 0).xy;
    ok = ok && s.x > -1.0e38;
    snowy = snowy || s.y > 0.0;
    lo = min(lo, s.x);
    hi = max(hi, s.x);
  }
  if (!ok || !snowy || hi - lo > cut) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    return;
  }
  ivec2 me = ij + kCorner[kTriangleCorner[corner]];
  float y = texelFetch(snow_surface, ivec3(me, layer), 0).x;
  vec2 xz = grid_origin + (vec2(me) + 0.5) * texel;
  vec2 uv = vec2(xz.x - shear_origin.z - y * shear_origin.x,
                 xz.y - shear_origin.w - y * shear_origin.y);
  gl_Position = vec4(uv / map_extent * 2.0 - 1.0, (y_top - y) / y_range * 2.0 - 1.0, 1.0);
}

// Live preview falling flakes (src/live/snow_view.cpp): a visual cue only.
// Point gl_VertexID falls through the box at the fall speed, drifts with the
// wind and flutters; its place is a hash of its id and the simulated time,
// so nothing is stored between frames.
#version 430 core

uniform mat4 u_view_projection;
uniform vec3 u_box_min;     // metres
uniform vec3 u_box_max;     // metres
uniform float u_time;       // simulated seconds
uniform float u_fall_speed; // m/s
uniform vec2 u_wind;        // m/s along x, z
uniform float u_flutter;    // metres of sideways flutter
uniform float u_point_size; // pixels

float hash(uint x) {
  x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
  return float(x) * (1.0 / 4294967296.0);
}

void main() {
  uint id = uint(gl_VertexID);
  vec3 size = max(u_box_max - u_box_min, vec3(1e-3));
  float h1 = hash(id * 4u), h2 = hash(id * 4u + 1u), h3 = hash(id * 4u + 2u),
        h4 = hash(id * 4u + 3u);
  float speed = u_fall_speed * (0.8 + 0.4 * h4);
  float fallen = fract(h3 + u_time * speed / size.y) * size.y;  // metres below the top
  float t = fallen / speed;                                      // seconds since it left the top
  vec2 xz = vec2(h1, h2) * size.xz + u_wind * t +
            u_flutter * vec2(sin(u_time * 1.7 + h1 * 40.0), cos(u_time * 1.3 + h2 * 40.0));
  xz = u_box_min.xz + mod(xz, size.xz);
  gl_Position = u_view_projection * vec4(xz.x, u_box_max.y - fallen, xz.y, 1.0);
  gl_PointSize = u_point_size;
}

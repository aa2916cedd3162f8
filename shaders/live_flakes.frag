// Live preview falling flakes (src/live/snow_view.cpp): plain white points.
#version 430 core

layout(location = 0) out vec4 o_color;

void main() { o_color = vec4(0.97, 0.98, 1.0, 1.0); }

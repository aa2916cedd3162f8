// Binding slots of the live preview's passes (live_*.vert/.frag,
// src/live/snow_view.cpp), shared by C++ ("shaders/live_bindings.h") and
// GLSL (#include "live_bindings.h"), like bindings.h.
#ifndef SNOW_SHADERS_LIVE_BINDINGS_H
#define SNOW_SHADERS_LIVE_BINDINGS_H

#define SNOW_LIVE_GROUND 0    // sampler2DArray RG32F per map layer: ground (m), 1 where a surface
#define SNOW_LIVE_DEPTH 1     // sampler2DArray RG32F: the stabilizer's depth (m) in r
#define SNOW_LIVE_COVERAGE 2  // sampler2DArray R32F: coverage in [0,1]

#endif  // SNOW_SHADERS_LIVE_BINDINGS_H

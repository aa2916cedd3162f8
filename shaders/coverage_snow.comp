#version 450 core
// Coverage count pass with a snow surface in the shadow maps (see coverage_common.glsl).
#define COVERAGE_SNOW 1
#include "coverage_count.glsl"

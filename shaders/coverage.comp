#version 450 core
// Coverage count pass (see coverage_common.glsl).
#define COVERAGE_SNOW 0
#include "coverage_count.glsl"

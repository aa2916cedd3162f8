#version 450 core
// Coverage exact pass (see coverage_common.glsl).
#define COVERAGE_SNOW 0
#include "coverage_exact.glsl"

#version 450 core
// Coverage exact pass with a snow surface in the shadow maps (see coverage_common.glsl).
#define COVERAGE_SNOW 1
#include "coverage_exact.glsl"

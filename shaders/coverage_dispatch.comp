#version 450 core
// Turns the uncertain-pair count of pass 1 into the indirect dispatch size
// of the exact pass (one invocation; items are strided past 65535 groups).
#include "bindings.h"

layout(local_size_x = 1) in;

layout(std430, binding = SNOW_COVERAGE_QUEUE) readonly buffer Queue { uint queue_count; };
layout(std430, binding = SNOW_COVERAGE_DISPATCH) writeonly buffer Dispatch { uvec4 groups; };

void main() { groups = uvec4(clamp((queue_count + 63u) / 64u, 1u, 65535u), 1u, 1u, 0u); }

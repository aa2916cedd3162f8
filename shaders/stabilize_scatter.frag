#version 450 core
// Steep routing, scatter: the routed amount, blended additively.
flat in float g_amount;
layout(location = 0) out vec4 o_arrive;
void main() { o_arrive = vec4(g_amount, 0.0, 0.0, 0.0); }

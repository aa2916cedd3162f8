#version 450 core
// Depth only (benchmark of the raw rasterization work, snow::time_depth_passes).
void main() {}

#version 450 core
// Depth only: the shadow maps need no colour.
void main() {}

// Coverage counting, pass 1 of 2 (see coverage_common.glsl): per receiver,
// over the batch's directions, adds the certainly lit ones to its count and
// queues the receiver with a mask of its uncertain directions for
// coverage_exact (one atomic per receiver, not per direction). No exact test here: a
// software rasterizer runs every branch of a shader, so the rare expensive
// path lives in its own pass over a compact queue.
#include "coverage_common.glsl"

layout(local_size_x = 64) in;

uniform int first_receiver;
uniform int receiver_count;

void main() {
  int id = first_receiver + int(gl_GlobalInvocationID.x);
  if (id >= receiver_count) return;
  Receiver rc = load_receiver(uint(id));
  uint lit = 0u;
  uint uncertain = 0u;
  for (int k = 0; k < direction_count; ++k) {
    int state = classify(rc, k);
    if (state == 0) ++lit;
    if (state == 2) uncertain |= 1u << uint(k);
  }
  counts[id] += lit;
  if (uncertain != 0u) queue[atomicAdd(queue_count, 1u)] = uvec2(uint(id), uncertain);
}

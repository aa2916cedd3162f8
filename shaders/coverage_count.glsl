// Coverage counting, pass 1 of 2 (see coverage_common.glsl): per receiver,
// over the batch's directions, adds the certainly lit ones to its count and
// queues the uncertain ones for coverage_exact. No exact test here: a
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
  for (int k = 0; k < direction_count; ++k) {
    int state = classify(rc, k);
    if (state == 0) ++lit;
    if (state == 2) queue[atomicAdd(queue_count, 1u)] = (uint(id) << 6) | uint(k);
  }
  counts[id] += lit;
}

#pragma once
// A minimal parallel loop for the CPU stages (sky culling, meshing): the
// machines this runs on may have 2 cores and no GPU, so CPU work uses them all.
#include <cstddef>
#include <functional>

namespace snow {

/// Worker threads parallel_for uses by default: one per hardware thread, 1..32.
unsigned default_threads();

/// Calls fn(i) once for every i in [0, count), on up to `threads` threads
/// (0 = default_threads()), handing out indices in order as threads become
/// free; returns when all calls have returned. If calls throw, the remaining
/// indices are skipped and the first exception is rethrown here. fn must be
/// safe to call concurrently for different i.
void parallel_for(size_t count, const std::function<void(size_t)>& fn, unsigned threads = 0);

}  // namespace snow

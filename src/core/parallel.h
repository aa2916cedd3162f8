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

/// parallel_for over [0, count) cut into ranges of `chunk` indices (the last
/// one shorter; a chunk of 0 is taken as 1): fn(begin, end) once per range.
void parallel_for_ranges(size_t count, size_t chunk,
                         const std::function<void(size_t begin, size_t end)>& fn,
                         unsigned threads = 0);

/// The sum of part(begin, end) over the ranges of parallel_for_ranges: the
/// parts on all cores, then added in range order, so the result is the same
/// bits on any number of threads.
double parallel_sum(size_t count, size_t chunk,
                    const std::function<double(size_t begin, size_t end)>& part);

}  // namespace snow

#pragma once
// Heap settings for the pipeline's large blocks: transparent huge pages and
// glibc's mmap threshold.
//
// Transparent huge pages for the heap. The pipeline allocates and first
// touches gigabytes in large blocks (maps, stabilizer arrays, meshes, and
// llvmpipe's textures and framebuffers, which Mesa takes from malloc); with
// 4 KiB pages much of its time went to page faults and TLB misses (1M
// terrain at 2048 texels, AMD EPYC, llvmpipe: 17.8 s with 4 KiB pages,
// 10.7 s with huge pages, same bytes out; tools/RESULTS.md). glibc (2.35 and
// later) backs its heap with transparent huge pages when its tunable
// glibc.malloc.hugetlb is 1, but reads tunables only at program start, from
// the environment: so the program re-executes itself once with it added to
// GLIBC_TUNABLES. (snowmodel's launcher, src/app/launcher.c, sets it before
// starting snowmodel-core, which saves that second start.)
//
// Large jobs on a virtual machine that hands its free memory back to the
// host turn them off again (fit_huge_pages): there a huge page that was not
// freed just before faults in the host as well, and costs more than small
// pages do.
//
// The mmap threshold: glibc gives each block over it a mapping of its own
// and unmaps it when freed, so the next such block faults in fresh pages
// again (about 3 ms per MB on a virtual machine), and those mappings get
// huge pages only where they happen to align. Its default threshold starts
// at 128 KiB and rises only as such blocks are freed. Blocks up to 32 MiB
// (the most that dynamic threshold reaches) come from the heap instead,
// reused once freed. ToyCar (109k triangles), one process with huge pages:
// 0.091-0.11 -> 0.057-0.077 s; Kenney tiles and SheenChair 10-30 ms less;
// peak memory the same to 5 % more (the 10k terrain 311 -> 325-330 MiB).
#include <cstddef>
#include <cstdint>
#include <string>

namespace snow {

/// Call first thing in main, before any thread starts. Sets glibc's mmap
/// threshold to 32 MiB unless GLIBC_TUNABLES names glibc.malloc.mmap_threshold
/// (the user's choice). Then, unless GLIBC_TUNABLES already names
/// glibc.malloc.hugetlb (the user's choice: glibc.malloc.hugetlb=0 turns
/// huge pages off), adds glibc.malloc.hugetlb=1 to it and re-executes
/// /proc/self/exe with the same arguments. Returns only when there is
/// nothing to do or the re-execution failed (then the program goes on with
/// the usual pages). Does not re-execute where glibc has no such tunable or
/// ignores tunables (setuid). Re-executes at most once: the new process
/// finds the marker SNOWMODEL_HUGE_PAGES_REEXEC=1 in its environment and
/// removes it.
void tune_heap(char** argv);

/// One line for `snowmodel info`: whether this process asked glibc for huge
/// pages, whether the kernel's transparent huge pages allow them, and
/// whether large jobs turn them off (fit_huge_pages).
std::string huge_pages_status();
/// One line for `snowmodel info`: the mmap threshold this process set, or
/// why it set none.
std::string mmap_threshold_status();

/// Where the kernel lists its virtio devices.
inline constexpr const char* kVirtioDevices = "/sys/bus/virtio/devices";

/// Whether this (virtual) machine hands its free memory back to the host in
/// 2 MiB blocks: a memory balloon (virtio device 5) bound to its driver
/// with free page reporting (VIRTIO_BALLOON_F_REPORTING, feature bit 5)
/// among the features it negotiated, under `devices` (each device's
/// `features` file holds one '0' or '1' per bit, bit 0 first). The kernel
/// reports free blocks of 2 MiB about 2 s after they are freed and the host
/// drops them; a huge page is such a block, so a huge page that was not
/// freed just before faults in the host too. On such a machine (2-core
/// Intel Xeon VM, Firecracker kernel) touching a fresh 1 GiB took 2.9-3.2 s
/// in huge pages and 0.5-1.1 s in 4 KiB pages (0.2-0.3 and 0.4 s when the
/// same memory had just been freed).
bool free_pages_reported(const char* devices = kVirtioDevices);

/// A large job: maps of this many texel columns (512 x 512) or more (about
/// 75 MiB and up), or an input of this many bytes or more (its load alone
/// takes about 2.5 times that: the 1M-triangle terrain's 84 MB, 204 MiB).
inline constexpr size_t kLargeJobColumns = size_t(512) * 512;
inline constexpr uint64_t kLargeJobInputBytes = uint64_t(32) << 20;

/// Call as soon as a job's size is known, with what is known of it
/// (`input_bytes`: the input's bytes, gltf_input_bytes; `columns`: texel
/// columns of its maps; 0 where not known yet). Where the heap has huge
/// pages because tune_heap (or snowmodel's launcher) asked for them, not
/// the user's GLIBC_TUNABLES, the machine hands free memory back to its
/// host (free_pages_reported) and the job is large (kLargeJobColumns,
/// kLargeJobInputBytes), turns transparent huge pages off for the rest of
/// the process (prctl PR_SET_THP_DISABLE; the pages it has keep their size)
/// and returns true, once. A small job mostly takes memory another process
/// freed just before, whose huge pages come cheap; a large one needs more
/// than that, fresh from the host. On the Xeon VM above, with huge pages
/// against without: ToyCar 41 / 46 ms, Kenney tiles 146-221 / 152-230 ms
/// (medians of 20); the courtyard 2.6-3.1 / 2.2-2.7 s, the 1M terrain at
/// 2048 texels 4.2-5.1 / 3.3-3.6 s, and at 256 texels 0.71-0.95 / 0.60-0.63
/// s (tools/RESULTS.md, session 31).
bool fit_huge_pages(uint64_t input_bytes, size_t columns);

}  // namespace snow

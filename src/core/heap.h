#pragma once
// Heap settings for the pipeline's large blocks: transparent huge pages and
// glibc's mmap threshold.
//
// Transparent huge pages for the heap. The pipeline allocates and first touches
// gigabytes in large blocks (maps, stabilizer arrays, meshes, and llvmpipe's
// textures and framebuffers, which Mesa takes from malloc); with 4 KiB pages
// much of its time goes to page faults and TLB misses (huge pages change the
// speed only, never the bytes out; tools/RESULTS.md). glibc (2.35 and later)
// backs its heap with transparent huge pages when its tunable
// glibc.malloc.hugetlb is 1, but reads tunables only at program start, from the
// environment: so the program re-executes itself once with it added to
// GLIBC_TUNABLES. (snowmodel's launcher, src/app/launcher.c, sets it before
// starting snowmodel-core, which saves that second start.)
//
// Large jobs on a virtual machine that hands its free memory back to the host
// turn them off again (turn_off_huge_pages): there a huge page that was not
// freed just before faults in the host as well, and costs more than small pages
// do.
//
// The mmap threshold: glibc gives each block over it a mapping of its own and
// unmaps it when freed, so the next such block faults in fresh pages again, and
// those mappings get huge pages only where they happen to align. Its default
// threshold starts at 128 KiB and rises only as such blocks are freed. Blocks
// up to 32 MiB (the most that dynamic threshold reaches) come from the heap
// instead, reused once freed: faster for small and mid-sized scenes, for a few
// per cent more peak memory at most (tools/RESULTS.md).
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
/// whether large jobs turn them off (plan::huge_pages_off).
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
/// reports free blocks of 2 MiB shortly after they are freed and the host
/// drops them; a huge page is such a block, so a huge page that was not
/// freed just before faults in the host too, and touching fresh memory
/// there costs more in huge pages than in 4 KiB pages (tools/RESULTS.md).
bool free_pages_reported(const char* devices = kVirtioDevices);

/// Where the heap has huge pages because tune_heap (or snowmodel's launcher)
/// asked for them, not the user's GLIBC_TUNABLES, turns transparent huge
/// pages off for the rest of the process (prctl PR_SET_THP_DISABLE; the
/// pages it has keep their size) and returns true, once. The planner
/// decides when (plan::huge_pages_off: a large job on a machine that hands
/// free memory back to its host, where a large job's fresh memory is
/// cheaper in small pages; a small job mostly takes memory another process
/// freed just before, whose huge pages come cheap).
bool turn_off_huge_pages();

}  // namespace snow

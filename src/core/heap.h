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
// The mmap threshold: glibc gives each block over it a mapping of its own
// and unmaps it when freed, so the next such block faults in fresh pages
// again (about 3 ms per MB on a virtual machine), and those mappings get
// huge pages only where they happen to align. Its default threshold starts
// at 128 KiB and rises only as such blocks are freed. Blocks up to 32 MiB
// (the most that dynamic threshold reaches) come from the heap instead,
// reused once freed. ToyCar (109k triangles), one process with huge pages:
// 0.091-0.11 -> 0.057-0.077 s; Kenney tiles and SheenChair 10-30 ms less;
// peak memory the same to 5 % more (the 10k terrain 311 -> 325-330 MiB).
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
/// pages, and whether the kernel's transparent huge pages allow them.
std::string huge_pages_status();
/// One line for `snowmodel info`: the mmap threshold this process set, or
/// why it set none.
std::string mmap_threshold_status();

}  // namespace snow

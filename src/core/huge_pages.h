#pragma once
// Transparent huge pages for the heap. The pipeline allocates and first
// touches gigabytes in large blocks (maps, stabilizer arrays, meshes, and
// llvmpipe's textures and framebuffers, which Mesa takes from malloc); with
// 4 KiB pages much of its time went to page faults and TLB misses (1M
// terrain at 2048 texels, AMD EPYC, llvmpipe: 17.8 s with 4 KiB pages,
// 10.7 s with huge pages, same bytes out; tools/RESULTS.md). glibc (2.35 and
// later) backs its heap with transparent huge pages when its tunable
// glibc.malloc.hugetlb is 1, but reads tunables only at program start, from
// the environment: so the program re-executes itself once with it added to
// GLIBC_TUNABLES.
#include <string>

namespace snow {

/// Call first thing in main, before any thread starts. Unless
/// GLIBC_TUNABLES already names glibc.malloc.hugetlb (the user's choice:
/// glibc.malloc.hugetlb=0 turns huge pages off), adds glibc.malloc.hugetlb=1
/// to it and re-executes /proc/self/exe with the same arguments. Returns only
/// when there is nothing to do or the re-execution failed (then the program
/// goes on with the usual pages). Does nothing where glibc has no such
/// tunable or ignores tunables (setuid). Re-executes at most once: the new
/// process finds the marker SNOWMODEL_HUGE_PAGES_REEXEC=1 in its environment
/// and removes it.
void use_huge_pages(char** argv);

/// One line for `snowmodel info`: whether this process asked glibc for huge
/// pages, and whether the kernel's transparent huge pages allow them.
std::string huge_pages_status();

}  // namespace snow

#pragma once
/* glibc's huge-page tunable in the environment: the rules that
 * snow::tune_heap (core/heap.h) and snowmodel's launcher (app/launcher.c)
 * both apply before they execute the program. C, so that the launcher
 * links libc alone. */
#include <stddef.h>
#include <stdlib.h> /* defines __GLIBC__ */

#ifdef __cplusplus
extern "C" {
#endif

/* The tunable that backs glibc's heap with transparent huge pages, and the
 * marker set only across the execution that adds it (so that it happens at
 * most once, even where glibc drops GLIBC_TUNABLES: setuid programs). */
#define SNOW_HUGE_PAGE_TUNABLE "glibc.malloc.hugetlb"
#define SNOW_HUGE_PAGE_MARKER "SNOWMODEL_HUGE_PAGES_REEXEC"
/* glibc has the tunable from 2.35 on. */
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 35))
#define SNOW_GLIBC_HAS_HUGE_PAGE_TUNABLE 1
#else
#define SNOW_GLIBC_HAS_HUGE_PAGE_TUNABLE 0
#endif

/* The value of tunable `name` in `tunables` (GLIBC_TUNABLES: entries
 * separated by ':', the last one naming it wins) and its length in
 * *length; NULL when none names it. */
const char* snow_tunable_value(const char* tunables, const char* name, size_t* length);

/* Adds SNOW_HUGE_PAGE_TUNABLE=1 to GLIBC_TUNABLES and sets the marker, and
 * returns 1; returns 0 and changes nothing where this glibc has no such
 * tunable or ignores tunables (setuid), where the marker is already set,
 * or where GLIBC_TUNABLES already gives the tunable a value (the user's
 * choice: 0 turns huge pages off). */
int snow_add_huge_page_tunable(void);

#ifdef __cplusplus
}
#endif

/* snowmodel's launcher: runs snowmodel-core, which lies beside it, with
 * glibc's huge-page tunable in its environment.
 *
 * The core would otherwise re-execute itself to get the tunable
 * (snow::tune_heap, core/heap.h), since glibc reads tunables only at
 * program start. That start loads and relocates the core's libraries
 * (libstdc++, OpenMesh, tinygltf, GLFW and X11's), 10 ms of its 13.7 ms
 * here; this program links libc alone and starts in about 3 ms
 * (snowmodel --version 27 -> 17 ms, ToyCar 0.081 -> 0.066-0.069 s;
 * tools/RESULTS.md, after session 25). It follows the core's rules: a
 * glibc.malloc.hugetlb the user set is kept, nothing is added where glibc
 * ignores tunables (setuid) or where a re-execution already happened (the
 * marker SNOWMODEL_HUGE_PAGES_REEXEC, which the core removes), and the
 * marker is set so that the core does not re-execute. The arguments go
 * through unchanged. */
#define _GNU_SOURCE /* memrchr */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/auxv.h>
#include <unistd.h>

#define CORE_NAME "snowmodel-core"
#define TUNABLE "glibc.malloc.hugetlb"
#define MARKER "SNOWMODEL_HUGE_PAGES_REEXEC"

#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 35))
#define GLIBC_HAS_TUNABLE 1
#else
#define GLIBC_HAS_TUNABLE 0
#endif

/* Whether the ':'-separated GLIBC_TUNABLES gives the huge-page tunable a
 * value (the last entry naming it wins), as the core's tunable_value. */
static int names_tunable(const char* tunables) {
  const size_t key = strlen(TUNABLE "=");
  int named = 0;
  for (const char* entry = tunables; entry != NULL; entry = strchr(entry, ':')) {
    if (*entry == ':') ++entry;
    if (strncmp(entry, TUNABLE "=", key) == 0) named = entry[key] != '\0' && entry[key] != ':';
  }
  return named;
}

/* GLIBC_TUNABLES with the huge-page tunable, unless the core's rules say
 * to leave the environment as it is. */
static void add_tunable(void) {
  if (!GLIBC_HAS_TUNABLE || getenv(MARKER) != NULL || getauxval(AT_SECURE) != 0) return;
  const char* before = getenv("GLIBC_TUNABLES");
  if (before != NULL && names_tunable(before)) return;
  const size_t length = (before != NULL ? strlen(before) + 1 : 0) + strlen(TUNABLE "=1") + 1;
  char* tunables = malloc(length);
  if (tunables == NULL) return;
  snprintf(tunables, length, "%s%s" TUNABLE "=1", before != NULL && *before ? before : "",
           before != NULL && *before ? ":" : "");
  if (setenv("GLIBC_TUNABLES", tunables, 1) == 0) setenv(MARKER, "1", 1);
  free(tunables);
}

int main(int argc, char** argv) {
  (void)argc;
  /* The core's path: this program's directory, from /proc, else from argv[0]. */
  char core[PATH_MAX];
  ssize_t n = readlink("/proc/self/exe", core, sizeof core);
  if (n >= (ssize_t)sizeof core) n = -1; /* truncated */
  if (n < 0 && argv[0] != NULL && strchr(argv[0], '/') != NULL && strlen(argv[0]) < sizeof core) {
    n = (ssize_t)strlen(argv[0]);
    memcpy(core, argv[0], (size_t)n);
  }
  char* slash = n > 0 ? memrchr(core, '/', (size_t)n) : NULL;
  if (slash == NULL || (size_t)(slash - core) + sizeof "/" CORE_NAME > sizeof core) {
    fprintf(stderr, "error: cannot find " CORE_NAME ": this program's own path is unknown\n");
    return 1;
  }
  memcpy(slash + 1, CORE_NAME, sizeof CORE_NAME);
  add_tunable();
  execv(core, argv);
  fprintf(stderr, "error: cannot run %s (%s): snowmodel is not installed whole\n", core,
          strerror(errno));
  return 1;
}

/* snowmodel's launcher: runs snowmodel-core, which lies beside it, with
 * glibc's huge-page tunable in its environment.
 *
 * The core would otherwise re-execute itself to get the tunable
 * (snow::tune_heap, core/heap.h), since glibc reads tunables only at
 * program start. That start loads and relocates the core's libraries
 * (libstdc++, OpenMesh, tinygltf, GLFW and X11's), most of its start-up
 * time; this program links libc alone and starts in a fraction of it
 * (tools/RESULTS.md, "Memory and page faults"). It applies the core's rules
 * (core/heap_env.h: a value the user set is kept, nothing is added where
 * glibc ignores tunables or after a re-execution) and sets the marker, so
 * that the core does not re-execute. The arguments go through unchanged. */
#define _GNU_SOURCE /* memrchr */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "core/heap_env.h"

#define CORE_NAME "snowmodel-core"

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
  snow_add_huge_page_tunable();
  execv(core, argv);
  fprintf(stderr, "error: cannot run %s (%s): snowmodel is not installed whole\n", core,
          strerror(errno));
  return 1;
}

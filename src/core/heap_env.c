#define _DEFAULT_SOURCE /* setenv, unsetenv */
#include "core/heap_env.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/auxv.h>

const char* snow_tunable_value(const char* tunables, const char* name, size_t* length) {
  const size_t key = strlen(name);
  const char* value = NULL;
  for (const char* entry = tunables; entry != NULL; entry = strchr(entry, ':')) {
    if (*entry == ':') ++entry;
    if (strncmp(entry, name, key) == 0 && entry[key] == '=') value = entry + key + 1;
  }
  if (value != NULL) *length = strcspn(value, ":");
  return value;
}

int snow_add_huge_page_tunable(void) {
  if (!SNOW_GLIBC_HAS_HUGE_PAGE_TUNABLE || getenv(SNOW_HUGE_PAGE_MARKER) != NULL ||
      getauxval(AT_SECURE) != 0) {
    return 0;
  }
  const char* before = getenv("GLIBC_TUNABLES");
  size_t length = 0;
  if (before != NULL && snow_tunable_value(before, SNOW_HUGE_PAGE_TUNABLE, &length) != NULL &&
      length > 0) {
    return 0;
  }
  const int other = before != NULL && *before != '\0';
  const size_t size = (other ? strlen(before) + 1 : 0) + strlen(SNOW_HUGE_PAGE_TUNABLE "=1") + 1;
  char* tunables = malloc(size);
  if (tunables == NULL) return 0;
  snprintf(tunables, size, "%s%s" SNOW_HUGE_PAGE_TUNABLE "=1", other ? before : "",
           other ? ":" : "");
  int added = 0;
  if (setenv(SNOW_HUGE_PAGE_MARKER, "1", 1) == 0) {
    added = setenv("GLIBC_TUNABLES", tunables, 1) == 0;
    if (!added) unsetenv(SNOW_HUGE_PAGE_MARKER);
  }
  free(tunables);
  return added;
}

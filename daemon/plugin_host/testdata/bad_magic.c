/* SPDX-License-Identifier: MIT
 * Test fixture: procam_plugin_info with a wrong magic number. Like wrong_abi,
 * its constructor marks $PROCAM_TEST_MARKER and aborts if it ever runs. */
#include <stdio.h>
#include <stdlib.h>

#define FX_NAME "bad_magic"
#define FX_MAGIC 0xdeadbeefu
#include "good.c"

__attribute__((constructor)) static void fx_must_not_run(void) {
  const char* marker = getenv("PROCAM_TEST_MARKER");
  if (marker) {
    FILE* f = fopen(marker, "w");
    if (f) {
      fputs("bad_magic constructor ran\n", f);
      fclose(f);
    }
  }
  abort();
}

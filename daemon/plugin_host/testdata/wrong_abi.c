/* SPDX-License-Identifier: MIT
 * Test fixture: built for plugin ABI 999. Its constructor writes the file named
 * by $PROCAM_TEST_MARKER and aborts, so a host that ran any of its code before
 * checking the ABI is caught by the test. */
#include <stdio.h>
#include <stdlib.h>

#define FX_NAME "wrong_abi"
#define FX_ABI_VERSION 999u
#include "good.c"

__attribute__((constructor)) static void fx_must_not_run(void) {
  const char* marker = getenv("PROCAM_TEST_MARKER");
  if (marker) {
    FILE* f = fopen(marker, "w");
    if (f) {
      fputs("wrong_abi constructor ran\n", f);
      fclose(f);
    }
  }
  abort();
}

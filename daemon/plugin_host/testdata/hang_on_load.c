/* SPDX-License-Identifier: MIT
 * Test fixture: a static constructor never returns. The host's probe must time
 * out, kill the child and reject the plugin. */
#include <unistd.h>

#define FX_NAME "hang_on_load"
#include "good.c"

__attribute__((constructor)) static void fx_hang(void) {
  for (;;) pause();
}

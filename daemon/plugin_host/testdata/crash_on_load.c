/* SPDX-License-Identifier: MIT
 * Test fixture: a static constructor raises SIGSEGV when the library is loaded.
 * The host's probe child must absorb it; the test process must survive. */
#include <signal.h>

#define FX_NAME "crash_on_load"
#include "good.c"

__attribute__((constructor)) static void fx_crash(void) { raise(SIGSEGV); }

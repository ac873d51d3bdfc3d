/* SPDX-License-Identifier: MIT
 * Test fixture: loads and creates fine, then describe() raises SIGSEGV. The
 * probe must report the crash and blame describe(). */
#define FX_NAME "crash_in_describe"
#define FX_DESCRIBE_CRASHES 1
#include "good.c"

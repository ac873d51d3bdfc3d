/* SPDX-License-Identifier: MIT
 * Test fixture: a plugin that takes the host services (session_set_host) and,
 * in end_round, logs (plain, multi-line, 3000 bytes, unknown level, from a
 * worker thread) and reports progress 0..1 in 1001 steps. */
#define FX_NAME "host_services"
#define FX_HOST_SERVICES 1
#include "good.c"

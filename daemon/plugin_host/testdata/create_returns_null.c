/* SPDX-License-Identifier: MIT
 * Test fixture: procam_plugin_create returns NULL (refuses the host's ABI). */
#define FX_NAME "create_returns_null"
#define FX_CREATE_RETURNS_NULL 1
#include "good.c"

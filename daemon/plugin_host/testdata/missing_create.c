/* SPDX-License-Identifier: MIT
 * Test fixture: has procam_plugin_info but exports its create function under a
 * wrong name, so procam_plugin_create is missing. */
#define FX_NAME "missing_create"
#define FX_CREATE_SYMBOL "procam_plugin_create_v2"
#include "good.c"

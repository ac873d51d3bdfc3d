/* SPDX-License-Identifier: MIT
 * Test fixture: has procam_plugin_create but exports its info block under a
 * wrong name, so procam_plugin_info is missing. */
#define FX_NAME "no_info"
#define FX_INFO_SYMBOL "procam_plugin_information"
#include "good.c"

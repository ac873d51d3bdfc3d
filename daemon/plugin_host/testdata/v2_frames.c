/* SPDX-License-Identifier: MIT
 * Test fixture: a correct plugin built for the ABI 2 header (ABI version 2,
 * the full ABI 2 table, frames in the ABI 2 layout without light_index) that
 * plans two frames: an ABI 3 host must read them with the ABI 2 stride, run
 * the plugin unchanged and give both frames light_index 0. */
#define FX_NAME "v2_frames"
#define FX_ABI_VERSION 2u /* the value of PROCAM_PLUGIN_ABI_VERSION in that header */
#define FX_TWO_FRAMES 1
#include "good.c"

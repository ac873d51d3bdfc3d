/* SPDX-License-Identifier: MIT
 * Test fixture: a correct plugin built for the ABI 1 header of procam 0.2 (ABI
 * version 1, create() serves only host ABI 1, the table with session_set_host
 * and struct_size PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE). An ABI 2 host must load
 * and run it, never read the session_create2 slot (a trap pointer) and refuse
 * to pass it inputs. */
#define FX_NAME "v1_host"
#define FX_ABI_VERSION 1u /* the value of PROCAM_PLUGIN_ABI_VERSION in that header */
#define FX_V1_HOST_TABLE 1
#include "good.c"

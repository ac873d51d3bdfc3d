/* SPDX-License-Identifier: MIT
 * Test fixture: a correct plugin built for the first ABI 1 header (ABI version
 * 1 in its info block and table, create() serves only host ABI 1), whose
 * function table ends at get_outputs (struct_size 64 on LP64): it must still
 * load and run, and the host must not read past its table. */
#define FX_NAME "v1_table"
#define FX_ABI_VERSION 1u /* the value of PROCAM_PLUGIN_ABI_VERSION in that header */
#define FX_V1_TABLE 1
#include "good.c"

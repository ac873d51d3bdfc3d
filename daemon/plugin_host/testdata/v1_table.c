/* SPDX-License-Identifier: MIT
 * Test fixture: a correct plugin built for the first ABI 1 header, whose
 * function table ends at get_outputs (struct_size 64 on LP64): it must still
 * load and run, and the host must not read past its table. */
#define FX_NAME "v1_table"
#define FX_V1_TABLE 1
#include "good.c"

/* SPDX-License-Identifier: MIT
 * Test fixture: the function table leaves get_outputs NULL. */
#define FX_NAME "null_function"
#define FX_NULL_FUNCTION 1
#include "good.c"

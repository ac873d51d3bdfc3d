/* SPDX-License-Identifier: MIT
 * Test fixture: loads and scans fine, but names an output "../evil" (path
 * traversal if the host used it as a file name). */
#define FX_NAME "bad_outputs"
#define FX_OUTPUT_NAME "../evil"
#include "good.c"

/* SPDX-License-Identifier: MIT
 * Test fixture: loads fine, but plans a frame labelled "../up" (labels end up
 * in file names, so the host must refuse the plan). */
#define FX_NAME "bad_plan"
#define FX_LABEL "../up"
#include "good.c"

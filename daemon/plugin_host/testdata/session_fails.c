/* SPDX-License-Identifier: MIT
 * Test fixture: loads fine, but session_create always fails with a message. */
#define FX_NAME "session_fails"
#define FX_SESSION_FAILS 1
#include "good.c"

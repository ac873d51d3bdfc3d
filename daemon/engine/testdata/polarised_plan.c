/* SPDX-License-Identifier: MIT
 * Test fixture plugin "polarised": plans one black frame whose settings carry
 * a projector polariser angle, so scan_runner_test can check that the angle
 * reaches the projector (or that a projector without a polariser fails the
 * scan). Params (flat JSON object, numbers only):
 *   {"width": W, "height": H, "projector_polarizer_deg": A}
 * W x H is the projector size (the pattern must match it); A may be absent
 * (NaN: no polariser). Output: "frame_mean" (scalar).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "procam/plugin_abi.h"

#define FX_EXPORT __attribute__((visibility("default")))

FX_EXPORT const procam_plugin_info fx_info __asm__(PROCAM_PLUGIN_INFO_SYMBOL) = {
    PROCAM_PLUGIN_MAGIC, PROCAM_PLUGIN_ABI_VERSION, sizeof(procam_plugin_info), 0,
    "polarised", "0.0.1", "polarised"};

struct procam_session {
  int planned;
  int ended;
  double mean;
  uint8_t* black;
  procam_pattern_frame frame;
  procam_plan plan;
  procam_output output;
};

static void set_error(procam_error* err, const char* msg) {
  if (err) snprintf(err->message, sizeof err->message, "%s", msg);
}

/* The number after "key": in a flat JSON object, or `fallback` if absent. */
static double json_number(const char* json, const char* key, double fallback) {
  char quoted[64];
  const char* p;
  snprintf(quoted, sizeof quoted, "\"%s\"", key);
  p = strstr(json, quoted);
  if (p == NULL) return fallback;
  p = strchr(p + strlen(quoted), ':');
  return p == NULL ? fallback : strtod(p + 1, NULL);
}

static const char* fx_describe(void) {
  return "[{\"name\": \"polarised\", \"description\": \"one black frame with projector_polarizer_deg\", "
         "\"params\": []}]";
}

static int fx_session_create(const char* method, const char* params_json, const char* rig_json,
                             procam_session** out, procam_error* err) {
  double w, h;
  procam_session* s;
  (void)rig_json;
  if (strcmp(method, "polarised") != 0) {
    set_error(err, "unknown method");
    return PROCAM_ERR_INVALID_ARGUMENT;
  }
  w = json_number(params_json, "width", 0);
  h = json_number(params_json, "height", 0);
  if (!(w >= 1 && h >= 1 && w <= 8192 && h <= 8192)) {
    set_error(err, "params: width and height (the projector size) are required");
    return PROCAM_ERR_INVALID_ARGUMENT;
  }
  s = calloc(1, sizeof(procam_session));
  if (s == NULL) return PROCAM_ERR_NO_MEMORY;
  s->frame.pattern.width = (uint32_t)w;
  s->frame.pattern.height = (uint32_t)h;
  s->black = calloc((size_t)w * (size_t)h, 1);
  if (s->black == NULL) {
    free(s);
    return PROCAM_ERR_NO_MEMORY;
  }
  s->frame.label = "black";
  s->frame.pattern.channels = 1;
  s->frame.pattern.pixel_type = PROCAM_PIXEL_U8;
  s->frame.pattern.bit_depth = 8;
  s->frame.pattern.stride_bytes = (uint32_t)w;
  s->frame.pattern.data = s->black;
  s->frame.settings.struct_size = sizeof(procam_frame_settings);
  s->frame.settings.camera_index = 0;
  s->frame.settings.exposure_us = 0;
  s->frame.settings.gain_db = -1;
  s->frame.settings.projector_focus_mm = 0;
  s->frame.settings.polarizer_deg = NAN;
  s->frame.settings.projector_polarizer_deg = json_number(params_json, "projector_polarizer_deg", NAN);
  s->plan.frame_count = 1;
  s->plan.frames = &s->frame;
  s->plan.note = "the only round";
  *out = s;
  return PROCAM_OK;
}

static void fx_session_destroy(procam_session* s) {
  if (s) free(s->black);
  free(s);
}

static int fx_next_plan(procam_session* s, const procam_plan** plan, procam_error* err) {
  if (s->planned) {
    if (!s->ended) {
      set_error(err, "end_round first");
      return PROCAM_ERR_STATE;
    }
    return 0;
  }
  s->planned = 1;
  *plan = &s->plan;
  return 1;
}

static int fx_add_frame(procam_session* s, uint32_t index, const procam_image* f, procam_error* err) {
  uint32_t x, y;
  double sum = 0;
  if (index != 0 || f == NULL || f->channels != 1 || f->pixel_type != PROCAM_PIXEL_U8) {
    set_error(err, "expected frame 0, 1-channel U8");
    return PROCAM_ERR_BAD_FRAME;
  }
  for (y = 0; y < f->height; ++y)
    for (x = 0; x < f->width; ++x) sum += ((const uint8_t*)f->data)[y * f->stride_bytes + x];
  s->mean = sum / (double)(f->width * f->height);
  return PROCAM_OK;
}

static int fx_end_round(procam_session* s, procam_error* err) {
  (void)err;
  s->ended = 1;
  return PROCAM_OK;
}

static int fx_get_outputs(procam_session* s, const procam_output** outputs, uint32_t* count,
                          procam_error* err) {
  (void)err;
  memset(&s->output, 0, sizeof s->output);
  s->output.name = "frame_mean";
  s->output.kind = PROCAM_OUTPUT_SCALAR;
  s->output.unit = "";
  s->output.description = "mean grey value of the captured frame";
  s->output.scalar = s->mean;
  *outputs = &s->output;
  *count = 1;
  return PROCAM_OK;
}

static const procam_plugin_vtable fx_vtable = {
    PROCAM_PLUGIN_ABI_VERSION, sizeof(procam_plugin_vtable), fx_describe, fx_session_create,
    fx_session_destroy,        fx_next_plan,                 fx_add_frame, fx_end_round,
    fx_get_outputs,            NULL /* session_set_host: no log/progress */,
    NULL /* session_create2: takes no inputs */};

FX_EXPORT const procam_plugin_vtable* fx_create(uint32_t host_abi) __asm__(PROCAM_PLUGIN_CREATE_SYMBOL);
const procam_plugin_vtable* fx_create(uint32_t host_abi) {
  return host_abi == PROCAM_PLUGIN_ABI_VERSION ? &fx_vtable : NULL;
}

/* SPDX-License-Identifier: MIT
 * Test fixture: "null", a minimal correct decoder plugin that exercises the
 * host machinery (like OpenImageIO's null plugin). Method "null" plans one
 * black 4x3 U8 frame, then outputs "frame_mean" (scalar: mean of the captured
 * frame) and "depth_mm" (2x2 F32 image 1, 2, 3, NaN).
 *
 * The other fixtures #include this file after defining knobs that break one
 * thing each:
 *   FX_NAME            plugin name (default "null")
 *   FX_MAGIC           procam_plugin_info.magic
 *   FX_ABI_VERSION     procam_plugin_info.abi_version
 *   FX_INFO_SYMBOL     exported name of the info block
 *   FX_CREATE_SYMBOL   exported name of the create function
 *   FX_CREATE_RETURNS_NULL, FX_NULL_FUNCTION, FX_SESSION_FAILS, FX_DESCRIBE_CRASHES
 *   FX_OUTPUT_NAME     name of the scalar output (default "frame_mean")
 *   FX_LABEL           label of the planned frame (default "black")
 *   FX_V1_TABLE        return the function table as the first ABI 1 header
 *                      declared it (no session_set_host, the v1 struct_size),
 *                      followed in memory by a trap pointer the host must not read
 *                      (with FX_ABI_VERSION 1u: a plugin built with that header)
 *   FX_V1_HOST_TABLE   the ABI 1 table with session_set_host (procam 0.2), whose
 *                      struct_size ends before session_create2; that slot holds a
 *                      trap pointer the host must not read (with FX_ABI_VERSION 1u)
 *   FX_HOST_SERVICES   set session_set_host and log/report progress in end_round
 *   FX_TWO_FRAMES      plan two frames ("black-0" camera 0, exposure 1000 us;
 *                      "black-1" camera 1, exposure 2000 us); frame_mean is the
 *                      mean of both. With FX_ABI_VERSION < 3 the frames use the
 *                      ABI 1/2 layout, so a host reading them with the ABI 3
 *                      stride would see garbage in frame 1.
 * A fixture with FX_ABI_VERSION < 3 plans with procam_pattern_frame_v2, the
 * frame layout of the ABI 1/2 headers (no light_index).
 */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "procam/plugin_abi.h"

#ifndef FX_NAME
#define FX_NAME "null"
#endif
#ifndef FX_MAGIC
#define FX_MAGIC PROCAM_PLUGIN_MAGIC
#endif
#ifndef FX_ABI_VERSION
#define FX_ABI_VERSION PROCAM_PLUGIN_ABI_VERSION
#endif
#ifndef FX_INFO_SYMBOL
#define FX_INFO_SYMBOL PROCAM_PLUGIN_INFO_SYMBOL
#endif
#ifndef FX_CREATE_SYMBOL
#define FX_CREATE_SYMBOL PROCAM_PLUGIN_CREATE_SYMBOL
#endif
#ifndef FX_LABEL
#define FX_LABEL "black"
#endif
#ifndef FX_OUTPUT_NAME
#define FX_OUTPUT_NAME "frame_mean"
#endif

#define FX_EXPORT __attribute__((visibility("default")))

/* In C the variable cannot be called procam_plugin_info (that is the typedef's
 * name), so it gets its symbol name through an asm label. */
FX_EXPORT const procam_plugin_info fx_info __asm__(FX_INFO_SYMBOL) = {
    FX_MAGIC, FX_ABI_VERSION, sizeof(procam_plugin_info), 0, FX_NAME, "0.0.1", "null"};

static const uint8_t black[4 * 3]; /* zeros */

#if FX_ABI_VERSION < 3
typedef procam_pattern_frame_v2 fx_frame; /* the layout of the ABI 1/2 headers */
#else
typedef procam_pattern_frame fx_frame;
#endif
#ifdef FX_TWO_FRAMES
#define FX_FRAMES 2
#else
#define FX_FRAMES 1
#endif

struct procam_session {
  const procam_host_services* host; /* FX_HOST_SERVICES: from session_set_host */
  int planned;
  int ended;
  double mean;
  float depth[4];
  fx_frame frames[FX_FRAMES];
  procam_plan plan;
  procam_output outputs[2];
};

static void set_error(procam_error* err, const char* msg) {
  if (err) snprintf(err->message, sizeof err->message, "%s", msg);
}

static const char* fx_describe(void) {
#ifdef FX_DESCRIBE_CRASHES
  raise(SIGSEGV);
#endif
  return "[{\"name\": \"null\", \"description\": \"one black frame, trivial outputs\", "
         "\"params\": []}]";
}

static int fx_session_create(const char* method, const char* params_json, const char* rig_json,
                             procam_session** out, procam_error* err) {
  (void)params_json;
  (void)rig_json;
#ifdef FX_SESSION_FAILS
  (void)method;
  (void)out;
  set_error(err, "null plugin: this fixture refuses every session");
  /* ...and "forgets" the terminating NUL: the rest of the buffer is filled. */
  memset(err->message + strlen(err->message), '!',
         sizeof err->message - strlen(err->message));
  return PROCAM_ERR_INVALID_ARGUMENT;
#else
  if (strcmp(method, "null") != 0) {
    set_error(err, "unknown method");
    return PROCAM_ERR_INVALID_ARGUMENT;
  }
  *out = calloc(1, sizeof(procam_session));
  if (*out == NULL) return PROCAM_ERR_NO_MEMORY;
  return PROCAM_OK;
#endif
}

static void fx_session_destroy(procam_session* s) { free(s); }

static int fx_next_plan(procam_session* s, const procam_plan** plan, procam_error* err) {
  if (s->planned) {
    if (!s->ended) {
      set_error(err, "end_round first");
      return PROCAM_ERR_STATE;
    }
    return 0;
  }
  s->planned = 1;
  for (int i = 0; i < FX_FRAMES; ++i) {
    fx_frame* f = &s->frames[i];
#ifdef FX_TWO_FRAMES
    f->label = i == 0 ? "black-0" : "black-1";
    f->settings.exposure_us = 1000.0 * (i + 1);
#else
    f->label = FX_LABEL;
    f->settings.exposure_us = 0;
#endif
    f->pattern.width = 4;
    f->pattern.height = 3;
    f->pattern.channels = 1;
    f->pattern.pixel_type = PROCAM_PIXEL_U8;
    f->pattern.bit_depth = 8;
    f->pattern.stride_bytes = 4;
    f->pattern.data = black;
    f->settings.struct_size = sizeof f->settings;
    f->settings.camera_index = i;
    f->settings.gain_db = -1;
    f->settings.projector_focus_mm = 0;
    f->settings.polarizer_deg = NAN;
    f->settings.projector_polarizer_deg = NAN;
  }
  s->plan.frame_count = FX_FRAMES;
  /* An ABI 1/2 host reads this array with the v2 stride (the cast is what an
   * old plugin's header would have had for its own struct). */
  s->plan.frames = (const procam_pattern_frame*)(const void*)s->frames;
  s->plan.note = "the only round";
  *plan = &s->plan;
  return 1;
}

static int fx_add_frame(procam_session* s, uint32_t index, const procam_image* f,
                        procam_error* err) {
  uint32_t x, y;
  double sum = 0;
  if (index >= FX_FRAMES || f == NULL || f->pixel_type != PROCAM_PIXEL_U8 || f->channels != 1) {
    set_error(err, FX_FRAMES == 1 ? "expected frame 0, 1-channel U8" : "expected frame 0 or 1, 1-channel U8");
    return PROCAM_ERR_BAD_FRAME;
  }
  for (y = 0; y < f->height; ++y)
    for (x = 0; x < f->width; ++x) sum += ((const uint8_t*)f->data)[y * f->stride_bytes + x];
  s->mean += sum / (double)(f->width * f->height) / FX_FRAMES;
  return PROCAM_OK;
}

#ifdef FX_HOST_SERVICES
#include <pthread.h>

static void fx_log(procam_session* s, int level, const char* msg) {
  if (s->host != NULL && s->host->log != NULL) s->host->log(s->host->ctx, level, msg);
}

/* Breaks the contract on purpose: calls the host from a worker thread. */
static void* fx_worker(void* arg) {
  fx_log((procam_session*)arg, PROCAM_LOG_ERROR, "from a worker thread");
  return NULL;
}

static int fx_session_set_host(procam_session* s, const procam_host_services* host,
                               procam_error* err) {
  if (host == NULL || host->struct_size < sizeof(procam_host_services)) {
    set_error(err, "host services table too small");
    return PROCAM_ERR_INVALID_ARGUMENT;
  }
  s->host = host;
  fx_log(s, PROCAM_LOG_ERROR, "inside session_set_host"); /* not allowed: dropped */
  return PROCAM_OK;
}

/* The messages the host test expects, in order (see host_services_test.cpp). */
static void fx_report(procam_session* s) {
  static char big[3001];
  pthread_t worker;
  int i;
  fx_log(s, PROCAM_LOG_INFO, "decoding 1 frame");
  fx_log(s, PROCAM_LOG_WARN, "line1\nline2\x01" "end");
  memset(big, 'x', sizeof big - 1);
  big[sizeof big - 1] = '\0';
  fx_log(s, PROCAM_LOG_DEBUG, big);
  fx_log(s, 42, "unknown level");
  if (pthread_create(&worker, NULL, fx_worker, s) == 0) pthread_join(worker, NULL);
  if (s->host->progress != NULL) {
    s->host->progress(s->host->ctx, NAN, "nan"); /* dropped */
    for (i = 0; i <= 1000; ++i) s->host->progress(s->host->ctx, i / 1000.0, "unwrap");
    s->host->progress(s->host->ctx, 2.0, "clamp"); /* clamped to 1 */
  }
}
#endif

static int fx_end_round(procam_session* s, procam_error* err) {
  (void)err;
#ifdef FX_HOST_SERVICES
  fx_report(s);
#endif
  s->ended = 1;
  return PROCAM_OK;
}

/* unused only in null_function.c */
__attribute__((unused)) static int fx_get_outputs(procam_session* s,
                                                  const procam_output** outputs,
                                                  uint32_t* count, procam_error* err) {
  (void)err;
  memset(s->outputs, 0, sizeof s->outputs);
  s->outputs[0].name = FX_OUTPUT_NAME;
  s->outputs[0].kind = PROCAM_OUTPUT_SCALAR;
  s->outputs[0].unit = "";
  s->outputs[0].description = "mean grey value of the captured frame";
  s->outputs[0].scalar = s->mean;
  s->depth[0] = 1.0f;
  s->depth[1] = 2.0f;
  s->depth[2] = 3.0f;
  s->depth[3] = NAN;
  s->outputs[1].name = "depth_mm";
  s->outputs[1].kind = PROCAM_OUTPUT_IMAGE;
  s->outputs[1].unit = "mm";
  s->outputs[1].description = "a constant 2x2 depth map";
  s->outputs[1].image.width = 2;
  s->outputs[1].image.height = 2;
  s->outputs[1].image.channels = 1;
  s->outputs[1].image.pixel_type = PROCAM_PIXEL_F32;
  s->outputs[1].image.bit_depth = 32;
  s->outputs[1].image.stride_bytes = 2 * sizeof(float);
  s->outputs[1].image.data = s->depth;
  *outputs = s->outputs;
  *count = 2;
  return PROCAM_OK;
}

#ifdef FX_V1_TABLE
/* procam_plugin_vtable exactly as the first ABI 1 header declared it. */
typedef struct fx_vtable_v1 {
  uint32_t abi_version;
  uint32_t struct_size;
  const char* (*describe)(void);
  int (*session_create)(const char*, const char*, const char*, procam_session**, procam_error*);
  void (*session_destroy)(procam_session*);
  int (*next_plan)(procam_session*, const procam_plan**, procam_error*);
  int (*add_frame)(procam_session*, uint32_t, const procam_image*, procam_error*);
  int (*end_round)(procam_session*, procam_error*);
  int (*get_outputs)(procam_session*, const procam_output**, uint32_t*, procam_error*);
} fx_vtable_v1;

/* What follows the table in memory is where a newer host would find
 * session_set_host: a non-NULL garbage pointer, so a host reading past
 * struct_size would call it and crash. */
static const struct {
  fx_vtable_v1 table;
  uintptr_t trap;
} fx_v1 = {{FX_ABI_VERSION, sizeof(fx_vtable_v1), fx_describe, fx_session_create,
            fx_session_destroy, fx_next_plan, fx_add_frame, fx_end_round, fx_get_outputs},
           (uintptr_t)0x1};
#define FX_TABLE ((const procam_plugin_vtable*)(const void*)&fx_v1.table)
#elif defined(FX_V1_HOST_TABLE)
/* The ABI 1 table of procam 0.2 (with session_set_host): its struct_size
 * stops before session_create2, which holds garbage a host must not call. */
static const procam_plugin_vtable fx_vtable = {
    FX_ABI_VERSION, (uint32_t)PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE, fx_describe, fx_session_create,
    fx_session_destroy, fx_next_plan, fx_add_frame, fx_end_round, fx_get_outputs, NULL,
    (int (*)(const char*, const char*, const char*, const procam_output*, uint32_t,
             procam_session**, procam_error*))(uintptr_t)0x1};
#define FX_TABLE (&fx_vtable)
#else
static const procam_plugin_vtable fx_vtable = {
    FX_ABI_VERSION, sizeof(procam_plugin_vtable), fx_describe, fx_session_create,
    fx_session_destroy,        fx_next_plan,                 fx_add_frame, fx_end_round,
#ifdef FX_NULL_FUNCTION
    NULL,
#else
    fx_get_outputs,
#endif
#ifdef FX_HOST_SERVICES
    fx_session_set_host,
#else
    NULL,
#endif
    NULL /* session_create2: no method takes inputs */
};
#define FX_TABLE (&fx_vtable)
#endif

FX_EXPORT const procam_plugin_vtable* fx_create(uint32_t host_abi) __asm__(FX_CREATE_SYMBOL);
const procam_plugin_vtable* fx_create(uint32_t host_abi) {
#ifdef FX_CREATE_RETURNS_NULL
  (void)host_abi;
  return NULL;
#else
  return host_abi == FX_ABI_VERSION ? FX_TABLE : NULL;
#endif
}

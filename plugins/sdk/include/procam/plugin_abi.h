/* SPDX-License-Identifier: MIT
 * procam decoder-plugin C ABI. The only thing that crosses between procamd (or
 * the offline decoder) and a plugin shared library.
 *
 * A plugin is a shared library exporting exactly two symbols:
 *
 *   "procam_plugin_info"    data of type procam_plugin_info (no pointers)
 *   "procam_plugin_create"  const procam_plugin_vtable* (uint32_t host_abi)
 *
 * The data symbol shares its name with the type, so C/C++ code declares it
 * with an assembler label, e.g.
 *   extern const procam_plugin_info procam_info_ __asm__("procam_plugin_info");
 * The C++ SDK's PROCAM_DEFINE_PLUGIN (procam/plugin_sdk.hpp) does this for you.
 *
 * Loading order (host side, daemon/plugin_host/, see its README.md):
 *   1. The host reads `procam_plugin_info` straight from the ELF file, WITHOUT
 *      loading it, and checks `magic`, `abi_version` and `struct_size`. A
 *      mismatch is reported and the file is skipped; no plugin code has run.
 *   2. Only then the host dlopen()s the library and calls
 *      procam_plugin_create(<the abi_version from step 1>), and checks the
 *      returned table's abi_version (the same), its struct_size (one of the
 *      sizes "Version history" lists for that version) and that every
 *      required function pointer is set (session_set_host and
 *      session_create2 are optional).
 *
 * Rules for both sides:
 *   - No C++ types, exceptions or longjmps cross this ABI. A plugin catches
 *     everything and returns PROCAM_ERR_* with a message in procam_error.
 *   - Ownership: memory is freed by whoever allocated it. Everything a plugin
 *     returns (plans, outputs, strings) is owned by the plugin session and stays
 *     valid until the next call on that session or its destruction. Everything
 *     the host passes in (frames, JSON strings) is owned by the host and valid
 *     only during the call: copy what you keep.
 *   - Threads: one session is used by one host thread at a time (thread-bound (docs/threading.md)
 *     between calls, never concurrent). Different sessions may run concurrently
 *     on different threads, so plugin globals must be immutable or locked.
 *     A plugin may use threads internally; `threads` in the rig JSON is the
 *     host's suggestion.
 *   - Units: lengths in millimetres, times in microseconds, angles in degrees,
 *     image coordinates in pixels with pixel centres at integers (OpenCV).
 *   - Plugins never touch hardware: they describe frames (plan) and decode
 *     frames the host captured.
 *   - Names and sizes the host enforces (violations reject the plugin or
 *     fail the scan with plugin_error):
 *       method names [a-z0-9_-]{1,63}; describe() is a JSON array with one
 *       object per method in info.methods, each with a string "name";
 *       frame labels 1..255 bytes without '/', '\' or control characters;
 *       settings.struct_size == sizeof(procam_frame_settings);
 *       output names [a-z0-9_]{1,64} (they become file names), unique;
 *       a round has >= 1 frame; a session plans at most 1000 rounds.
 *
 * Scan protocol, per session (one scan):
 *   session_create(method, params, rig)
 *     or, ABI 2, session_create2(method, params, rig, inputs, input_count)
 *   loop:
 *     next_plan(&plan) -> 1 (a round to capture) or 0 (no more rounds)
 *     for each frame i of plan, in any order, as they arrive: add_frame(i, img)
 *     end_round()      decode this round; may decide another round is needed
 *   get_outputs()
 *   session_destroy()
 * Multi-round methods (error correction, adaptive codes) return further plans
 * from next_plan after end_round; single-round methods return 0 the 2nd time.
 *
 * Host services (log + progress), optional, appended to ABI 1:
 *   A plugin that sets procam_plugin_vtable.session_set_host gets, right after
 *   a successful session_create and before any other call on that session,
 *   a procam_host_services table: log(level, message) and
 *   progress(fraction, stage). Contract:
 *     - Call them ONLY from within an ABI call on that session (next_plan,
 *       add_frame, end_round, get_outputs), on the thread that made that
 *       call. Never from session_set_host/session_destroy, never between
 *       calls, never from a plugin's worker threads: the host is not ready
 *       there and may drop, race or crash. A plugin with worker threads
 *       hands messages to the calling thread (the C++ SDK does this:
 *       sdk::Session::log/progress from a worker are queued and delivered
 *       when the current ABI call returns).
 *     - The table and `ctx` stay valid until session_destroy; `message` and
 *       `stage` are NUL-terminated UTF-8, owned by the plugin, read only
 *       during the call. Both functions return promptly and never fail.
 *     - The host may truncate messages (1 KiB), escape control characters and
 *       drop progress reports (it forwards at most ~20 per second);
 *       `fraction` is 0..1 of the current round's decode (NaN/out of range
 *       are clamped or dropped); `stage` is a short word ("unwrap"), may be NULL.
 *   struct_size of procam_host_services lets the host append members later;
 *   a plugin reads only the members that struct_size covers.
 *
 * Scan inputs (ABI 2): outputs of an earlier scan fed to a new session.
 *   A method that takes inputs lists them in its describe() object:
 *     "inputs": [{"name": "depth_mm", "kind": "image_f32", "unit": "mm",
 *                 "required": true, "description": "..."}]
 *   (key absent or [] = the method takes no inputs). "name" follows the
 *   output-name rule [a-z0-9_]{1,64}; "kind" is "image_f32" (the only kind
 *   today: a 1-channel PROCAM_PIXEL_F32 map of camera 0's size, NaN where
 *   invalid). The host reads describe() at load time and, before any plugin
 *   call, refuses a scan that names an input the method does not declare,
 *   leaves out a required one, or passes one of the wrong kind; it never
 *   passes inputs to an ABI 1 plugin or to a table without session_create2.
 *   It then calls session_create2 with `inputs[0..input_count)`:
 *     - each entry is a procam_output of kind PROCAM_OUTPUT_IMAGE (name,
 *       unit, description, image set; the other members zero);
 *     - names are unique; order carries no meaning;
 *     - `inputs` may be NULL when input_count is 0;
 *     - everything (array, strings, pixels) is host-owned and valid ONLY
 *       during the call: a plugin copies what it keeps (the C++ SDK's
 *       sdk::Inputs::image_f32 does);
 *     - the plugin still checks what it needs (size, values) and fails with
 *       PROCAM_ERR_INVALID_ARGUMENT naming the input and how to supply it.
 *   A v2 table with session_create2 gets every session through it (with 0
 *   inputs when the scan names none); session_create stays required and is
 *   what an ABI 1 host would have called.
 *
 * Version history
 *   1 (procam 0.1): initial ABI.
 *   1, append-only (procam 0.2): procam_plugin_vtable gains the optional
 *     session_set_host (may be NULL) and procam_host_services is added. The
 *     version stays 1: the change only appends to the vtable and the host
 *     tells the two layouts apart by vtable struct_size (the v1 size,
 *     PROCAM_PLUGIN_VTABLE_V1_SIZE, or the full size), so plugins built
 *     against the first ABI 1 header load and run unchanged (without host
 *     services). The other way round is not promised: a procamd from before
 *     this change requires struct_size == its own (v1) size and rejects
 *     plugins built with this header. A real break (new required calls,
 *     changed structs) bumps the version to 2.
 *     procam_rc_name() is added (a static inline helper, no symbol).
 *   2 (procam 0.3): scan inputs. procam_plugin_vtable gains the optional
 *     session_create2 (after session_set_host) and PROCAM_ERR_FAILED_PRECONDITION
 *     is added (a method cannot start because something it needs -- a
 *     calibration table, an input -- is missing from the rig or the request).
 *     The table of a version-2 plugin has struct_size ==
 *     sizeof(procam_plugin_vtable). A version-2 host still loads ABI 1
 *     plugins (PROCAM_PLUGIN_ABI_VERSION_MIN): it reads abi_version from the
 *     ELF info block, calls procam_plugin_create(1) for them and accepts
 *     their two table sizes (PROCAM_PLUGIN_VTABLE_V1_SIZE,
 *     PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE); it never passes inputs to them (a
 *     scan that names inputs for an ABI 1 plugin fails with a message saying
 *     so). An ABI 1 host rejects version-2 plugins at the ELF check.
 *   3 (procam 0.4): lights. procam_frame_settings gains `light_index` (and
 *     `reserved3`) at its end, so procam_pattern_frame grows by 8 bytes; the
 *     rig description gains "lights" (proto/PROTOCOL.md "Rig description").
 *     A frame with light_index k >= 1 is lit by the rig's light k alone (a
 *     light co-located with a camera, e.g. for Helmholtz reciprocal pairs).
 *     The vtable is unchanged (struct_size == sizeof(procam_plugin_vtable)).
 *     A version-3 host still loads ABI 1 and 2 plugins: it reads their plans
 *     through procam_pattern_frame_v2 (the old stride, settings.struct_size
 *     == sizeof(procam_frame_settings_v2)) and gives every frame
 *     light_index 0, so they run unchanged. An ABI 2 host rejects version-3
 *     plugins at the ELF check.
 */
#ifndef PROCAM_PLUGIN_ABI_H
#define PROCAM_PLUGIN_ABI_H

#include <stddef.h>
#include <stdint.h>

#include "procam/pixel.h" /* procam_pixel_type, procam_image: the bottom layer's image view */

#ifdef __cplusplus
extern "C" {
#endif

#define PROCAM_PLUGIN_ABI_VERSION 3u
/* The oldest ABI a host built with this header still loads (see "Version history"). */
#define PROCAM_PLUGIN_ABI_VERSION_MIN 1u
#define PROCAM_PLUGIN_MAGIC 0x49504350u /* "PCPI" little-endian */

/* Symbol names the host looks up. */
#define PROCAM_PLUGIN_INFO_SYMBOL "procam_plugin_info"
#define PROCAM_PLUGIN_CREATE_SYMBOL "procam_plugin_create"

/* Return codes of every ABI function that can fail. */
enum {
  PROCAM_OK = 0,
  PROCAM_ERR_INVALID_ARGUMENT = -1, /* bad method, parameter or frame index */
  PROCAM_ERR_BAD_FRAME = -2,        /* frame has the wrong size/format or is corrupt */
  PROCAM_ERR_STATE = -3,            /* call out of the documented order */
  PROCAM_ERR_NO_MEMORY = -4,
  PROCAM_ERR_INTERNAL = -5,         /* bug or unexpected exception in the plugin */
  PROCAM_ERR_FAILED_PRECONDITION = -6 /* ABI 2: something the method needs is missing
                                         (a calibration table in the rig, ...); the
                                         message says how to provide it */
};

/* "PROCAM_ERR_BAD_FRAME" etc. for a return code above; NULL for any other
 * value (callers print their own "unknown code N"). For messages and tests. */
static inline const char* procam_rc_name(int rc) {
  switch (rc) {
    case PROCAM_OK: return "PROCAM_OK";
    case PROCAM_ERR_INVALID_ARGUMENT: return "PROCAM_ERR_INVALID_ARGUMENT";
    case PROCAM_ERR_BAD_FRAME: return "PROCAM_ERR_BAD_FRAME";
    case PROCAM_ERR_STATE: return "PROCAM_ERR_STATE";
    case PROCAM_ERR_NO_MEMORY: return "PROCAM_ERR_NO_MEMORY";
    case PROCAM_ERR_INTERNAL: return "PROCAM_ERR_INTERNAL";
    case PROCAM_ERR_FAILED_PRECONDITION: return "PROCAM_ERR_FAILED_PRECONDITION";
    default: return NULL;
  }
}

/* Error detail a plugin fills on failure. NUL-terminated, truncated to fit. */
typedef struct procam_error {
  char message[512];
} procam_error;

/* Plain, pointer-free plugin description, readable from the ELF file before
 * any plugin code runs. */
typedef struct procam_plugin_info {
  uint32_t magic;            /* PROCAM_PLUGIN_MAGIC */
  uint32_t abi_version;      /* PROCAM_PLUGIN_ABI_VERSION the plugin was built for */
  uint32_t struct_size;      /* sizeof(procam_plugin_info) */
  uint32_t reserved;
  char name[64];             /* plugin name, e.g. "structured-light" */
  char version[32];          /* plugin version, e.g. "0.1.0" */
  char methods[1024];        /* comma-separated method names, e.g. "gray,xor02" */
} procam_plugin_info;

/* Per-frame capture settings. Fields set to their "unset" value keep the
 * rig's configured value. Extended by appending fields (struct_size tells;
 * since it is the last member of procam_pattern_frame, an append changes the
 * frame array's stride, so it comes with an ABI version: see "Version history"). */
typedef struct procam_frame_settings {
  uint32_t struct_size;
  int32_t camera_index;       /* which camera of the rig; 0 = first. */
  double exposure_us;         /* camera exposure; <= 0: rig default */
  double gain_db;             /* camera analog gain; < 0: rig default */
  double projector_focus_mm;  /* projector focal-plane distance; <= 0: rig default */
  double polarizer_deg;       /* camera analyser angle; NaN: none/unchanged */
  double projector_polarizer_deg; /* projector polariser angle; NaN: none/unchanged */
  /* ---- appended in ABI 3 (procam 0.4); an ABI 1/2 struct ends above ---- */
  int32_t light_index;        /* which light the frame is lit by: 0 = the projector
                                 (showing `pattern`, as every ABI 1/2 frame);
                                 k >= 1 = light k of the rig description's
                                 "lights" (1-based), the projector dark and
                                 `pattern` ignored (still projector-sized). */
  int32_t reserved3;          /* 0 */
} procam_frame_settings;

/* ABI 1/2 frame settings and frame, as those headers declared them. A host
 * reads the plans of ABI 1/2 plugins through these (their frames array has
 * this stride) and treats every such frame as light_index 0. */
typedef struct procam_frame_settings_v2 {
  uint32_t struct_size;
  int32_t camera_index;
  double exposure_us;
  double gain_db;
  double projector_focus_mm;
  double polarizer_deg;
  double projector_polarizer_deg;
} procam_frame_settings_v2;
typedef struct procam_pattern_frame_v2 {
  const char* label;
  procam_image pattern;
  procam_frame_settings_v2 settings;
} procam_pattern_frame_v2;

/* One frame to capture: show `pattern` on the projector, capture with `settings`. */
typedef struct procam_pattern_frame {
  const char* label;              /* e.g. "col bit 9 inverse"; used in file names */
  procam_image pattern;           /* projector-sized, 1 channel U8/U16/F32 in [0,1] */
  procam_frame_settings settings;
} procam_pattern_frame;

typedef struct procam_plan {
  uint32_t frame_count;
  const procam_pattern_frame* frames;
  const char* note;               /* why this round (shown to users), may be NULL */
} procam_plan;

typedef enum procam_output_kind {
  PROCAM_OUTPUT_IMAGE = 1,   /* a map: depth, correspondence, mask, ... */
  PROCAM_OUTPUT_SCALAR = 2,  /* a number: decode_ms, valid_fraction, ... */
  PROCAM_OUTPUT_POINTS = 3,  /* a point cloud: xyz (+ optional attributes) */
  PROCAM_OUTPUT_JSON = 4     /* structured report: model choice, per-round notes */
} procam_output_kind;

/* A named result. Names are lower_snake_case and carry their unit where one
 * applies ("depth_mm", "proj_col_px"); `unit` repeats it for tools. */
typedef struct procam_output {
  const char* name;
  uint32_t kind;              /* procam_output_kind */
  const char* unit;           /* "mm", "px", "ms", "" */
  const char* description;
  procam_image image;         /* IMAGE. F32 maps use NaN where invalid. */
  double scalar;              /* SCALAR */
  const float* points;        /* POINTS: point_count rows of point_stride floats; */
  uint64_t point_count;       /* the first three are x, y, z in mm, camera frame */
  uint32_t point_stride;      /* floats per point, >= 3 */
  const char* point_fields;   /* e.g. "x,y,z,intensity" */
  const char* json;           /* JSON */
} procam_output;

typedef struct procam_session procam_session; /* opaque, plugin-owned */

/* Log levels of procam_host_services.log. */
enum {
  PROCAM_LOG_DEBUG = 0,
  PROCAM_LOG_INFO = 1,
  PROCAM_LOG_WARN = 2,
  PROCAM_LOG_ERROR = 3
};

/* What the host offers a session (see "Host services" above). Host-owned;
 * valid until session_destroy. Any function pointer may be NULL. */
typedef struct procam_host_services {
  uint32_t struct_size; /* sizeof(procam_host_services) of the host */
  void* ctx;            /* pass back as the first argument */
  /* A line for the daemon log (and the scan's `log` events). `level` is a
   * PROCAM_LOG_* value; `message` one line of text, no trailing newline. */
  void (*log)(void* ctx, int level, const char* message);
  /* Progress within the current round's decode: `fraction` 0..1, `stage` a
   * short name of the current step or NULL. */
  void (*progress)(void* ctx, double fraction, const char* stage);
} procam_host_services;

typedef struct procam_plugin_vtable {
  uint32_t abi_version;   /* PROCAM_PLUGIN_ABI_VERSION */
  uint32_t struct_size;   /* sizeof(procam_plugin_vtable) */

  /* JSON array describing methods and their parameters (name, type, default,
   * range, description). Static, owned by the plugin. */
  const char* (*describe)(void);

  /* Start a scan. `rig_json` describes resolutions, calibration (see
   * proto/PROTOCOL.md "Rig description"); `params_json` is a JSON object. */
  int (*session_create)(const char* method, const char* params_json,
                        const char* rig_json, procam_session** out,
                        procam_error* err);
  void (*session_destroy)(procam_session* s);

  /* Returns 1 and sets *plan for a round to capture, 0 when done, <0 on error. */
  int (*next_plan)(procam_session* s, const procam_plan** plan, procam_error* err);

  /* Hand over frame `index` of the current round's plan (any order, once each). */
  int (*add_frame)(procam_session* s, uint32_t index, const procam_image* frame,
                   procam_error* err);

  /* All frames of the round were added: decode. */
  int (*end_round)(procam_session* s, procam_error* err);

  /* Results, valid until session_destroy. */
  int (*get_outputs)(procam_session* s, const procam_output** outputs,
                     uint32_t* count, procam_error* err);

  /* ---- appended in ABI 1 (procam 0.2); a table of the v1 size ends above ---- */

  /* Optional (may be NULL): receives the host's services for this session
   * (see "Host services"). Called at most once, right after session_create,
   * before any other call on `s`; `host` stays valid until session_destroy.
   * Return PROCAM_OK; an error return fails the scan like session_create. */
  int (*session_set_host)(procam_session* s, const procam_host_services* host,
                          procam_error* err);

  /* ---- appended in ABI 2 (procam 0.3) ---- */

  /* Optional (may be NULL: the plugin's methods take no inputs). Like
   * session_create, plus the scan's inputs (see "Scan inputs"): an array of
   * `input_count` entries, host-owned, valid only during this call. When set,
   * the host starts every session of this plugin through it. */
  int (*session_create2)(const char* method, const char* params_json,
                         const char* rig_json, const procam_output* inputs,
                         uint32_t input_count, procam_session** out,
                         procam_error* err);
} procam_plugin_vtable;

/* Size of the table as first published for ABI 1 (up to get_outputs). */
#define PROCAM_PLUGIN_VTABLE_V1_SIZE \
  (offsetof(procam_plugin_vtable, get_outputs) + sizeof(void (*)(void)))
/* Size of the ABI 1 table with the appended session_set_host (procam 0.2).
 * A host accepts an ABI 1 table of either size; an ABI 2 table is
 * sizeof(procam_plugin_vtable). */
#define PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE offsetof(procam_plugin_vtable, session_create2)

/* Signature of the exported create function. Returns NULL if the plugin cannot
 * serve `host_abi_version`. */
typedef const procam_plugin_vtable* (*procam_plugin_create_fn)(uint32_t host_abi_version);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* PROCAM_PLUGIN_ABI_H */

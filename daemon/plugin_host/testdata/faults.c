/* SPDX-License-Identifier: MIT
 * Test fixture "faults": a plugin that misbehaves on request, one method per
 * fault, for the worker-isolation tests (isolation_test.cpp) and the daemon
 * test that a faulting scan leaves procamd serving. Every method plans one
 * round of 3 black U8 frames of the rig's projector size (4x3 without a rig
 * description); then:
 *   ok           behaves: logs one line, outputs frame_sum (scalar: sum of
 *                all pixels of all frames), sum_image (2x2 F32: 1, 2, 3, NaN),
 *                points (2 points x 4 floats) and report (JSON)
 *   segv         dereferences NULL in add_frame of frame 1 (mid-round)
 *   segv_outputs behaves as "ok" until get_outputs, which dereferences NULL
 *   two_rounds   behaves as "ok" over two rounds (the second planned after
 *                the first's end_round): frame_sum sums all 6 frames
 *   abort        calls abort() in end_round
 *   hang         never returns from end_round
 *   oom          allocates 16 MiB blocks in end_round until malloc fails
 *                (address space is what RLIMIT_AS counts: the blocks are
 *                not touched, so this is quick), then returns
 *                PROCAM_ERR_NO_MEMORY
 *   garbage      writes junk to fd 3 (the worker's control socket,
 *                WORKER_PROTOCOL.md) in end_round, then returns OK
 *   write_frame  writes into the frame it was handed (host memory: in a
 *                worker a read-only shared mapping) in add_frame
 *   try_network, try_write_outside, try_write_scratch, try_signal, try_caps
 *                attempt, in end_round, what the worker sandbox forbids (or,
 *                for the scratch folder, allows) and log "<rule>: blocked
 *                (<error>)" or "<rule>: allowed": a UDP and a TCP socket;
 *                creating $PROCAM_TEST_OUTSIDE; creating $TMPDIR/plugin-file;
 *                SIGCONT to the parent process; CapEff of /proc/self/status
 *                ("caps: <hex>"); try_unix: a Unix stream socket connected to
 *                the named socket $PROCAM_TEST_UNIX ("unix"); try_read:
 *                reading $PROCAM_TEST_SECRET ("read_outside") and
 *                /etc/ld.so.cache ("read_system", a file every program
 *                reads); try_freeze_escape: what the daemon's freeze of
 *                the worker relies on being denied (README.md "Speed"): fork
 *                ("fork"), a thread ("thread", must stay
 *                allowed), a POSIX timer signalling SIGCONT ("timer"),
 *                F_SETSIG ("setsig"), PR_SET_PDEATHSIG ("pdeathsig"),
 *                joining the parent's process group ("setpgid"), native AIO
 *                ("aio"), PTRACE_TRACEME ("traceme"; only tried with
 *                $PROCAM_TEST_TRACEME set: without the sandbox it would make
 *                the test process its tracer), and removing a written page
 *                from a memfd with fallocate(FALLOC_FL_PUNCH_HOLE)
 *                ("punch_hole") and madvise(MADV_REMOVE) ("madv_remove")
 *   scribble     behaves as "ok" plus a fifth output, "heap_image": a
 *                512x512 F32 map (pixel i = i % 251) allocated with the
 *                host's operator new[] (in a worker: its shared heap,
 *                worker/shared_heap.hpp), and get_outputs starts a thread
 *                that, 100 ms later, overwrites that map and every
 *                writable "procam-outputs" mapping of the worker but the
 *                heap (the output arena, found in /proc/self/maps) with
 *                changing bytes for about a second,
 *                creating "scribbled" in its working directory (the
 *                scratch folder) after every pass, or "no-arena" if it
 *                found none: what the daemon returned must not change
 *   stream       plans 4096 frames and does nothing in add_frame: the
 *                per-frame cost of the host itself (bench/worker_bench.cpp)
 * Never load this into a process you care about.
 */
#define _GNU_SOURCE 1 /* F_SETSIG */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <pthread.h>
#include <linux/falloc.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/prctl.h>
#include <sys/ptrace.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>

#include "procam/plugin_abi.h"

#define FX_EXPORT __attribute__((visibility("default")))

FX_EXPORT const procam_plugin_info fx_info __asm__(PROCAM_PLUGIN_INFO_SYMBOL) = {
    PROCAM_PLUGIN_MAGIC, PROCAM_PLUGIN_ABI_VERSION, sizeof(procam_plugin_info), 0, "faults", "0.0.1",
    "ok,segv,abort,hang,oom,garbage,write_frame,scribble,stream,try_network,try_write_outside,try_write_scratch,try_signal,try_caps,try_unix,try_read,try_freeze_escape,two_rounds,segv_outputs"};

struct procam_session {
  char method[32];
  const procam_host_services* host;
  int planned, ended;
  double sum;
  float image[4];
  float points[8];
  procam_pattern_frame frames[3];
  procam_pattern_frame* stream; /* "stream": 4096 frames */
  uint32_t pw, ph;               /* pattern size: the projector's */
  uint8_t* pattern;              /* pw x ph zeros */
  procam_plan plan;
  procam_output outputs[5];
};

/* The C++ runtime's operator new[] / delete[] where the host has one (weak:
   resolved in the process that loads this fixture). */
extern void* _Znam(unsigned long) __attribute__((weak));
#define FX_BIG_SIDE 512
static float* g_big; /* "scribble"'s heap_image: allocated once, kept for the process */

static void set_error(procam_error* err, const char* msg) {
  if (err) snprintf(err->message, sizeof err->message, "%s", msg);
}

static int is(const procam_session* s, const char* m) { return strcmp(s->method, m) == 0; }

static const char* fx_describe(void) {
  return "[{\"name\": \"ok\"}, {\"name\": \"segv\"}, {\"name\": \"abort\"}, {\"name\": \"hang\"},"
         " {\"name\": \"oom\"}, {\"name\": \"garbage\"}, {\"name\": \"write_frame\"},"
         " {\"name\": \"scribble\"}, {\"name\": \"stream\"}, {\"name\": \"try_network\"}, {\"name\": \"try_write_outside\"},"
         " {\"name\": \"try_write_scratch\"}, {\"name\": \"try_signal\"}, {\"name\": \"try_caps\"},"
         " {\"name\": \"try_unix\"}, {\"name\": \"try_read\"}, {\"name\": \"try_freeze_escape\"},"
         " {\"name\": \"two_rounds\"}, {\"name\": \"segv_outputs\"}]";
}

static int fx_session_create(const char* method, const char* params_json, const char* rig_json,
                             procam_session** out, procam_error* err) {
  const char* proj;
  (void)params_json;
  if (strlen(method) >= 32) {
    set_error(err, "unknown method");
    return PROCAM_ERR_INVALID_ARGUMENT;
  }
  *out = calloc(1, sizeof(procam_session));
  if (*out == NULL) return PROCAM_ERR_NO_MEMORY;
  strcpy((*out)->method, method);
  /* The rig JSON (nlohmann, compact): "projector":{"height":H,...,"width":W}. */
  (*out)->pw = 4;
  (*out)->ph = 3;
  proj = rig_json ? strstr(rig_json, "\"projector\":") : NULL;
  if (proj != NULL) {
    const char* h = strstr(proj, "\"height\":");
    const char* w = strstr(proj, "\"width\":");
    if (h != NULL && w != NULL) {
      (*out)->ph = (uint32_t)strtoul(h + 9, NULL, 10);
      (*out)->pw = (uint32_t)strtoul(w + 8, NULL, 10);
    }
  }
  if ((*out)->pw == 0 || (*out)->ph == 0 || (*out)->pw > 16384 || (*out)->ph > 16384) {
    set_error(err, "projector size in the rig description out of range");
    free(*out);
    return PROCAM_ERR_INVALID_ARGUMENT;
  }
  (*out)->pattern = calloc((size_t)(*out)->pw * (*out)->ph, 1);
  if ((*out)->pattern == NULL) {
    free(*out);
    return PROCAM_ERR_NO_MEMORY;
  }
  return PROCAM_OK;
}

static void fx_session_destroy(procam_session* s) {
  free(s->stream);
  free(s->pattern);
  free(s);
}

static int fx_set_host(procam_session* s, const procam_host_services* host, procam_error* err) {
  (void)err;
  s->host = host;
  return PROCAM_OK;
}

static int fx_next_plan(procam_session* s, const procam_plan** plan, procam_error* err) {
  int i;
  if (s->planned >= (is(s, "two_rounds") ? 2 : 1)) return 0;
  ++s->planned;
  for (i = 0; i < 3; ++i) {
    procam_pattern_frame* f = &s->frames[i];
    f->label = i == 0 ? "a" : i == 1 ? "b" : "c";
    f->pattern.width = s->pw;
    f->pattern.height = s->ph;
    f->pattern.channels = 1;
    f->pattern.pixel_type = PROCAM_PIXEL_U8;
    f->pattern.bit_depth = 8;
    f->pattern.stride_bytes = s->pw;
    f->pattern.data = s->pattern;
    f->settings.struct_size = sizeof(procam_frame_settings);
    f->settings.gain_db = -1;
    f->settings.polarizer_deg = NAN;
    f->settings.projector_polarizer_deg = NAN;
  }
  s->plan.frame_count = 3;
  s->plan.frames = s->frames;
  if (is(s, "stream")) {
    s->stream = malloc(4096 * sizeof *s->stream);
    if (s->stream == NULL) {
      set_error(err, "no memory for the stream plan");
      return PROCAM_ERR_NO_MEMORY;
    }
    for (i = 0; i < 4096; ++i) s->stream[i] = s->frames[0];
    s->plan.frame_count = 4096;
    s->plan.frames = s->stream;
  }
  s->plan.note = "three black frames";
  *plan = &s->plan;
  return 1;
}

static int fx_add_frame(procam_session* s, uint32_t index, const procam_image* f, procam_error* err) {
  uint32_t x, y;
  if ((f->pixel_type != PROCAM_PIXEL_U8 && f->pixel_type != PROCAM_PIXEL_U16) || f->channels != 1) {
    set_error(err, "expected 1-channel U8 or U16 frames");
    return PROCAM_ERR_BAD_FRAME;
  }
  if (is(s, "stream")) return PROCAM_OK;
  if (is(s, "segv") && index == 1) *(volatile int*)(uintptr_t)0 = 1;
  if (is(s, "write_frame")) ((volatile uint8_t*)(uintptr_t)f->data)[0] = 0xff;
  for (y = 0; y < f->height; ++y) {
    const uint8_t* row = (const uint8_t*)f->data + y * f->stride_bytes;
    for (x = 0; x < f->width; ++x)
      s->sum += f->pixel_type == PROCAM_PIXEL_U8 ? row[x] : ((const uint16_t*)(const void*)row)[x];
  }
  return PROCAM_OK;
}

static void* fx_nothing(void* arg) { return arg; }

static void fx_log(procam_session* s, const char* line) {
  if (s->host != NULL && s->host->log != NULL) s->host->log(s->host->ctx, PROCAM_LOG_INFO, line);
}

/* Logs "<rule>: allowed" (ok != 0) or "<rule>: blocked (<strerror(errno)>)". */
static void fx_verdict(procam_session* s, const char* rule, int ok) {
  char line[256];
  if (ok) snprintf(line, sizeof line, "%s: allowed", rule);
  else snprintf(line, sizeof line, "%s: blocked (%s)", rule, strerror(errno));
  fx_log(s, line);
}

static void fx_try(procam_session* s) {
  if (is(s, "try_network")) {
    int udp = socket(AF_INET, SOCK_DGRAM, 0);
    fx_verdict(s, "udp", udp >= 0);
    if (udp >= 0) close(udp);
    int tcp = socket(AF_INET6, SOCK_STREAM, 0);
    fx_verdict(s, "tcp", tcp >= 0);
    if (tcp >= 0) close(tcp);
  } else if (is(s, "try_write_outside") || is(s, "try_write_scratch")) {
    char path[1024];
    const char* dir = getenv("TMPDIR");
    int fd;
    if (is(s, "try_write_outside")) snprintf(path, sizeof path, "%s", getenv("PROCAM_TEST_OUTSIDE") ? getenv("PROCAM_TEST_OUTSIDE") : "/tmp/procam-outside");
    else snprintf(path, sizeof path, "%s/plugin-file", dir ? dir : "/tmp");
    fd = open(path, O_CREAT | O_WRONLY | O_TRUNC, 0600);
    fx_verdict(s, is(s, "try_write_outside") ? "write_outside" : "write_scratch", fd >= 0);
    if (fd >= 0) close(fd);
  } else if (is(s, "try_unix")) {
    struct sockaddr_un addr;
    const char* path = getenv("PROCAM_TEST_UNIX");
    int fd = socket(AF_UNIX, SOCK_STREAM, 0), ok = 0;
    memset(&addr, 0, sizeof addr);
    addr.sun_family = AF_UNIX;
    snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path ? path : "/nonexistent");
    if (fd >= 0) ok = connect(fd, (const struct sockaddr*)&addr, sizeof addr) == 0;
    fx_verdict(s, "unix", ok);
    if (fd >= 0) close(fd);
  } else if (is(s, "try_read")) {
    const char* secret = getenv("PROCAM_TEST_SECRET");
    int fd = open(secret ? secret : "/nonexistent", O_RDONLY);
    char c;
    fx_verdict(s, "read_outside", fd >= 0 && read(fd, &c, 1) == 1);
    if (fd >= 0) close(fd);
    fd = open("/etc/ld.so.cache", O_RDONLY);
    fx_verdict(s, "read_system", fd >= 0 && read(fd, &c, 1) == 1);
    if (fd >= 0) close(fd);
  } else if (is(s, "try_freeze_escape")) {
    pid_t child = fork();
    if (child == 0) _exit(0);
    fx_verdict(s, "fork", child > 0);
    if (child > 0) waitpid(child, NULL, 0);
    {
      pthread_t t;
      int rc = pthread_create(&t, NULL, fx_nothing, NULL);
      if (rc != 0) errno = rc;
      fx_verdict(s, "thread", rc == 0);
      if (rc == 0) pthread_join(t, NULL);
    }
    {
      struct sigevent ev;
      timer_t timer;
      int ok;
      memset(&ev, 0, sizeof ev);
      ev.sigev_notify = SIGEV_SIGNAL;
      ev.sigev_signo = SIGCONT;
      ok = timer_create(CLOCK_MONOTONIC, &ev, &timer) == 0;
      fx_verdict(s, "timer", ok);
      if (ok) timer_delete(timer);
    }
    {
      int fds[2];
      if (pipe(fds) == 0) {
        fx_verdict(s, "setsig", fcntl(fds[0], F_SETSIG, SIGCONT) == 0);
        close(fds[0]);
        close(fds[1]);
      }
    }
    fx_verdict(s, "pdeathsig", prctl(PR_SET_PDEATHSIG, SIGCONT) == 0);
    fx_verdict(s, "setpgid", setpgid(0, getpgid(getppid())) == 0);
    {
      unsigned long ctx = 0;
      int ok = syscall(SYS_io_setup, 1, &ctx) == 0;
      fx_verdict(s, "aio", ok);
      if (ok) syscall(SYS_io_destroy, ctx);
    }
    if (getenv("PROCAM_TEST_TRACEME") != NULL) fx_verdict(s, "traceme", ptrace(PTRACE_TRACEME, 0, NULL, NULL) == 0);
    {
      int fd = memfd_create("fx-holes", 0);
      char* page = NULL;
      if (fd >= 0 && ftruncate(fd, 8192) == 0) {
        page = mmap(NULL, 8192, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
        if (page == MAP_FAILED) page = NULL;
      }
      if (page != NULL) {
        memset(page, 1, 8192);
        fx_verdict(s, "punch_hole", fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, 0, 4096) == 0);
        fx_verdict(s, "madv_remove", madvise(page + 4096, 4096, MADV_REMOVE) == 0);
        munmap(page, 8192);
      }
      if (fd >= 0) close(fd);
    }
  } else if (is(s, "try_signal")) {
    fx_verdict(s, "signal", kill(getppid(), SIGCONT) == 0);
  } else if (is(s, "try_caps")) {
    char line[256], out[300];
    FILE* f = fopen("/proc/self/status", "r");
    while (f != NULL && fgets(line, sizeof line, f) != NULL)
      if (strncmp(line, "CapEff:", 7) == 0) {
        line[strcspn(line, "\n")] = '\0';
        snprintf(out, sizeof out, "caps: %s", line + 8);
        fx_log(s, out);
      }
    if (f != NULL) fclose(f);
  }
}

static int fx_end_round(procam_session* s, procam_error* err) {
  fx_try(s);
  s->ended = 1;
  if (is(s, "abort")) abort();
  if (is(s, "hang"))
    for (;;) sleep(1);
  if (is(s, "garbage")) {
    static const char junk[] = "this is not a procam worker message";
    if (write(3, junk, sizeof junk) < 0) {
      set_error(err, "fd 3 is not writable: not running in a worker?");
      return PROCAM_ERR_INTERNAL;
    }
  }
  if (is(s, "oom")) {
    void* head = NULL;
    size_t mib = 0;
    for (;;) {
      void** block = malloc(16u << 20);
      if (block == NULL) break;
      *block = head;
      head = block;
      mib += 16;
    }
    while (head != NULL) {
      void* next = *(void**)head;
      free(head);
      head = next;
    }
    snprintf(err->message, sizeof err->message, "out of memory after %zu MiB", mib);
    return PROCAM_ERR_NO_MEMORY;
  }
  if (s->host != NULL && s->host->log != NULL) s->host->log(s->host->ctx, PROCAM_LOG_INFO, "decoded 3 frames");
  if (s->host != NULL && s->host->progress != NULL) s->host->progress(s->host->ctx, 1.0, "sum");
  return PROCAM_OK;
}

static void fx_sleep_ms(long ms) {
  struct timespec t = {ms / 1000, (ms % 1000) * 1000000L};
  nanosleep(&t, NULL);
}

static void fx_touch(const char* name) {
  int fd = open(name, O_CREAT | O_WRONLY | O_TRUNC, 0600);
  if (fd >= 0) close(fd);
}

/* "scribble": writes over the worker's output arena after the reply. */
static void* fx_scribbler(void* arg) {
  int pass, found = 0;
  (void)arg;
  fx_sleep_ms(100);
  for (pass = 0; pass < 50; ++pass) {
    char line[512];
    FILE* maps = fopen("/proc/self/maps", "r");
    while (maps != NULL && fgets(line, sizeof line, maps) != NULL) {
      unsigned long lo, hi;
      char perms[8];
      if (strstr(line, "procam-outputs") == NULL || strstr(line, "procam-outputs-heap") != NULL ||
          sscanf(line, "%lx-%lx %7s", &lo, &hi, perms) != 3 || perms[1] != 'w')
        continue;
      memset((void*)lo, 0x40 + pass % 32, hi - lo);
      found = 1;
    }
    if (g_big != NULL) memset(g_big, 0x40 + pass % 32, sizeof(float) * FX_BIG_SIDE * FX_BIG_SIDE);
    if (maps != NULL) fclose(maps);
    /* Every pass: the daemon empties the scratch folder when a reused
       worker's session ends, and a frozen worker scribbles only after that. */
    fx_touch(found ? "scribbled" : "no-arena");
    fx_sleep_ms(20);
  }
  return NULL;
}

static int fx_get_outputs(procam_session* s, const procam_output** outs, uint32_t* count, procam_error* err) {
  int i;
  (void)err;
  if (is(s, "segv_outputs")) *(volatile int*)(uintptr_t)0 = 1;
  memset(s->outputs, 0, sizeof s->outputs);
  s->outputs[0].name = "frame_sum";
  s->outputs[0].kind = PROCAM_OUTPUT_SCALAR;
  s->outputs[0].unit = "";
  s->outputs[0].scalar = s->sum;
  s->image[0] = 1;
  s->image[1] = 2;
  s->image[2] = 3;
  s->image[3] = NAN;
  s->outputs[1].name = "sum_image";
  s->outputs[1].kind = PROCAM_OUTPUT_IMAGE;
  s->outputs[1].unit = "mm";
  s->outputs[1].image.width = 2;
  s->outputs[1].image.height = 2;
  s->outputs[1].image.channels = 1;
  s->outputs[1].image.pixel_type = PROCAM_PIXEL_F32;
  s->outputs[1].image.bit_depth = 32;
  s->outputs[1].image.stride_bytes = 8;
  s->outputs[1].image.data = s->image;
  for (i = 0; i < 8; ++i) s->points[i] = (float)i;
  s->outputs[2].name = "points";
  s->outputs[2].kind = PROCAM_OUTPUT_POINTS;
  s->outputs[2].points = s->points;
  s->outputs[2].point_count = 2;
  s->outputs[2].point_stride = 4;
  s->outputs[2].point_fields = "x,y,z,i";
  s->outputs[3].name = "report";
  s->outputs[3].kind = PROCAM_OUTPUT_JSON;
  s->outputs[3].json = "{\"frames\": 3}";
  *count = 4;
  if (is(s, "scribble")) {
    pthread_t t;
    if (g_big == NULL && _Znam != NULL) g_big = (float*)_Znam(sizeof(float) * FX_BIG_SIDE * FX_BIG_SIDE);
    if (g_big != NULL) {
      for (i = 0; i < FX_BIG_SIDE * FX_BIG_SIDE; ++i) g_big[i] = (float)(i % 251);
      s->outputs[4].name = "heap_image";
      s->outputs[4].kind = PROCAM_OUTPUT_IMAGE;
      s->outputs[4].unit = "";
      s->outputs[4].image.width = FX_BIG_SIDE;
      s->outputs[4].image.height = FX_BIG_SIDE;
      s->outputs[4].image.channels = 1;
      s->outputs[4].image.pixel_type = PROCAM_PIXEL_F32;
      s->outputs[4].image.bit_depth = 32;
      s->outputs[4].image.stride_bytes = sizeof(float) * FX_BIG_SIDE;
      s->outputs[4].image.data = g_big;
      *count = 5;
    }
    if (pthread_create(&t, NULL, fx_scribbler, NULL) == 0) pthread_detach(t);
  }
  *outs = s->outputs;
  return PROCAM_OK;
}

static const procam_plugin_vtable fx_vtable = {
    PROCAM_PLUGIN_ABI_VERSION, sizeof(procam_plugin_vtable), fx_describe, fx_session_create,
    fx_session_destroy, fx_next_plan, fx_add_frame, fx_end_round, fx_get_outputs, fx_set_host, NULL};

FX_EXPORT const procam_plugin_vtable* procam_plugin_create(uint32_t host_abi) {
  return host_abi == PROCAM_PLUGIN_ABI_VERSION ? &fx_vtable : NULL;
}

// SPDX-License-Identifier: MIT
// procam-plugin-worker: hosts one decoder-plugin session for procamd (or
// `procam decode`) in its own process (README.md "Process model"; protocol:
// WORKER_PROTOCOL.md). Started by the daemon with the control socket on fd 3;
// not meant to be run by hand.
//
// It loads the plugin with the same PluginHost code as the daemon (ELF
// check, dlopen, vtable and describe() checks; no probe: the daemon did
// that) and drives it through the same Session, whose checks run here and
// again in the daemon. Frames are read from the shared ring (mapped
// read-only); plans go back as sealed memfd blobs, outputs through the
// output arena (output_arena.hpp), where maps the plugin allocated in the
// worker's shared heap (shared_heap.hpp, its operator new) are named
// rather than copied.
// Exit: 0 when the daemon closes the socket; 2 on a protocol error from
// the daemon's side; a plugin crash ends it by that signal.
#include <malloc.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "procam/core/log.hpp"
#include "procam/host/plugin_host.hpp"
#include "output_arena.hpp"
#include "sandbox.hpp"
#include "shared_heap.hpp"
#include "worker_wire.hpp"

using namespace procam;
using namespace procam::host;

static_assert(wire::kSandboxLandlockScope == worker::kLandlockScope && wire::kSandboxSeccomp == worker::kSeccomp &&
              wire::kSandboxFreezeSafe == worker::kFreezeSafe && wire::kSandboxPagesStay == worker::kPagesStay);

namespace {

constexpr int kSock = wire::kControlFd;
uint32_t g_seq = 0;  // the request being served: replies and reports carry it

void send_or_die(wire::Msg type, const std::string& payload, int fd = -1) {
  if (!wire::send_msg(kSock, type, g_seq, payload, fd)) std::_Exit(0);  // the daemon is gone
}

void reply_error(const Status& st) { send_or_die(wire::Msg::error, wire::encode_error(st)); }

void reply_ok(const std::string& payload = {}, int fd = -1) { send_or_die(wire::Msg::ok, payload, fd); }

// Bulk replies are written straight into their memfd (one copy).
void reply_blob(uint8_t flag, const std::function<void(wire::Writer&)>& encode, const char* name) {
  auto blob = wire::make_sealed_blob(encode, name);
  if (!blob) return reply_error(blob.status());
  wire::Writer w;
  w.u8(flag);
  reply_ok(w.bytes(), blob->get());
}

// The worker's allocator keeps what the plugin frees, for the next round
// and the next scan of a reused worker (README.md "Speed"). glibc's defaults
// serve each block over 128 KiB (raised to the largest one freed so far)
// with its own mmap and give it back with munmap at free: a plugin that
// plans 41 patterns of 768 KiB (structured-light's ensemble) paid 41
// munmaps of written memory in the closing next_plan -- about 10 ms on the
// project's VM, on the client's time after the last frame -- and the page
// faults of 32 MB again in the next scan's plan. Blocks up to 32 MiB (the
// largest mmap threshold glibc allows) now come from the heap, and the
// heap is trimmed only when 1 GiB lies free at its top. What this keeps is
// bounded by the plugin's own peak (and the address-space limit); an idle
// worker is ended after idle_timeout. The daemon keeps glibc's defaults.
void tune_allocator() {
  ::mallopt(M_MMAP_THRESHOLD, 32 << 20);
  ::mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

void apply_limits(uint64_t memory_limit_mb) {
  rlimit core{0, 0};
  ::setrlimit(RLIMIT_CORE, &core);
#if defined(__SANITIZE_ADDRESS__)
  (void)memory_limit_mb;  // ASan reserves terabytes of address space
#else
  if (memory_limit_mb > 0) {
    rlimit as{};
    as.rlim_cur = as.rlim_max = static_cast<rlim_t>(memory_limit_mb) << 20;
    ::setrlimit(RLIMIT_AS, &as);
  }
#endif
}

struct Served {
  // The plugin stays loaded after a session ends (end_session), so the next
  // session of the same plugin finds its memory warm (README.md "Worker reuse").
  std::optional<PluginHost> host;
  std::string plugin_file;
  std::optional<Session> session;
  wire::Mapping ring;
  // Outputs of every session are written here; the daemon maps it once
  // (output_arena.hpp; WORKER_PROTOCOL.md "Output arena").
  wire::OutputArena outputs;
  // Sandbox on: after the plugin is loaded, reads are restricted too
  // (worker::restrict_reads), with the scratch folder readable.
  bool sandbox = false;
  std::string scratch;
  std::vector<std::string> readable;  // --readable: more folders to read
  uint32_t slots = 0;
  uint64_t slot_size = 0;
};

// create: load the plugin file and start the session.
void serve_create(Served& s, const wire::Message& m) {
  if (!m.fd) return reply_error(Error(Code::invalid_argument, "create request without its data blob"));
  auto blob = wire::map_sealed_blob(m.fd.get());
  if (!blob) return reply_error(blob.status());
  wire::CreateRequest req;
  if (Status st = wire::decode_create(*blob, req); !st) return reply_error(st);
  if (!s.host) {
    LoadOptions lo;
    lo.probe_in_child = false;  // the daemon probed this file
    s.host.emplace(lo);
    IsolationOptions here;
    here.mode = Isolation::in_process;
    s.host->set_isolation(here);
    s.plugin_file = req.plugin_file;
    if (Status st = s.host->load_file(req.plugin_file); !st) return reply_error(st);
    if (s.sandbox) {
      const std::string problem = worker::restrict_reads(req.plugin_file, s.scratch, s.readable);
      if (!problem.empty()) std::fprintf(stderr, "procam-plugin-worker: partial sandbox: %s\n", problem.c_str());
    }
  } else if (req.plugin_file != s.plugin_file) {
    return reply_error(Error(Code::failed_precondition, "this worker hosts '" + s.plugin_file +
                                                            "', not '" + req.plugin_file + "'"));
  }
  PluginHost& host = *s.host;
  if (host.find(req.plugin_name) == nullptr)
    return reply_error(Error(Code::failed_precondition, "plugin file '" + req.plugin_file +
                                                            "' no longer holds plugin '" + req.plugin_name + "'"));
  auto session = host.create_session(req.plugin_name, req.method, req.params, req.rig, req.inputs);
  if (!session) return reply_error(session.status());
  s.session.emplace(std::move(*session));
  // Host services: the Session's bridge checked and limited them; forward.
  s.session->set_log_handler([](log::Level lv, const std::string& line) {
    wire::Writer w;
    w.i32(static_cast<int32_t>(lv));  // log::Level debug..error == PROCAM_LOG_DEBUG..ERROR
    w.str(line);
    send_or_die(wire::Msg::log, w.bytes());
  });
  s.session->set_progress_handler([](double fraction, const std::string& stage) {
    wire::Writer w;
    w.f64(fraction);
    w.str(stage);
    send_or_die(wire::Msg::progress, w.bytes());
  });
  wire::Writer w;
  w.u8(s.session->has_host_services() ? 1 : 0);
  reply_ok(w.bytes());
}

void serve_add_frame(Served& s, const wire::Message& m) {
  wire::Reader r(reinterpret_cast<const uint8_t*>(m.payload.data()), m.payload.size());
  const uint32_t index = r.u32("index"), slot = r.u32("slot");
  procam_image v{};
  v.width = r.u32("width");
  v.height = r.u32("height");
  v.channels = r.u32("channels");
  v.pixel_type = r.u32("pixel type");
  v.bit_depth = r.u32("bit depth");
  if (!r.ok()) return reply_error(Error(Code::invalid_argument, "malformed add_frame: " + r.error()));
  const size_t row = wire::packed_row_bytes(v);
  size_t bytes = 0;
  if (s.slots == 0 || slot >= s.slots || row == 0 || __builtin_mul_overflow(row, size_t{v.height}, &bytes) ||
      bytes > s.slot_size)
    return reply_error(Error(Code::invalid_argument, "add_frame names slot " + std::to_string(slot) +
                                                         " or a frame that does not fit the ring"));
  v.stride_bytes = row;
  v.data = s.ring.data() + slot * s.slot_size;
  Status st = s.session->add_frame(index, v);
  if (!st) return reply_error(st);
  reply_ok();
}

// next_plan; true when it replied "no more rounds".
bool serve_next_plan(Served& s) {
  auto plan = s.session->next_plan();
  if (!plan) {
    reply_error(plan.status());
    return false;
  }
  if (!plan->has_value()) {
    reply_ok(std::string(1, '\0'));
    return true;
  }
  reply_blob(1, [&](wire::Writer& w) { wire::write_plan(w, **plan); }, "procam-plan");
  return false;
}

// get_outputs. `mode` (checked <= 2): 1 = into the output arena (a worker
// the daemon may reuse), 2 = the same, naming maps that lie in the shared
// heap instead of copying them (the daemon reads them with this worker
// stopped), 0 = a sealed blob of its own (WORKER_PROTOCOL.md).
void serve_get_outputs(Served& s, uint8_t mode) {
  auto outs = s.session->outputs();
  if (!outs) return reply_error(outs.status());
  const wire::HeapSpan heap{worker::heap::base(), worker::heap::size()};
  const auto encode = [&](wire::Writer& w) { wire::write_outputs(w, *outs, mode == 2 ? &heap : nullptr); };
  if (mode == 0) {
    auto blob = wire::make_sealed_blob(encode, "procam-outputs-blob");
    if (!blob) return reply_error(blob.status());
    wire::Writer w;
    w.u8(1);
    w.u64(0);
    return reply_ok(w.bytes(), blob->get());
  }
  auto written = s.outputs.write(encode);
  if (!written) return reply_error(written.status());
  wire::Writer w;
  w.u8(1);
  w.u64(written->used);
  reply_ok(w.bytes(), written->new_fd);
}

int serve(const worker::SandboxReport& sandbox, bool sandbox_on, std::vector<std::string> readable) {
  wire::Writer hello;
  hello.u32(sandbox.flags);
  hello.str(sandbox.scratch);
  hello.str(sandbox.problems.substr(0, 4096));
  // The shared heap goes with hello (the daemon maps it once); the worker
  // keeps only its mapping.
  if (!wire::send_msg(kSock, wire::Msg::hello, 0, hello.bytes(), worker::heap::fd())) return 0;
  worker::heap::close_fd();
  Served s;
  s.sandbox = sandbox_on;
  s.scratch = sandbox.scratch;
  s.readable = std::move(readable);
  for (;;) {
    auto m = wire::recv_msg(kSock, -1);
    if (!m) {
      if (m.status().code() == Code::unavailable) return 0;  // the daemon closed: done
      std::fprintf(stderr, "procam-plugin-worker: %s\n", m.status().to_string().c_str());
      return 2;
    }
    g_seq = m->seq;
    const auto type = static_cast<wire::Msg>(m->type);
    if (type == wire::Msg::create) {
      if (s.session) return 2;
      serve_create(s, *m);
      continue;
    }
    if (!s.session) {
      reply_error(Error(Code::failed_precondition, std::string(wire::msg_name(m->type)) + " before create"));
      continue;
    }
    switch (type) {
      case wire::Msg::next_plan: (void)serve_next_plan(s); break;
      case wire::Msg::set_ring: {
        wire::Reader r(reinterpret_cast<const uint8_t*>(m->payload.data()), m->payload.size());
        const uint32_t slots = r.u32("slots");
        const uint64_t slot_size = r.u64("slot size");
        if (!r.ok() || !m->fd) {
          reply_error(Error(Code::invalid_argument, "malformed set_ring"));
          break;
        }
        auto map = wire::map_ring(m->fd.get(), slots, slot_size);
        if (!map) {
          reply_error(map.status());
          break;
        }
        s.ring = std::move(*map);
        s.slots = slots;
        s.slot_size = slot_size;
        reply_ok();
        break;
      }
      case wire::Msg::add_frame: serve_add_frame(s, *m); break;
      case wire::Msg::end_round: {
        // Payload (version 6): empty, or u8 `ahead`: 0 = only end_round;
        // 1 + m = after the ok, go on with next_plan and, when it says no
        // more rounds, get_outputs in mode m, each reply sent unasked with
        // the request numbers the daemon counts for them (seq + 1, seq + 2)
        // (WORKER_PROTOCOL.md "Replies ahead").
        uint8_t ahead = 0;
        if (Status bad = wire::decode_end_round(m->payload, ahead); !bad) {
          reply_error(bad);
          break;
        }
        Status st = s.session->end_round();
        if (!st) {
          reply_error(st);
          break;
        }
        reply_ok();
        if (ahead == 0) break;
        g_seq = m->seq + 1;
        if (!serve_next_plan(s)) break;  // a plan (or an error): the daemon asks again
        g_seq = m->seq + 2;
        serve_get_outputs(s, static_cast<uint8_t>(ahead - 1));
        break;
      }
      case wire::Msg::stop: {
        Status st = s.session->stop();
        if (!st) reply_error(st);
        else reply_ok();
        break;
      }
      case wire::Msg::end_session:
        s.session.reset();  // session_destroy; the plugin stays loaded
        reply_ok();
        break;
      case wire::Msg::get_outputs: {
        wire::Reader req(reinterpret_cast<const uint8_t*>(m->payload.data()), m->payload.size());
        const uint8_t mode = req.u8("arena flag");
        if (!req.ok() || mode > 2) {
          reply_error(Error(Code::invalid_argument, "malformed get_outputs: " +
                                                        (req.ok() ? "mode " + std::to_string(mode) : req.error())));
          break;
        }
        serve_get_outputs(s, mode);
        break;
      }
      default:
        std::fprintf(stderr, "procam-plugin-worker: unexpected message %u\n", m->type);
        return 2;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t memory_limit_mb = 0;
  bool sandbox = true;
  std::string scratch_parent;
  std::vector<std::string> readable;
  pid_t parent_pid = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--memory-limit-mb" && i + 1 < argc) {
      memory_limit_mb = std::strtoull(argv[++i], nullptr, 10);
    } else if (a == "--sandbox" && i + 1 < argc) {
      sandbox = std::string(argv[++i]) != "0";
    } else if (a == "--scratch-parent" && i + 1 < argc) {
      scratch_parent = argv[++i];
    } else if (a == "--readable" && i + 1 < argc) {
      readable.emplace_back(argv[++i]);
    } else if (a == "--parent-pid" && i + 1 < argc) {
      parent_pid = static_cast<pid_t>(std::strtol(argv[++i], nullptr, 10));
    } else {
      std::fprintf(stderr,
                   "procam-plugin-worker: unknown argument '%s'\n"
                   "(started by procamd with its control socket on fd 3; not for interactive use)\n",
                   a.c_str());
      return 2;
    }
  }
  // End with the daemon, even while it keeps this worker stopped (SIGSTOP
  // after the outputs reply: a stopped process reads no EOF). The daemon
  // spawns every worker from one thread that lives as long as it does, so
  // this fires when the daemon dies, not when some thread of it ends. The
  // sandbox's seccomp filter keeps plugins from changing it.
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (parent_pid > 0 && ::getppid() != parent_pid) return 0;  // the daemon died before the prctl
  ::signal(SIGPIPE, SIG_IGN);
  tune_allocator();
  // Nothing of the parent's but stdio and the control socket.
  ::close_range(wire::kControlFd + 1, ~0u, 0);
  apply_limits(memory_limit_mb);
#if !defined(__SANITIZE_ADDRESS__)
  // Large allocations from here on come from the shared heap
  // (shared_heap_new.cpp): 1 GiB of address space, a quarter of the limit
  // at most; pages only where the plugin allocates.
  const uint64_t limit = memory_limit_mb >= (uint64_t{1} << 40) ? 0 : memory_limit_mb << 20;
  worker::heap::init(static_cast<size_t>(limit > 0 ? std::min<uint64_t>(uint64_t{1} << 30, limit / 4)
                                                   : uint64_t{1} << 30));
#endif
  // Plugin log lines reach the daemon through the protocol; only the
  // worker's own warnings go to stderr (the daemon's log).
  log::configure("warn,plugins=off");
  // Before any plugin code (its static constructors run in dlopen).
  const worker::SandboxReport report = sandbox ? worker::enter_sandbox(scratch_parent) : worker::SandboxReport{};
  return serve(report, sandbox, std::move(readable));
}

// SPDX-License-Identifier: MIT
// Least privilege for procam-plugin-worker (README.md "Process model",
// "Least privilege"), applied before any plugin code runs:
//   - a private scratch folder (mkdtemp, 0700) that becomes TMPDIR and the
//     working directory: the only place the plugin may create or change files;
//   - no_new_privs, every capability dropped (effective, permitted,
//     inheritable, ambient, bounding set where allowed);
//   - Landlock (kernel 5.13+; what the running kernel offers): file writes,
//     creation, removal, truncation only beneath the scratch folder (and
//     writes to /dev/null); TCP bind/connect denied (ABI 4+); no signals to
//     and no abstract-socket connections outside the worker (ABI 6+); ptrace
//     of processes outside the worker denied (every ABI);
//   - seccomp: socket() fails with EACCES for every family, AF_UNIX too (no
//     network, no connecting to named Unix sockets: the worker needs no
//     socket but the one it inherited), io_uring_setup fails with ENOSYS
//     (it could bypass the socket rule); no new processes (clone only with
//     CLONE_THREAD), no timer_create, mq_notify, F_SETSIG, PR_SET_PDEATHSIG,
//     setsid, setpgid, ptrace, io_setup: what the daemon's freeze of the
//     worker after its outputs reply relies on (README.md "Speed");
//   - after the plugin is loaded (restrict_reads): Landlock file reads and
//     execution only beneath the plugin's folder, the system's library and
//     data folders and the scratch folder.
// What was applied is reported, not assumed: the daemon logs it and the
// tests skip a rule the kernel cannot enforce.
// Single-threaded use at worker start; not thread-safe.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace procam::worker {

enum SandboxFlags : uint32_t {
  kScratch = 1u << 0,
  kNoNewPrivs = 1u << 1,
  kCapsDropped = 1u << 2,
  kLandlockFs = 1u << 3,
  kLandlockNet = 1u << 4,
  kLandlockScope = 1u << 5,
  kSeccomp = 1u << 6,
  // The seccomp filter also denies what would make freezing the worker
  // unsound (new processes, delayed SIGCONT, parent-death signal, process
  // group changes, ptrace, native AIO): set with kSeccomp.
  kFreezeSafe = 1u << 7,
  // The seccomp filter also denies removing pages from shared memory
  // (madvise MADV_REMOVE, fallocate FALLOC_FL_PUNCH_HOLE or
  // FALLOC_FL_COLLAPSE_RANGE): a page of the shared heap, once written,
  // stays written, so the daemon checks each page once per worker instead
  // of on every outputs reply (README.md "Speed"). Set with kSeccomp.
  kPagesStay = 1u << 8,
};

struct SandboxReport {
  uint32_t flags = 0;   // SandboxFlags applied
  std::string scratch;  // the scratch folder ("" if none)
  std::string problems; // what could not be applied, for the daemon log
};

// Creates the scratch folder in `scratch_parent` ("" = $TMPDIR or /tmp) and
// applies every rule it can. Never fails as a whole: see the report.
SandboxReport enter_sandbox(const std::string& scratch_parent);

// Once the plugin is loaded (its file and libraries read, dlopen done):
// a second Landlock layer lets the worker read and execute files only
// beneath the plugin file's folder, /usr, /lib, /lib64, /proc, the CPU and
// cgroup files of /sys, /etc/ld.so.cache, /etc/localtime, /dev/{null,zero,
// urandom,random}, `scratch` and each of `readable` (IsolationOptions::
// readable). Returns "" or what could not be applied (the kernel lacks
// Landlock): the worker runs on without the rule.
std::string restrict_reads(const std::string& plugin_file, const std::string& scratch,
                           const std::vector<std::string>& readable);

}  // namespace procam::worker

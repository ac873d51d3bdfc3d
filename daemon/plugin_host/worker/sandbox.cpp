// SPDX-License-Identifier: MIT
// Least privilege for the worker (sandbox.hpp).
#include "sandbox.hpp"

#include <errno.h>
#include <fcntl.h>
#include <linux/audit.h>
#include <linux/capability.h>
#include <linux/falloc.h>
#include <linux/filter.h>
#include <linux/landlock.h>
#include <linux/seccomp.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace procam::worker {
namespace {

void note(SandboxReport& r, const std::string& what) {
  r.problems += (r.problems.empty() ? "" : "; ") + what + ": " + std::strerror(errno);
}

void drop_capabilities(SandboxReport& r) {
  int last = 40;
  std::ifstream("/proc/sys/kernel/cap_last_cap") >> last;
  for (int c = 0; c <= last; ++c) (void)::prctl(PR_CAPBSET_DROP, c, 0, 0, 0);  // EPERM without CAP_SETPCAP
  (void)::prctl(PR_CAP_AMBIENT, PR_CAP_AMBIENT_CLEAR_ALL, 0, 0, 0);
  __user_cap_header_struct hdr{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2] = {};
  if (::syscall(SYS_capset, &hdr, data) == 0) r.flags |= kCapsDropped;
  else note(r, "capset");
}

// Landlock's kernel ABI (stable; the build host's <linux/landlock.h> may
// predate the network and scope members, so the layout is spelled out).
struct RulesetAttr {
  uint64_t handled_access_fs;
  uint64_t handled_access_net;  // ABI 4+
  uint64_t scoped;              // ABI 6+
};
constexpr uint64_t kFsExecute = 1ull << 0, kFsReadFile = 1ull << 2, kFsReadDir = 1ull << 3;
constexpr uint64_t kFsWriteFile = 1ull << 1, kFsRemoveDir = 1ull << 4, kFsRemoveFile = 1ull << 5,
                   kFsMakeChar = 1ull << 6, kFsMakeDir = 1ull << 7, kFsMakeReg = 1ull << 8,
                   kFsMakeSock = 1ull << 9, kFsMakeFifo = 1ull << 10, kFsMakeBlock = 1ull << 11,
                   kFsMakeSym = 1ull << 12, kFsRefer = 1ull << 13, kFsTruncate = 1ull << 14;
constexpr uint64_t kNetBindTcp = 1ull << 0, kNetConnectTcp = 1ull << 1;
constexpr uint64_t kScopeAbstractUnix = 1ull << 0, kScopeSignal = 1ull << 1;

void landlock(SandboxReport& r) {
  const long abi = ::syscall(SYS_landlock_create_ruleset, nullptr, 0, LANDLOCK_CREATE_RULESET_VERSION);
  if (abi < 1) {
    note(r, "Landlock (kernel 5.13+ with landlock in lsm=)");
    return;
  }
  uint64_t fs = kFsWriteFile | kFsRemoveDir | kFsRemoveFile | kFsMakeChar | kFsMakeDir | kFsMakeReg |
                kFsMakeSock | kFsMakeFifo | kFsMakeBlock | kFsMakeSym;
  if (abi >= 2) fs |= kFsRefer;
  if (abi >= 3) fs |= kFsTruncate;
  RulesetAttr attr{};
  attr.handled_access_fs = fs;
  size_t attr_size = offsetof(RulesetAttr, handled_access_net);
  if (abi >= 4) {
    attr.handled_access_net = kNetBindTcp | kNetConnectTcp;  // no rule: every TCP bind/connect denied
    attr_size = offsetof(RulesetAttr, scoped);
  }
  if (abi >= 6) {
    attr.scoped = kScopeAbstractUnix | kScopeSignal;
    attr_size = sizeof attr;
  }
  const int ruleset = static_cast<int>(::syscall(SYS_landlock_create_ruleset, &attr, attr_size, 0));
  if (ruleset < 0) {
    note(r, "landlock_create_ruleset");
    return;
  }
  auto allow = [&](const std::string& path, uint64_t access) {
    landlock_path_beneath_attr pb{};
    pb.allowed_access = access;
    pb.parent_fd = ::open(path.c_str(), O_PATH | O_CLOEXEC);
    if (pb.parent_fd < 0) return;
    (void)::syscall(SYS_landlock_add_rule, ruleset, LANDLOCK_RULE_PATH_BENEATH, &pb, 0);
    ::close(pb.parent_fd);
  };
  if (!r.scratch.empty()) allow(r.scratch, fs);
  allow("/dev/null", kFsWriteFile | (abi >= 3 ? kFsTruncate : 0));
  if (::syscall(SYS_landlock_restrict_self, ruleset, 0) == 0) {
    r.flags |= kLandlockFs;
    if (abi >= 4) r.flags |= kLandlockNet;
    if (abi >= 6) r.flags |= kLandlockScope;
  } else {
    note(r, "landlock_restrict_self");
  }
  ::close(ruleset);
}

void seccomp(SandboxReport& r) {
#if defined(__x86_64__)
  constexpr uint32_t arch = AUDIT_ARCH_X86_64;
#elif defined(__aarch64__)
  constexpr uint32_t arch = AUDIT_ARCH_AARCH64;
#else
  r.problems += (r.problems.empty() ? "" : "; ") + std::string("seccomp: unsupported architecture");
  return;
#endif
  sock_filter filter[] = {
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, arch, 1, 0),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_KILL_PROCESS),  // another ABI (x32, ia32): not ours
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_io_uring_setup, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | ENOSYS),
      // No new sockets of any family: the worker talks only over the
      // socketpair it inherited. AF_UNIX too, so a plugin cannot connect to
      // named Unix sockets (the daemon user's D-Bus, an agent, procamd's own).
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_socket, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EACCES),
      // Freezing (README.md "Speed", "Why freezing is sound"): after the
      // outputs reply the daemon stops the worker with SIGSTOP and reads the
      // output arena in place. That holds only if nothing else can write the
      // arena or resume the worker while it is stopped, so:
      //  - no new processes: a child (fork, vfork, posix_spawn, clone without
      //    CLONE_THREAD) would inherit the writable arena mapping and not be
      //    stopped with the worker. Threads (CLONE_THREAD) stay allowed: they
      //    stop with their thread group. clone3 passes its flags in memory,
      //    which seccomp cannot read: ENOSYS, and glibc falls back to clone.
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_clone3, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | ENOSYS),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_clone, 0, 4),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[0])),  // flags, low 32 bits (LE)
      BPF_JUMP(BPF_JMP | BPF_JSET | BPF_K, CLONE_THREAD, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),  // also reached from clone without CLONE_THREAD
#if defined(__NR_fork)
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_fork, 1, 0),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_vfork, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
#endif
      //  - no way to have the kernel send SIGCONT later: a POSIX timer or a
      //    message-queue notification (the signal is in memory: all denied),
      //    F_SETSIG (the signal of O_ASYNC, leases, dnotify), a parent-death
      //    signal, a move to another process group or session (a stopped
      //    group that becomes orphaned gets SIGHUP + SIGCONT), and ptrace
      //    (PTRACE_TRACEME would make the daemon its tracer);
      //  - no asynchronous writes into memory that complete while stopped:
      //    native AIO (io_setup; io_uring is denied above).
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_io_setup, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | ENOSYS),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_timer_create, 4, 0),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_mq_notify, 3, 0),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_setsid, 2, 0),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_setpgid, 1, 0),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_ptrace, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_fcntl, 0, 4),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[1])),  // cmd
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, F_SETSIG, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      //  - (kPagesStay) no removing pages from shared memory: the daemon
      //    checks a page of the shared heap only the first time an output
      //    lies on it (a hole would make the daemon allocate what it reads).
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_madvise, 0, 4),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[2])),  // advice
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, MADV_REMOVE, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_fallocate, 0, 4),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[1])),  // mode
      BPF_JUMP(BPF_JMP | BPF_JSET | BPF_K, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_COLLAPSE_RANGE, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_prctl, 0, 4),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[0])),  // option
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, PR_SET_PDEATHSIG, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
  };
  sock_fprog prog{static_cast<unsigned short>(sizeof filter / sizeof filter[0]), filter};
  if (::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &prog, 0, 0) == 0) r.flags |= kSeccomp | kFreezeSafe | kPagesStay;
  else note(r, "seccomp");
}

// One Landlock rule: `access` beneath `path` (skipped if it does not exist).
void allow_beneath(int ruleset, const std::string& path, uint64_t access) {
  landlock_path_beneath_attr pb{};
  pb.parent_fd = ::open(path.c_str(), O_PATH | O_CLOEXEC);
  if (pb.parent_fd < 0) return;
  struct stat st {};
  // Directory rights only on directories (the kernel refuses them on files).
  pb.allowed_access = ::fstat(pb.parent_fd, &st) == 0 && !S_ISDIR(st.st_mode) ? access & ~kFsReadDir : access;
  (void)::syscall(SYS_landlock_add_rule, ruleset, LANDLOCK_RULE_PATH_BENEATH, &pb, 0);
  ::close(pb.parent_fd);
}

}  // namespace

std::string restrict_reads(const std::string& plugin_file, const std::string& scratch,
                           const std::vector<std::string>& readable) {
  const long abi = ::syscall(SYS_landlock_create_ruleset, nullptr, 0, LANDLOCK_CREATE_RULESET_VERSION);
  if (abi < 1) return std::string("Landlock read rule (kernel 5.13+ with landlock in lsm=): ") + std::strerror(errno);
  RulesetAttr attr{};
  const uint64_t read = kFsExecute | kFsReadFile | kFsReadDir;
  attr.handled_access_fs = read;
  const int ruleset = static_cast<int>(
      ::syscall(SYS_landlock_create_ruleset, &attr, offsetof(RulesetAttr, handled_access_net), 0));
  if (ruleset < 0) return std::string("landlock_create_ruleset (reads): ") + std::strerror(errno);
  std::string dir = std::filesystem::path(plugin_file).parent_path().string();
  if (dir.empty()) dir = ".";
  // The plugin's folder (its data files), the system's libraries and data,
  // the scratch folder; what the C and C++ runtimes read (CPU count,
  // cgroup limits, the loader cache, time zone, random numbers).
  for (const std::string& p : {dir, std::string("/usr"), std::string("/lib"), std::string("/lib64"),
                               std::string("/etc/ld.so.cache"), std::string("/etc/localtime"),
                               std::string("/proc"), std::string("/sys/devices/system/cpu"),
                               std::string("/sys/fs/cgroup"), std::string("/dev/null"), std::string("/dev/zero"),
                               std::string("/dev/urandom"), std::string("/dev/random")})
    allow_beneath(ruleset, p, read);
  if (!scratch.empty()) allow_beneath(ruleset, scratch, read);
  for (const std::string& p : readable) allow_beneath(ruleset, p, read);
  std::string problem;
  if (::syscall(SYS_landlock_restrict_self, ruleset, 0) != 0)
    problem = std::string("landlock_restrict_self (reads): ") + std::strerror(errno);
  ::close(ruleset);
  return problem;
}

SandboxReport enter_sandbox(const std::string& scratch_parent) {
  SandboxReport r;
  std::string parent = scratch_parent;
  if (parent.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    parent = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  }
  // The daemon's pid in the name: a daemon that starts sweeps the folders
  // of daemons that died without cleaning up (sweep_stale_scratch).
  std::string tmpl = parent + "/procam-worker-" + std::to_string(::getppid()) + "-XXXXXX";
  if (::mkdtemp(tmpl.data()) != nullptr) {
    r.scratch = tmpl;
    r.flags |= kScratch;
    ::setenv("TMPDIR", tmpl.c_str(), 1);
    if (::chdir(tmpl.c_str()) != 0) note(r, "chdir to the scratch folder");
  } else {
    note(r, "mkdtemp in '" + parent + "'");
  }
  if (::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) == 0) r.flags |= kNoNewPrivs;
  else note(r, "no_new_privs");
  drop_capabilities(r);
  landlock(r);
  if ((r.flags & kNoNewPrivs) != 0) seccomp(r);  // seccomp without CAP_SYS_ADMIN needs no_new_privs
  return r;
}

}  // namespace procam::worker

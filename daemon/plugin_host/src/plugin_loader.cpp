// SPDX-License-Identifier: MIT
// Loading one plugin file: ELF info check, probe child, dlopen + checks.
#include "plugin_loader.hpp"

#include <dlfcn.h>
#include <elf.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <optional>
#include <set>
#include <thread>

#include "elf_symbols.hpp"

namespace procam::host::detail {
namespace {

std::string quoted(const std::string& file) { return "plugin '" + file + "'"; }

std::string hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", v);
  return buf;
}

// A fixed-size char field of procam_plugin_info as a string; nullopt if it
// has no NUL inside its size.
std::optional<std::string> field_string(const char* field, size_t size) {
  const void* nul = std::memchr(field, 0, size);
  if (nul == nullptr) return std::nullopt;
  return std::string(field, static_cast<size_t>(static_cast<const char*>(nul) - field));
}

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

const char* signal_name(int sig) {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGABRT: return "SIGABRT";
    case SIGILL: return "SIGILL";
    case SIGFPE: return "SIGFPE";
    case SIGTRAP: return "SIGTRAP";
    case SIGSYS: return "SIGSYS";
    case SIGKILL: return "SIGKILL";
    case SIGTERM: return "SIGTERM";
    case SIGINT: return "SIGINT";
    case SIGQUIT: return "SIGQUIT";
    case SIGPIPE: return "SIGPIPE";
    case SIGALRM: return "SIGALRM";
    case SIGXCPU: return "SIGXCPU";
    case SIGXFSZ: return "SIGXFSZ";
    default: return nullptr;
  }
}

template <typename Fn>
Fn symbol_as(void* sym) {
  Fn fn;
  static_assert(sizeof fn == sizeof sym);
  std::memcpy(&fn, &sym, sizeof fn);  // object -> function pointer (POSIX dlsym)
  return fn;
}

// --- probe wire format (child -> parent over a pipe) -------------------------
// 'P' phase(u8)                                    before each step
// 'R' code(u32) msg_len(u32) hint_len(u32) msg hint  the final result
constexpr size_t kMaxReport = 64 * 1024;

void write_all(int fd, const void* data, size_t n) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;  // parent gone: nothing useful to do
    p += w;
    n -= static_cast<size_t>(w);
  }
}

[[noreturn]] void child_main(int fd, const std::string& path, const FileInfo& file) {
  // No core files from plugins that crash on purpose or by bug while probed,
  // and the default action for fatal signals, whatever the daemon installed.
  struct rlimit no_core {
    0, 0
  };
  ::setrlimit(RLIMIT_CORE, &no_core);
  for (int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGILL, SIGFPE, SIGTRAP, SIGSYS})
    ::signal(sig, SIG_DFL);
  ::signal(SIGPIPE, SIG_IGN);

  Status st;
  try {
    auto r = load_and_check(
        path, file,
        [fd](Phase p) {
          uint8_t rec[2] = {'P', static_cast<uint8_t>(p)};
          write_all(fd, rec, sizeof rec);
        },
        /*unload=*/false);
    st = r.status();
  } catch (...) {
    st = Error(Code::internal, quoted(path) + ": unexpected exception while probing");
  }
  std::string msg = st.message().substr(0, kMaxReport / 2);
  std::string hint = st.hint().substr(0, kMaxReport / 4);
  const auto code = static_cast<uint32_t>(st.code());
  const auto msg_len = static_cast<uint32_t>(msg.size());
  const auto hint_len = static_cast<uint32_t>(hint.size());
  std::string rec(1, 'R');
  rec.append(reinterpret_cast<const char*>(&code), 4);
  rec.append(reinterpret_cast<const char*>(&msg_len), 4);
  rec.append(reinterpret_cast<const char*>(&hint_len), 4);
  rec += msg;
  rec += hint;
  write_all(fd, rec.data(), rec.size());
  ::close(fd);
  ::_exit(0);  // no atexit handlers, no static destructors (ours or the plugin's)
}

struct Report {
  Phase phase = Phase::none;
  bool has_result = false;
  Status result;
};

Report parse_report(const std::string& buf) {
  Report r;
  size_t i = 0;
  while (i < buf.size()) {
    if (buf[i] == 'P' && i + 2 <= buf.size()) {
      r.phase = static_cast<Phase>(static_cast<uint8_t>(buf[i + 1]));
      i += 2;
    } else if (buf[i] == 'R' && i + 13 <= buf.size()) {
      uint32_t code = 0, msg_len = 0, hint_len = 0;
      std::memcpy(&code, buf.data() + i + 1, 4);
      std::memcpy(&msg_len, buf.data() + i + 5, 4);
      std::memcpy(&hint_len, buf.data() + i + 9, 4);
      i += 13;
      if (msg_len > buf.size() - i || hint_len > buf.size() - i - msg_len) break;
      if (code > static_cast<uint32_t>(Code::too_large)) break;
      r.has_result = true;
      if (code == 0) {
        r.result = Status::Ok();
      } else {
        r.result = Status(static_cast<Code>(code), buf.substr(i, msg_len),
                          buf.substr(i + msg_len, hint_len));
      }
      i += msg_len + hint_len;
    } else {
      break;  // truncated or garbled (the plugin wrote to our pipe?)
    }
  }
  return r;
}

}  // namespace

LoadedPlugin::~LoadedPlugin() {
  if (handle != nullptr && unload) ::dlclose(handle);
}

bool valid_plugin_name(std::string_view s) {
  if (s.empty() || s.size() > 63) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-')) return false;
  return true;
}

bool valid_output_name(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

std::string printable(std::string_view s, size_t max_len) {
  std::string out;
  for (size_t i = 0; i < s.size() && i < max_len; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  if (s.size() > max_len) out += "...";
  return out;
}

std::string error_message(const procam_error& err) {
  const size_t n = ::strnlen(err.message, sizeof err.message);
  std::string m(err.message, n);
  return m.empty() ? std::string("(the plugin gave no message)") : m;
}

Code code_for_rc(int rc) {
  switch (rc) {
    case PROCAM_ERR_INVALID_ARGUMENT: return Code::invalid_argument;
    case PROCAM_ERR_BAD_FRAME: return Code::corrupt_data;
    case PROCAM_ERR_STATE: return Code::failed_precondition;
    default: return Code::plugin_error;
  }
}

std::string rc_name(int rc) {
  switch (rc) {
    case PROCAM_OK: return "PROCAM_OK";
    case PROCAM_ERR_INVALID_ARGUMENT: return "PROCAM_ERR_INVALID_ARGUMENT";
    case PROCAM_ERR_BAD_FRAME: return "PROCAM_ERR_BAD_FRAME";
    case PROCAM_ERR_STATE: return "PROCAM_ERR_STATE";
    case PROCAM_ERR_NO_MEMORY: return "PROCAM_ERR_NO_MEMORY";
    case PROCAM_ERR_INTERNAL: return "PROCAM_ERR_INTERNAL";
    default: return "undocumented return code " + std::to_string(rc);
  }
}

const char* phase_text(Phase p) {
  switch (p) {
    case Phase::none: return "before loading started";
    case Phase::dlopen: return "in dlopen (its static constructors or libraries it depends on)";
    case Phase::create: return "in procam_plugin_create()";
    case Phase::vtable: return "while its function table was checked";
    case Phase::describe: return "in describe()";
    case Phase::done: return "after all checks passed";
  }
  return "at an unknown step";
}

Result<FileInfo> read_plugin_info(const std::string& path) {
  const std::string who = quoted(path);
  auto elf_file = elf::ElfFile::open(path);
  if (!elf_file.ok()) {
    const Status& e = elf_file.status();
    if (e.code() == Code::corrupt_data)
      return Error(Code::corrupt_data, who + " is not a valid plugin library: " + e.message() +
                                           ": remove it from the plugin directory or rebuild it");
    return e.with_context(who);
  }
  const elf::ElfFile& f = *elf_file;
  const uint16_t host = elf::host_machine();
  if (host != 0 && f.machine() != host)
    return Error(Code::abi_mismatch, who + " was built for " + elf::machine_name(f.machine()) +
                                         ", this procamd runs on " + elf::machine_name(host) +
                                         ": rebuild the plugin for this machine");

  auto sym = f.find_symbol(PROCAM_PLUGIN_INFO_SYMBOL);
  if (!sym.ok()) {
    if (sym.status().code() == Code::not_found)
      return Error(Code::corrupt_data,
                   who + " exports no '" PROCAM_PLUGIN_INFO_SYMBOL
                         "' symbol: it is not a procam decoder plugin (plugins export "
                         "procam_plugin_info and procam_plugin_create, see plugin_abi.h)");
    return Error(Code::corrupt_data,
                 who + " is not a valid plugin library: " + sym.status().message());
  }

  // Header first (magic, versions), so an older/newer ABI with a different
  // struct size is reported as an ABI mismatch, not as a size problem.
  constexpr size_t kHeader = 3 * sizeof(uint32_t);
  auto head = f.read_symbol(*sym, kHeader);
  if (!head.ok())
    return Error(Code::corrupt_data,
                 who + ": cannot read its procam_plugin_info: " + head.status().message());
  uint32_t magic = 0, abi = 0, size = 0;
  std::memcpy(&magic, head->data(), 4);
  std::memcpy(&abi, head->data() + 4, 4);
  std::memcpy(&size, head->data() + 8, 4);
  if (magic != PROCAM_PLUGIN_MAGIC)
    return Error(Code::corrupt_data, who + " has procam_plugin_info magic " + hex32(magic) +
                                         ", expected " + hex32(PROCAM_PLUGIN_MAGIC) +
                                         " (\"PCPI\"): the file is corrupt or not a procam plugin");
  if (abi != PROCAM_PLUGIN_ABI_VERSION)
    return Error(Code::abi_mismatch,
                 who + " was built for plugin ABI " + std::to_string(abi) +
                     ", this procamd speaks ABI " + std::to_string(PROCAM_PLUGIN_ABI_VERSION) +
                     ": rebuild the plugin against this procamd's plugin_abi.h");
  if (size != sizeof(procam_plugin_info))
    return Error(Code::abi_mismatch,
                 who + " declares plugin ABI " + std::to_string(abi) +
                     " but a procam_plugin_info of " + std::to_string(size) +
                     " bytes, this procamd's is " + std::to_string(sizeof(procam_plugin_info)) +
                     ": it was built against a different plugin_abi.h; rebuild it against "
                     "this procamd's plugin_abi.h");
  auto full = f.read_symbol(*sym, sizeof(procam_plugin_info));
  if (!full.ok())
    return Error(Code::corrupt_data,
                 who + ": cannot read its procam_plugin_info: " + full.status().message());
  FileInfo out;
  std::memcpy(&out.info, full->data(), sizeof out.info);

  auto name = field_string(out.info.name, sizeof out.info.name);
  if (!name)
    return Error(Code::corrupt_data, who +
                                         ": procam_plugin_info.name is not NUL-terminated "
                                         "within its 64 bytes");
  if (!valid_plugin_name(*name))
    return Error(Code::corrupt_data, who + " has invalid plugin name \"" + printable(*name) +
                                         "\": names are 1..63 characters of a-z, 0-9, '_' and '-'");
  auto version = field_string(out.info.version, sizeof out.info.version);
  if (!version)
    return Error(Code::corrupt_data, who +
                                         ": procam_plugin_info.version is not NUL-terminated "
                                         "within its 32 bytes");
  if (version->empty() || printable(*version, version->size()) != *version)
    return Error(Code::corrupt_data, who + " has invalid version \"" + printable(*version) +
                                         "\": it must be non-empty printable ASCII");
  auto methods = field_string(out.info.methods, sizeof out.info.methods);
  if (!methods)
    return Error(Code::corrupt_data, who +
                                         ": procam_plugin_info.methods is not NUL-terminated "
                                         "within its 1024 bytes");
  std::set<std::string> seen;
  size_t pos = 0;
  while (pos <= methods->size()) {
    size_t end = methods->find(',', pos);
    if (end == std::string::npos) end = methods->size();
    std::string m = trim(std::string_view(*methods).substr(pos, end - pos));
    if (!valid_plugin_name(m))
      return Error(Code::corrupt_data,
                   who + " has invalid method list \"" + printable(*methods) +
                       "\": it must be comma-separated names of 1..63 characters of a-z, "
                       "0-9, '_' and '-'");
    if (!seen.insert(m).second)
      return Error(Code::corrupt_data,
                   who + " lists method '" + m + "' twice in procam_plugin_info.methods");
    out.methods.push_back(m);
    pos = end + 1;
  }

  auto create = f.find_symbol(PROCAM_PLUGIN_CREATE_SYMBOL);
  if (!create.ok()) {
    if (create.status().code() == Code::not_found)
      return Error(Code::corrupt_data,
                   who + " exports no '" PROCAM_PLUGIN_CREATE_SYMBOL
                         "' function: a plugin must export procam_plugin_create (see "
                         "plugin_abi.h; C++ plugins need extern \"C\" and default visibility)");
    return Error(Code::corrupt_data,
                 who + " is not a valid plugin library: " + create.status().message());
  }
  if (create->type != STT_FUNC && create->type != STT_GNU_IFUNC)
    return Error(Code::corrupt_data,
                 who + ": '" PROCAM_PLUGIN_CREATE_SYMBOL "' is not a function (symbol type " +
                     std::to_string(create->type) + ")");
  return out;
}

Result<Checked> load_and_check(const std::string& path, const FileInfo& file,
                               const std::function<void(Phase)>& on_phase, bool unload) {
  const std::string who = quoted(path);
  const std::string name(file.info.name);  // NUL-terminated: checked in step 1

  on_phase(Phase::dlopen);
  // A path without '/' would make dlopen search LD_LIBRARY_PATH etc.
  const std::string dl_path = path.find('/') == std::string::npos ? "./" + path : path;
  ::dlerror();
  void* handle = ::dlopen(dl_path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* e = ::dlerror();
    return Error(Code::plugin_error,
                 who + " could not be loaded: " + std::string(e ? e : "dlopen failed") +
                     ": install the libraries it needs or rebuild it");
  }
  auto plugin = std::make_shared<LoadedPlugin>();
  plugin->handle = handle;  // dlclose'd by ~LoadedPlugin on any early return
  plugin->unload = unload;
  plugin->name = name;
  plugin->file = path;

  void* info_sym = ::dlsym(handle, PROCAM_PLUGIN_INFO_SYMBOL);
  void* create_sym = ::dlsym(handle, PROCAM_PLUGIN_CREATE_SYMBOL);
  if (info_sym == nullptr || create_sym == nullptr)
    return Error(Code::corrupt_data,
                 who + ": after loading, " +
                     (info_sym ? PROCAM_PLUGIN_CREATE_SYMBOL : PROCAM_PLUGIN_INFO_SYMBOL) +
                     " cannot be resolved although the file defines it");
  Dl_info di_info{}, di_create{};
  if (::dladdr(info_sym, &di_info) == 0 || ::dladdr(create_sym, &di_create) == 0 ||
      di_info.dli_fbase != di_create.dli_fbase)
    return Error(Code::corrupt_data,
                 who +
                     ": " PROCAM_PLUGIN_INFO_SYMBOL " and " PROCAM_PLUGIN_CREATE_SYMBOL
                     " resolve to different libraries (" +
                     std::string(di_info.dli_fname ? di_info.dli_fname : "?") + ", " +
                     std::string(di_create.dli_fname ? di_create.dli_fname : "?") + ")");
  if (std::memcmp(info_sym, &file.info, sizeof file.info) != 0)
    return Error(Code::corrupt_data,
                 who +
                     ": its procam_plugin_info in memory differs from the file (was the file "
                     "replaced while loading, or does the plugin write to it?)");

  on_phase(Phase::create);
  auto create = symbol_as<procam_plugin_create_fn>(create_sym);
  const procam_plugin_vtable* vt = create(PROCAM_PLUGIN_ABI_VERSION);
  if (vt == nullptr)
    return Error(Code::abi_mismatch,
                 who + ": procam_plugin_create(" + std::to_string(PROCAM_PLUGIN_ABI_VERSION) +
                     ") returned NULL: the plugin cannot serve this procamd's plugin ABI; "
                     "rebuild it against this procamd's plugin_abi.h");

  on_phase(Phase::vtable);
  if (vt->abi_version != PROCAM_PLUGIN_ABI_VERSION)
    return Error(Code::abi_mismatch,
                 who + ": procam_plugin_create returned a function table for ABI " +
                     std::to_string(vt->abi_version) + ", this procamd speaks ABI " +
                     std::to_string(PROCAM_PLUGIN_ABI_VERSION) +
                     ": rebuild the plugin against this procamd's plugin_abi.h");
  if (vt->struct_size != sizeof(procam_plugin_vtable))
    return Error(Code::abi_mismatch,
                 who + ": its function table is " + std::to_string(vt->struct_size) +
                     " bytes (struct_size), this procamd's is " +
                     std::to_string(sizeof(procam_plugin_vtable)) +
                     ": rebuild the plugin against this procamd's plugin_abi.h");
  std::string missing;
  auto need = [&missing](bool set, const char* fn) {
    if (!set) missing += (missing.empty() ? "" : ", ") + std::string(fn);
  };
  need(vt->describe != nullptr, "describe");
  need(vt->session_create != nullptr, "session_create");
  need(vt->session_destroy != nullptr, "session_destroy");
  need(vt->next_plan != nullptr, "next_plan");
  need(vt->add_frame != nullptr, "add_frame");
  need(vt->end_round != nullptr, "end_round");
  need(vt->get_outputs != nullptr, "get_outputs");
  if (!missing.empty())
    return Error(Code::plugin_error, who + ": its function table has NULL function pointers (" +
                                         missing +
                                         "): every function of procam_plugin_vtable must be set");

  on_phase(Phase::describe);
  const char* text = vt->describe();
  if (text == nullptr)
    return Error(Code::plugin_error, who + ": describe() returned NULL, expected a JSON array");
  constexpr size_t kMaxDescribe = 16u << 20;
  const size_t len = ::strnlen(text, kMaxDescribe + 1);
  if (len > kMaxDescribe)
    return Error(Code::plugin_error, who + ": describe() returned more than 16 MiB");
  auto doc =
      nlohmann::json::parse(std::string_view(text, len), nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded())
    return Error(Code::plugin_error, who + ": describe() did not return valid JSON: \"" +
                                         printable(std::string_view(text, len)) + "\"");
  if (!doc.is_array())
    return Error(Code::plugin_error, who + ": describe() returned JSON " +
                                         std::string(doc.type_name()) +
                                         ", expected an array of method objects");
  Checked out;
  std::set<std::string> described;
  for (size_t i = 0; i < doc.size(); ++i) {
    const auto& m = doc[i];
    const auto n = m.is_object() ? m.find("name") : m.end();
    if (!m.is_object() || n == m.end() || !n->is_string())
      return Error(Code::plugin_error, who + ": describe() entry " + std::to_string(i) +
                                           " is not an object with a string \"name\"");
    const std::string mname = n->get<std::string>();
    if (!described.insert(mname).second)
      return Error(Code::plugin_error,
                   who + ": describe() lists method '" + printable(mname) + "' twice");
    bool listed = false;
    for (const auto& x : file.methods) listed = listed || x == mname;
    if (!listed)
      return Error(Code::plugin_error, who + ": describe() has method '" + printable(mname) +
                                           "' that procam_plugin_info.methods does not list");
    auto d = m.find("description");
    if (d != m.end() && !d->is_string())
      return Error(Code::plugin_error,
                   who + ": describe() method '" + mname + "' has a non-string \"description\"");
  }
  for (const auto& mname : file.methods) {
    if (!described.count(mname))
      return Error(Code::plugin_error,
                   who + ": method '" + mname +
                       "' is listed in procam_plugin_info.methods but not in describe()");
    for (const auto& m : doc) {
      if (m.find("name")->get_ref<const std::string&>() != mname) continue;
      MethodInfo mi;
      mi.name = mname;
      auto d = m.find("description");
      if (d != m.end()) mi.description = d->get<std::string>();
      mi.describe = m;
      out.methods.push_back(std::move(mi));
    }
  }
  on_phase(Phase::done);
  plugin->vtable = vt;
  out.plugin = std::move(plugin);
  return out;
}

Status probe_in_child(const std::string& path, const FileInfo& file,
                      std::chrono::milliseconds timeout) {
  const std::string who = quoted(path);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    return Error(Code::unavailable,
                 who + ": cannot create a pipe to probe it: " + std::strerror(errno));
  std::fflush(nullptr);  // or buffered output would be written twice
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int e = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    return Error(Code::unavailable, who + ": cannot fork to probe it: " + std::strerror(e) +
                                        ": free resources, or disable probing "
                                        "(LoadOptions::probe_in_child)");
  }
  if (pid == 0) {
    ::close(fds[0]);
    child_main(fds[1], path, file);
  }
  ::close(fds[1]);

  using clock = std::chrono::steady_clock;
  const auto deadline = clock::now() + timeout;
  auto ms_left = [&]() -> int {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - clock::now());
    return left.count() <= 0 ? 0 : static_cast<int>(std::min<int64_t>(left.count(), 1 << 30));
  };
  std::string buf;
  bool timed_out = false;
  for (;;) {
    const int left = ms_left();
    if (left == 0) {
      timed_out = true;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int pr = ::poll(&p, 1, left);
    if (pr < 0 && errno == EINTR) continue;
    if (pr < 0) break;
    if (pr == 0) {
      timed_out = true;
      break;
    }
    char tmp[4096];
    const ssize_t r = ::read(fds[0], tmp, sizeof tmp);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;  // EOF: the child exited (or closed our pipe)
    if (buf.size() < kMaxReport) buf.append(tmp, static_cast<size_t>(r));
  }
  ::close(fds[0]);

  // Reap the child; if it does not exit by the deadline, kill it.
  int wstatus = 0;
  bool reaped = false;
  for (;;) {
    const pid_t w = ::waitpid(pid, &wstatus, WNOHANG);
    if (w == pid) {
      reaped = true;
      break;
    }
    if (w < 0 && errno != EINTR) break;  // ECHILD: SIGCHLD ignored, auto-reaped
    if (timed_out || ms_left() == 0) {
      timed_out = true;
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

  const Report rep = parse_report(buf);
  const std::string where = phase_text(rep.phase);
  if (timed_out)
    return Error(Code::timeout,
                 who + " did not finish loading within " + std::to_string(timeout.count()) +
                     " ms (stuck " + where +
                     "); the probe process was killed and the plugin "
                     "skipped: fix the hang, or raise the probe timeout if it is just slow");
  if (reaped && WIFSIGNALED(wstatus)) {
    const int sig = WTERMSIG(wstatus);
    const char* sname = signal_name(sig);
    return Error(Code::plugin_error,
                 who + " crashed while loading (signal " + std::to_string(sig) +
                     (sname ? std::string(", ") + sname : std::string()) + ") " + where +
                     "; it was skipped: run the plugin's tests or a debugger to find the crash");
  }
  if (rep.has_result) {
    if (reaped && WIFEXITED(wstatus) && WEXITSTATUS(wstatus) != 0 && rep.result.ok())
      return Error(Code::plugin_error, who + ": the probe process exited with status " +
                                           std::to_string(WEXITSTATUS(wstatus)));
    return rep.result;
  }
  if (reaped && WIFEXITED(wstatus))
    return Error(Code::plugin_error, who + " ended the process (exit status " +
                                         std::to_string(WEXITSTATUS(wstatus)) + ") " + where +
                                         " instead of returning; it was skipped");
  return Error(Code::internal, who + ": the probe process ended without a report " + where +
                                   " (is SIGCHLD ignored?)");
}

}  // namespace procam::host::detail

// SPDX-License-Identifier: MIT
// PluginHost: directory scan, the per-file load sequence, session creation.
#include "procam/host/plugin_host.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <set>
#include <system_error>

#include "host_services.hpp"
#include "plugin_loader.hpp"
#include "worker_proxy.hpp"
#include "procam/core/image.hpp"
#include "procam/core/log.hpp"

namespace procam::host {
namespace fs = std::filesystem;

PluginHost::PluginHost(LoadOptions options) : options_(options) {}
PluginHost::~PluginHost() = default;
PluginHost::PluginHost(PluginHost&&) noexcept = default;
PluginHost& PluginHost::operator=(PluginHost&&) noexcept = default;

const PluginInfo* PluginHost::find(std::string_view name) const {
  for (const auto& p : plugins_)
    if (p.name == name) return &p;
  return nullptr;
}

void PluginHost::load_directories(const std::vector<std::string>& dirs) {
  std::vector<fs::path> scanned;  // a directory listed twice is scanned once
  for (const auto& dir : dirs) {
    try {
      std::error_code ec;
      const auto st = fs::status(dir, ec);
      if (ec || !fs::exists(st)) {
        PROCAM_LOG(plugins, info) << "plugin directory '" << dir << "' does not exist; skipped";
        continue;
      }
      const fs::path canonical = fs::weakly_canonical(dir, ec);
      if (!ec) {
        if (std::find(scanned.begin(), scanned.end(), canonical) != scanned.end()) continue;
        scanned.push_back(canonical);
      }
      if (!fs::is_directory(st)) {
        rejected_.push_back(
            {dir, Error(Code::io_error, "plugin directory '" + dir + "' is not a directory")});
        PROCAM_LOG(plugins, warn) << rejected_.back().error.message();
        continue;
      }
      std::vector<std::string> files;
      fs::directory_iterator it(dir, ec), end;
      for (; !ec && it != end; it.increment(ec)) {
        const std::string fname = it->path().filename().string();
        if (fname.size() <= 3 || fname.compare(fname.size() - 3, 3, ".so") != 0) continue;
        std::error_code ec2;
        if (!it->is_regular_file(ec2) || ec2) continue;  // follows symlinks
        files.push_back(it->path().string());
      }
      if (ec) {
        rejected_.push_back({dir, Error(Code::io_error, "cannot read plugin directory '" + dir +
                                                            "': " + ec.message())});
        PROCAM_LOG(plugins, warn) << rejected_.back().error.message();
        continue;
      }
      std::sort(files.begin(), files.end());
      for (const auto& f : files) (void)load_file(f);
    } catch (const std::exception& e) {
      rejected_.push_back(
          {dir, Error(Code::internal, "scanning plugin directory '" + dir + "': " + e.what())});
    }
  }
}

void PluginHost::set_isolation(IsolationOptions options) {
  isolation_ = std::move(options);
  spare_.reset();  // a spare started with the old options goes
  idle_.reset();   // so do idle workers (their sessions keep only weak pointers)
  // Scratch folders of a daemon killed before it could remove them
  // (README.md "Least privilege"); once per folder and process.
  if (isolation_.mode == Isolation::process && isolation_.sandbox) {
    static std::mutex mu;
    static std::set<std::string> swept;
    const std::string parent = detail::scratch_parent_of(isolation_);
    std::lock_guard<std::mutex> lock(mu);
    if (swept.insert(parent).second) (void)detail::sweep_stale_scratch(parent);
  }
  if (isolation_.mode == Isolation::process && isolation_.max_idle_workers > 0)
    idle_ = std::make_shared<detail::IdlePool>(isolation_);
  if (isolation_.mode == Isolation::process && isolation_.prestart) {
    spare_ = std::make_unique<detail::SparePool>();
    auto first = detail::WorkerProxy::spawn_spare(isolation_);  // the first scan need not wait either
    if (first) spare_->spare = std::move(*first);
  }
}

bool PluginHost::runs_isolated(std::string_view plugin) const {
  if (isolation_.mode == Isolation::in_process) return false;
  return std::find(isolation_.trusted.begin(), isolation_.trusted.end(), plugin) == isolation_.trusted.end();
}

Status PluginHost::load_file(const std::string& path) {
  Status st;
  try {
    st = load_file_impl(path);
  } catch (const std::exception& e) {
    st =
        Error(Code::internal, "plugin '" + path + "': unexpected error while loading: " + e.what());
  }
  if (!st.ok()) {
    rejected_.push_back({path, st});
    PROCAM_LOG(plugins, warn) << "rejected " << st.to_string();
  }
  return st;
}

namespace {

// Refuses a plugin that someone other than its owner could have replaced: the
// file, or the folder holding it (after resolving symlinks, both the link's
// and the target's folder), is world-writable, or it is owned by another
// ordinary user. Code from such a file would run inside the daemon.
Status check_plugin_permissions(const std::string& path) {
  auto check = [](const fs::path& p, const char* what) -> Status {
    struct stat st {};
    if (::stat(p.c_str(), &st) != 0)
      return Error(Code::io_error, std::string("cannot stat ") + what + " '" + p.string() + "'");
    if (st.st_mode & S_IWOTH)
      return Error(Code::failed_precondition,
                   std::string(what) + " '" + p.string() + "' is world-writable; refusing to load code from it",
                   "chmod o-w '" + p.string() + "' (plugins must only be writable by their owner)");
    if (st.st_uid != 0 && st.st_uid != ::geteuid())
      return Error(Code::failed_precondition,
                   std::string(what) + " '" + p.string() + "' is owned by uid " + std::to_string(st.st_uid) +
                       ", neither root nor the daemon's user",
                   "install plugins as root or as the daemon's user");
    return {};
  };
  const fs::path file(path);
  std::error_code exists_ec;
  if (!fs::exists(file, exists_ec)) return {};  // the loader reports a missing file (not_found)
  PROCAM_TRY(check(file, "plugin file"));
  PROCAM_TRY(check(file.parent_path().empty() ? fs::path(".") : file.parent_path(), "plugin folder"));
  std::error_code ec;
  const fs::path real = fs::canonical(file, ec);
  if (!ec && real != file) PROCAM_TRY(check(real.parent_path(), "plugin folder"));
  return {};
}

}  // namespace

Status PluginHost::load_file_impl(const std::string& path) {
  // 0. Who could have written it?
  PROCAM_TRY(check_plugin_permissions(path));
  // 1. The info block, read from the file: no plugin code runs.
  auto file = detail::read_plugin_info(path);
  if (!file.ok()) return file.status();
  const std::string name(file->info.name);
  if (const PluginInfo* first = find(name))
    return Error(Code::failed_precondition, "plugin '" + path + "': duplicate plugin name '" +
                                                name + "', first loaded from '" + first->file +
                                                "'; it was skipped: remove one of the two files");

  // 2. Probe in a child: crashes and hangs stay there.
  if (options_.probe_in_child)
    PROCAM_TRY(detail::probe_in_child(path, *file, options_.probe_timeout));

  // 3. Load here and check again.
  auto checked = detail::load_and_check(path, *file, [](detail::Phase) {});
  if (!checked.ok()) return checked.status();

  PluginInfo info;
  info.name = name;
  info.version = file->info.version;
  info.abi = checked->plugin->abi;
  info.file = path;
  info.methods = std::move(checked->methods);
  PROCAM_LOG(plugins, info) << "loaded plugin '" << info.name << "' " << info.version << " from '"
                            << path << "' (" << info.methods.size() << " methods)";
  plugins_.push_back(std::move(info));
  loaded_.push_back(std::move(checked->plugin));
  return {};
}

namespace {

// The scan's inputs against what `m` declares (plugin_abi.h "Scan inputs").
Status check_inputs(const PluginInfo& p, const MethodInfo& m, const std::vector<InputImage>& inputs) {
  const std::string who = "method '" + p.name + "/" + m.name + "'";
  std::string declared;
  for (const InputSpec& s : m.inputs)
    declared += (declared.empty() ? "" : ", ") + s.name + (s.required ? "" : " (optional)");
  if (!inputs.empty() && p.abi < 2)
    return Error(Code::invalid_argument,
                 who + " cannot take inputs: plugin '" + p.name + "' was built for plugin ABI " +
                     std::to_string(p.abi) + ", which has no way to pass them",
                 "drop \"inputs\" from the request, or rebuild the plugin with an ABI 2 SDK");
  std::set<std::string> given;
  for (const InputImage& in : inputs) {
    if (!given.insert(in.name).second)
      return Error(Code::invalid_argument, "input '" + in.name + "' is given twice");
    const InputSpec* spec = nullptr;
    for (const InputSpec& s : m.inputs)
      if (s.name == in.name) spec = &s;
    if (spec == nullptr)
      return Error(Code::invalid_argument,
                   m.inputs.empty() ? who + " takes no inputs, but the request gives '" + in.name + "'"
                                    : who + " has no input '" + in.name + "' (it takes: " + declared + ")",
                   "drop that entry from \"inputs\"; `procam plugins` lists each method's inputs");
    // kind image_f32 (the only kind parse_inputs admits).
    if (in.image.pixel_type != PROCAM_PIXEL_F32 || in.image.channels != 1)
      return Error(Code::invalid_argument,
                   "input '" + in.name + "' of " + who + " must be a 1-channel float map (image_f32), got " +
                       std::to_string(in.image.channels) + "-channel " +
                       (in.image.pixel_type == PROCAM_PIXEL_U8 ? "8-bit"
                        : in.image.pixel_type == PROCAM_PIXEL_U16 ? "16-bit"
                                                                   : "non-float") +
                       " pixels",
                   "name an output stored as exr-f32 (e.g. depth_mm), not a PNG mask or preview");
    if (const char* problem = validate_view(in.image))
      return Error(Code::invalid_argument, "input '" + in.name + "': " + problem);
  }
  for (const InputSpec& s : m.inputs)
    if (s.required && !given.count(s.name))
      return Error(Code::invalid_argument,
                   who + " needs input '" + s.name + "' (" + s.kind + (s.unit.empty() ? "" : ", " + s.unit) +
                       (s.description.empty() ? "" : ": " + s.description) + ")",
                   "name an earlier scan's output: \"inputs\": {\"" + s.name + "\": {\"scan\": \"<scan id>\", "
                   "\"output\": \"" + s.name + "\"}} (procam scan --input " + s.name +
                       "=SCAN_ID; offline: procam decode --input " + s.name + "=FILE.exr)");
  return {};
}

}  // namespace

Result<Session> PluginHost::create_session(const std::string& plugin, const std::string& method,
                                           const std::string& params_json,
                                           const std::string& rig_json,
                                           const std::vector<InputImage>& inputs) const {
  try {
    size_t idx = plugins_.size();
    for (size_t i = 0; i < plugins_.size(); ++i)
      if (plugins_[i].name == plugin) idx = i;
    if (idx == plugins_.size()) {
      std::string known;
      for (const auto& p : plugins_) known += (known.empty() ? "" : ", ") + p.name;
      return Error(Code::not_found, "no plugin '" + plugin + "' is loaded (loaded plugins: " +
                                        (known.empty() ? std::string("none") : known) + ")");
    }
    const PluginInfo& info = plugins_[idx];
    const MethodInfo* minfo = nullptr;
    std::string methods;
    for (const auto& m : info.methods) {
      if (m.name == method) minfo = &m;
      methods += (methods.empty() ? "" : ", ") + m.name;
    }
    if (minfo == nullptr)
      return Error(Code::not_found, "plugin '" + plugin + "' has no method '" + method +
                                        "' (its methods: " + methods + ")");
    auto check_object = [](const std::string& text, const char* what) -> Status {
      if (text.find('\0') != std::string::npos)
        return Error(Code::invalid_argument, std::string(what) + " contains a NUL byte");
      auto j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
      if (j.is_discarded())
        return Error(Code::invalid_argument, std::string(what) + " is not valid JSON");
      if (!j.is_object())
        return Error(Code::invalid_argument,
                     std::string(what) + " must be a JSON object, got " + j.type_name());
      return {};
    };
    const std::string params = params_json.empty() ? "{}" : params_json;
    const std::string rig = rig_json.empty() ? "{}" : rig_json;
    PROCAM_TRY(check_object(params, "params"));
    PROCAM_TRY(check_object(rig, "rig description"));
    PROCAM_TRY(check_inputs(info, *minfo, inputs));

    const auto& loaded = loaded_[idx];
    if (runs_isolated(plugin)) {
      // The worker loads the same file with the same checks and calls
      // session_create(2) there (README.md "Process model").
      wire::CreateRequest req{info.file, plugin, method, params, rig, inputs};
      bool host_services = false;
      // A warm worker of this plugin first (README.md "Worker reuse"); one
      // that fails to take the session is killed, and a fresh one tried.
      if (idle_) {
        while (auto warm = idle_->take(plugin)) {
          Status st = warm->reuse(req, host_services);
          if (st) {
            Session s(loaded, std::move(warm), method,
                      host_services ? std::make_unique<detail::HostBridge>(plugin) : nullptr);
            s.idle_ = idle_;
            return s;
          }
          // The plugin's own refusal (bad params) would be the same on a
          // fresh worker; a worker that died while idle is replaced.
          if (!warm->faulted()) return st;
        }
      }
      std::unique_ptr<detail::WorkerProxy> spare;
      if (spare_) {
        std::lock_guard lock(spare_->mu);
        spare = std::move(spare_->spare);
      }
      auto proxy = detail::WorkerProxy::start(isolation_, req, host_services, std::move(spare));
      if (spare_) {  // the next session's worker starts while this one works
        auto next = detail::WorkerProxy::spawn_spare(isolation_);
        std::lock_guard lock(spare_->mu);
        if (next && !spare_->spare) spare_->spare = std::move(*next);
      }
      if (!proxy) return proxy.status();
      auto bridge = host_services ? std::make_unique<detail::HostBridge>(plugin) : nullptr;
      Session s(loaded, std::move(*proxy), method, std::move(bridge));
      s.idle_ = idle_;
      return s;
    }
    procam_session* s = nullptr;
    procam_error err{};
    int rc = 0;
    if (const detail::Create2Fn create2 = detail::create2_of(*loaded)) {
      // Every session of a plugin with session_create2 goes through it.
      std::vector<procam_output> abi_inputs(inputs.size());
      for (size_t i = 0; i < inputs.size(); ++i) {
        procam_output& o = abi_inputs[i];
        o.name = inputs[i].name.c_str();
        o.kind = PROCAM_OUTPUT_IMAGE;
        o.unit = inputs[i].unit.c_str();
        o.description = inputs[i].description.c_str();
        o.image = inputs[i].image;
      }
      rc = create2(method.c_str(), params.c_str(), rig.c_str(),
                   abi_inputs.empty() ? nullptr : abi_inputs.data(),
                   static_cast<uint32_t>(abi_inputs.size()), &s, &err);
    } else if (!inputs.empty()) {  // declared inputs but no session_create2: a plugin bug
      return Error(Code::plugin_error, "plugin '" + plugin + "' declares inputs for method '" + method +
                                           "' but has no session_create2 to receive them");
    } else {
      rc = loaded->vtable->session_create(method.c_str(), params.c_str(), rig.c_str(), &s, &err);
    }
    if (rc != PROCAM_OK) {
      // *out is not trusted after a failure: never destroyed (a leak at worst).
      return Error(rc < 0 ? detail::code_for_rc(rc) : Code::plugin_error,
                   "plugin '" + plugin + "' could not start method '" + method +
                                           "' (" + detail::rc_name(rc) + "): " +
                                           (rc < 0 ? detail::error_message(err)
                                                   : std::string("not allowed by the ABI")));
    }
    if (s == nullptr)
      return Error(Code::plugin_error, "plugin '" + plugin +
                                           "' session_create returned PROCAM_OK "
                                           "but no session");
    // Host services (log/progress) for plugins whose table has session_set_host.
    std::unique_ptr<detail::HostBridge> bridge;
    if (const detail::SetHostFn set_host = detail::set_host_of(*loaded->vtable)) {
      bridge = std::make_unique<detail::HostBridge>(plugin);
      procam_error herr{};
      const int hrc = set_host(s, bridge->table(), &herr);  // no CallScope: no callbacks yet
      if (hrc != PROCAM_OK) {
        loaded->vtable->session_destroy(s);
        return Error(hrc < 0 ? detail::code_for_rc(hrc) : Code::plugin_error,
                     "plugin '" + plugin + "' refused the host services for method '" + method +
                         "' (" + detail::rc_name(hrc) + "): " +
                         (hrc < 0 ? detail::error_message(herr)
                                  : std::string("not allowed by the ABI")));
      }
    }
    return Session(loaded, s, method, std::move(bridge));
  } catch (const std::exception& e) {
    return Error(Code::internal, "create_session: " + std::string(e.what()));
  }
}

}  // namespace procam::host

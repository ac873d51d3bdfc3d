// SPDX-License-Identifier: MIT
// Plugin log/progress callbacks, host side (see host_services.hpp).
#include "host_services.hpp"

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>

#include "procam/core/log.hpp"

namespace procam::host::detail {

std::string sanitize_log_message(const char* message) {
  if (message == nullptr) return {};
  const size_t n = ::strnlen(message, kMaxLogBytes + 1);
  size_t keep = n;
  const bool cut = n > kMaxLogBytes;
  if (cut) {
    keep = kMaxLogBytes;
    // Step back over UTF-8 continuation bytes (10xxxxxx): no split character.
    while (keep > 0 && (static_cast<unsigned char>(message[keep]) & 0xC0u) == 0x80u) --keep;
  }
  std::string out;
  out.reserve(keep + 8);
  for (size_t i = 0; i < keep; ++i) {
    const auto c = static_cast<unsigned char>(message[i]);
    if (c < 0x20 || c == 0x7f || c == '\\') {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (cut) out += "...";
  return out;
}

log::Level log_level_of(int plugin_level) {
  switch (plugin_level) {
    case PROCAM_LOG_DEBUG: return log::Level::debug;
    case PROCAM_LOG_WARN: return log::Level::warn;
    case PROCAM_LOG_ERROR: return log::Level::error;
    default: return log::Level::info;
  }
}

SetHostFn set_host_of(const procam_plugin_vtable& vt) {
  constexpr size_t need =
      offsetof(procam_plugin_vtable, session_set_host) + sizeof(vt.session_set_host);
  if (vt.struct_size < need) return nullptr;  // a v1 table: the field is not there
  return vt.session_set_host;
}

HostBridge::HostBridge(std::string plugin_name) : plugin_(std::move(plugin_name)) {
  table_.struct_size = sizeof(procam_host_services);
  table_.ctx = this;
  table_.log = &HostBridge::log_cb;
  table_.progress = &HostBridge::progress_cb;
}

HostBridge::CallScope::CallScope(HostBridge* bridge) : bridge_(bridge) {
  if (bridge_ != nullptr) bridge_->call_thread_.store(std::this_thread::get_id());
}

HostBridge::CallScope::~CallScope() {
  if (bridge_ != nullptr) bridge_->call_thread_.store(std::thread::id{});
}

bool HostBridge::on_call_thread() {
  if (call_thread_.load() == std::this_thread::get_id()) return true;
  if (dropped_.fetch_add(1) == 0)
    PROCAM_LOG(plugins, warn) << "plugin '" << plugin_
                              << "' called a host service from another thread or outside a "
                                 "call; dropped (plugin_abi.h \"Host services\")";
  return false;
}

void HostBridge::log_cb(void* ctx, int level, const char* message) {
  auto* self = static_cast<HostBridge*>(ctx);
  if (self == nullptr || message == nullptr || !self->on_call_thread()) return;
  try {
    self->deliver_log(level, sanitize_log_message(message));
  } catch (...) {
    // Nothing may cross into the plugin; a lost log line is acceptable.
  }
}

void HostBridge::deliver_log(int level, const std::string& line) {
  try {
    if (log_lines_ >= kMaxLogLines) return;
    if (++log_lines_ == kMaxLogLines) {
      PROCAM_LOG(plugins, warn) << "plugin '" << plugin_ << "': " << kMaxLogLines
                                << " log lines in one scan; further lines are dropped";
      return;
    }
    const log::Level lv = log_level_of(level);
    if (log::enabled("plugins", lv)) log::write("plugins", lv, "plugin '" + plugin_ + "': " + line);
    if (on_log_) on_log_(lv, line);
  } catch (...) {
    // A handler that throws is ignored (see the file comment).
  }
}

void HostBridge::progress_cb(void* ctx, double fraction, const char* stage) {
  auto* self = static_cast<HostBridge*>(ctx);
  if (self == nullptr || !self->on_call_thread()) return;
  self->deliver_progress(fraction, stage);
}

void HostBridge::deliver_progress(double fraction, const char* stage) {
  if (std::isnan(fraction)) return;
  try {
    fraction = std::min(1.0, std::max(0.0, fraction));
    std::string st = sanitize_log_message(stage);
    if (st.size() > 64) st.resize(64);
    const auto now = std::chrono::steady_clock::now();
    const bool due = !progress_sent_ || st != last_stage_ || fraction >= 1.0 ||
                     now - last_progress_ >= kProgressInterval;
    if (!due) return;
    progress_sent_ = true;
    last_progress_ = now;
    last_stage_ = st;
    if (on_progress_) on_progress_(fraction, st);
  } catch (...) {
    // As above: never throw into the plugin.
  }
}

}  // namespace procam::host::detail

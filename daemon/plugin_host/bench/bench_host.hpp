// SPDX-License-Identifier: MIT
// Shared by the isolation benchmarks: one PluginHost per (plugin file,
// isolation mode), loaded once and kept for the whole run (never destroyed:
// sessions may still hold it at exit). Aborts if the file does not load, so
// a benchmark never times a broken setup.
#pragma once

#include <cstdlib>
#include <map>
#include <string>
#include <utility>

#include "procam/host/plugin_host.hpp"

namespace procam::host::bench {

inline PluginHost& host_with(const std::string& plugin_file, Isolation mode) {
  static auto* hosts = new std::map<std::pair<std::string, Isolation>, PluginHost*>();
  PluginHost*& h = (*hosts)[{plugin_file, mode}];
  if (h == nullptr) {
    h = new PluginHost();
    if (!h->load_file(plugin_file).ok()) std::abort();
    IsolationOptions iso;
    iso.mode = mode;
    h->set_isolation(iso);
  }
  return *h;
}

}  // namespace procam::host::bench
